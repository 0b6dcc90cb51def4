"""The gateway's CAN buses as the config names them, their receive filters, and echo handling.

``[imu]`` names the bus of the IMU bridge and ``[isobus]`` the output bus; when ``[isobus]``
leaves interface/channel unset (or names the same bus) both roles share one python-can bus
object and one reader, and received frames are dispatched by id. The ISOBUS role receives
address claims (PGN 60928), requests (PGN 59904), transport frames (PGNs 60416 and 60160: a
commanded address comes by BAM) and every frame from our own address (its filters follow the
address): a frame from our address that we did not send is a clone or a
spoofer, which the address claim must see.

Echo: some interfaces (``udp_multicast``, python-can ``virtual`` and socketcan with
``receive_own_messages``, some adapters) deliver our own transmitted frames back to us, and
with the filter on our address all of them get through. :class:`EchoFilter` remembers every
frame we sent and drops one received copy per frame sent, so an identical frame from another
node still gets through. ``is_rx`` is no echo marker: socketcan clears it for every frame
sent from this host (MSG_DONTROUTE), so another process's claim on the same interface (a
tool, a second application, the vcan tests' cansend) would be taken for ours.
"""

from __future__ import annotations

import errno
from collections import deque
from dataclasses import dataclass

import can
from can.typechecking import CanFilter

from gateway.config.config_schema import ConfigError
from gateway.config.gateway_config import GatewayConfig
from gateway.isobus.j1939 import Pgn

#: Receive filter on the PDU format byte (and DP/EDP) of a PDU1 PGN: any source, any destination.
PDU1_MASK = 0x03FF0000
#: The PGNs the ISOBUS role receives from any node: address claim, request, and the transport
#: protocol's that carry a commanded address.
CLAIM_PGNS = (
    Pgn.ADDRESS_CLAIM,
    Pgn.ISO_REQUEST,
    Pgn.TP_CONNECTION_MANAGEMENT,
    Pgn.TP_DATA_TRANSFER,
)
#: Receive filter on the source address byte of a 29-bit id: any PGN from one address.
SOURCE_MASK = 0xFF
#: errnos of a send or receive that mean the interface is gone or down, not just busy.
BUS_DOWN_ERRNOS = frozenset({errno.ENETDOWN, errno.ENODEV, errno.ENXIO, errno.EBADF, errno.EIO})
_Frame = tuple[int, bytes]  # arbitration id and data: what tells an echo


@dataclass(frozen=True)
class BusSpec:
    """One python-can bus: interface and channel."""

    interface: str
    channel: str

    def open(self) -> can.BusABC:
        """Open the bus (raises can.CanError or OSError when it is absent or down)."""
        return can.Bus(interface=self.interface, channel=self.channel)

    def __str__(self) -> str:
        return f"{self.interface} {self.channel}"


@dataclass(frozen=True)
class BusPlan:
    """The buses to open: IMU and ISOBUS, the same object when ``shared``."""

    imu: BusSpec
    isobus: BusSpec

    @property
    def shared(self) -> bool:
        """True when one bus carries both the IMU frames and the ISOBUS traffic."""
        return self.imu == self.isobus

    @classmethod
    def from_config(cls, config: GatewayConfig) -> BusPlan:
        """[imu] and [isobus] (unset fields: [imu]'s); unknown interfaces name their key."""
        imu = BusSpec(config.imu.interface, config.imu.channel)
        isobus = BusSpec(
            config.isobus.interface or imu.interface, config.isobus.channel or imu.channel
        )
        for key, spec in (("imu.interface", imu), ("isobus.interface", isobus)):
            if spec.interface not in can.VALID_INTERFACES:
                raise ConfigError(
                    f"{key} = {spec.interface!r}: not a python-can interface; expected one of "
                    + ", ".join(sorted(can.VALID_INTERFACES))
                )
        return cls(imu, isobus)


def claim_filters(address: int | None = None) -> list[CanFilter]:
    """Receive filters for address claims and requests from any node, and for every frame
    from ``address`` (ours, once we have one: another node sending from it must be seen)."""
    filters: list[CanFilter] = [
        {"can_id": (int(p) << 8) & PDU1_MASK, "can_mask": PDU1_MASK, "extended": True}
        for p in CLAIM_PGNS
    ]
    if address is not None:
        filters.append({"can_id": address, "can_mask": SOURCE_MASK, "extended": True})
    return filters


def is_bus_down(exc: BaseException) -> bool:
    """True if a send or receive error means the interface is down or gone (reopen it)."""
    code = getattr(exc, "error_code", None) or getattr(exc, "errno", None)
    cause = exc.__cause__
    return code in BUS_DOWN_ERRNOS or (cause is not None and is_bus_down(cause))


class EchoFilter:
    """Recognises our own transmitted frames coming back: one received copy per frame sent
    within ``window_s`` before the copy arrived. Frames sent are kept ``keep_s`` (more than a
    reader's backlog), so that a copy read late is still told by its arrival time."""

    def __init__(self, window_s: float = 1.0, keep_s: float = 10.0) -> None:
        self.window_s = window_s
        self.keep_s = keep_s
        self.echoes = 0  # received frames recognised as our own
        self._sent: dict[_Frame, deque[float]] = {}  # frame -> wall times sent, none empty
        self._order: deque[tuple[float, _Frame]] = deque()  # every frame kept, oldest first

    def sent(self, msg: can.Message, t_wall: float) -> None:
        """Remember a frame we sent (any: the filter on our address lets all of them back)."""
        self._forget_before(t_wall - self.keep_s)
        frame = (msg.arbitration_id, bytes(msg.data))
        self._sent.setdefault(frame, deque()).append(t_wall)
        self._order.append((t_wall, frame))

    def is_echo(self, msg: can.Message, t_wall: float) -> bool:
        """True if ``msg``, arrived at ``t_wall`` (frames come in order of arrival), is a copy
        of a frame we sent in the window before (that copy is then forgotten)."""
        self._forget_before(t_wall - self.window_s)
        frame = (msg.arbitration_id, bytes(msg.data))
        times = self._sent.get(frame)
        if times is not None:
            times.popleft()
            if not times:
                del self._sent[frame]
        echo = times is not None
        self.echoes += echo
        return echo

    def _forget_before(self, t_wall: float) -> None:
        """Forget the frames sent before ``t_wall`` (those not already echoed)."""
        while self._order and self._order[0][0] < t_wall:
            t, frame = self._order.popleft()
            times = self._sent.get(frame)
            if times and times[0] <= t:
                times.popleft()
                if not times:
                    del self._sent[frame]
