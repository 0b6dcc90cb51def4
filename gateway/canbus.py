"""The gateway's CAN buses as the config names them, their receive filters, and echo handling.

``[imu]`` names the bus of the IMU bridge and ``[isobus]`` the output bus; when ``[isobus]``
leaves interface/channel unset (or names the same bus) both roles share one python-can bus
object and one reader, and received frames are dispatched by id. The ISOBUS role receives
only address claims (PGN 60928) and requests (PGN 59904): that is all the address claim needs.

Echo: some interfaces (``udp_multicast``, some adapters) deliver our own transmitted frames
back to us. :class:`EchoFilter` remembers what we sent of the PGNs we also receive, and drops
one received copy per frame sent, so an identical frame from another node still gets through.
"""

from __future__ import annotations

import errno
from collections import deque
from dataclasses import dataclass

import can
from can.typechecking import CanFilter

from gateway.config import GatewayConfig
from gateway.config_schema import ConfigError
from gateway.j1939 import Pgn

#: Receive filter on the PDU format byte (and DP/EDP) of a PDU1 PGN: any source, any destination.
PDU1_MASK = 0x03FF0000
#: The PGNs the ISOBUS role receives: address claim and request.
CLAIM_PGNS = (Pgn.ADDRESS_CLAIM, Pgn.ISO_REQUEST)
#: errnos of a send or receive that mean the interface is gone or down, not just busy.
BUS_DOWN_ERRNOS = frozenset({errno.ENETDOWN, errno.ENODEV, errno.ENXIO, errno.EBADF, errno.EIO})


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


def claim_filters() -> list[CanFilter]:
    """Receive filters for address claims and requests from any node."""
    return [
        {"can_id": (int(p) << 8) & PDU1_MASK, "can_mask": PDU1_MASK, "extended": True}
        for p in CLAIM_PGNS
    ]


def is_claim_traffic(arbitration_id: int) -> bool:
    """True for an address claim or a request (what :func:`claim_filters` passes)."""
    return any(arbitration_id & PDU1_MASK == (int(p) << 8) & PDU1_MASK for p in CLAIM_PGNS)


def is_bus_down(exc: BaseException) -> bool:
    """True if a send or receive error means the interface is down or gone (reopen it)."""
    code = getattr(exc, "error_code", None) or getattr(exc, "errno", None)
    cause = exc.__cause__
    return code in BUS_DOWN_ERRNOS or (cause is not None and is_bus_down(cause))


class EchoFilter:
    """Recognises our own transmitted frames coming back, one received copy per frame sent."""

    def __init__(self, window_s: float = 1.0) -> None:
        self.window_s = window_s
        self.echoes = 0  # received frames recognised as our own
        self._sent: dict[tuple[int, bytes], deque[float]] = {}  # frame -> wall times sent

    def sent(self, msg: can.Message, t_wall: float) -> None:
        """Remember a frame we sent (only those that our receive filters can pass back)."""
        if is_claim_traffic(msg.arbitration_id):
            times = self._sent.setdefault((msg.arbitration_id, bytes(msg.data)), deque())
            self._expire(times, t_wall)
            times.append(t_wall)

    def is_echo(self, msg: can.Message, t_wall: float) -> bool:
        """True (and forgotten) if ``msg`` is a copy of a frame we sent in the last window."""
        key = (msg.arbitration_id, bytes(msg.data))
        times = self._sent.get(key)
        if times is None:
            return False
        self._expire(times, t_wall)
        echo = bool(times)
        if echo:
            times.popleft()
            self.echoes += 1
        if not times:
            del self._sent[key]
        return echo

    def _expire(self, times: deque[float], t_wall: float) -> None:
        while times and times[0] < t_wall - self.window_s:
            times.popleft()
