"""The live service (``navgw run``, ``navgw demo``): an asyncio shell around the FusionCore.

Tasks of one event loop (no threads of ours but the learned state's writer; the estimator
is fast and runs inline):

- one CAN task per distinct bus (:class:`~gateway.service.bus_links.BusPlan`): opens the bus,
  retrying
  with back-off while it is absent or down, reads it through
  :class:`~drivers.frame_reader.FrameReader`, stamps each frame with the service time, records and
  decodes IMU frames into the inbox (an IMU frame read :data:`MAX_SAMPLE_AGE_S` after it
  arrived, the reader is behind: the stale IMU frames are shed undecoded, the whole backlog if
  it happens again soon, and it goes on with fresh ones), and hands address claims, requests
  and frames from our
  own address (not our own echo) to the core at once: a lower NAME that takes our address
  must silence us as soon as its claim is read, not after the IMU backlog queued before it.
  The ISOBUS filters follow our address, so that another node sending from it is seen;
- the GNSS task: fixes from :class:`~drivers.gnss_serial.GnssSerialReader` (which reconnects)
  into a queue of their own, where each waits until the IMU stream has reached its time: an
  overloaded inbox drops IMU samples, never a fix;
- the core task: IMU samples from one bounded :class:`Inbox`, each after the fixes older than
  it, to the :class:`~gateway.fusion.fusion_core.FusionCore` (the order replay merges them in),
  output
  frames sent on the ISOBUS as they are encoded (the attitude first); a failed send is
  counted and logged at a limited rate, and an interface that is down makes the CAN task
  reopen the bus;
- the tick task: advances the claim timers while no IMU frame arrives; the loop's heartbeat;
- the health task: sd_notify STATUS every few seconds and WATCHDOG=1 while :meth:`healthy`;
  the IMU mounting estimate (:mod:`gateway.service.mounting_watch`, fed every input after
  the core) logged every ``[calibration] report_interval_s``;
- the state task (``[state] enabled``): every ``save_interval_s``, and once a stop has
  lasted ``STOP_SAVE_S``, the learned biases, if the engine has learned better ones, the
  last stop, and the mounting estimate once determined, written to the state directory
  (:class:`~gateway.state.keeper.StateKeeper`); the write (an fsync, tens of ms on an ECU's
  flash) runs in a worker thread so that it never holds up the core. The learned state is
  read before anything is built
  (:func:`~gateway.state.keeper.effective_start`: with ``[calibration] apply`` the stored
  mounting may be the one in effect, for the whole run; the engine starts from the biases
  at the first IMU_AUX) and written once more at a clean stop (SIGTERM).

Time: every time the core sees (IMU frame arrival, GNSS receive time, claim timers) goes
through one :class:`~gateway.service.timebase.TimeBase`: the identity live, a scaled clock in the
demo; then, less the host clock's steps the IMU decoder has found, on the core's time
(:mod:`drivers.host_clock`): through a step of the host clock (NTP, chrony) the IMU samples
and the GNSS epochs stay on one time line. A fix is put on core time as it goes to the core,
and none goes while the IMU's arrivals may yet show a step forward (late for less than
0.375 s): on the old clock it would reach the engine a step ahead of the fixes after it.

Fairness: a task that finds its queue non-empty never awaits anything that suspends, so on a
busy host the CAN and core tasks could take turns for seconds while the serial port's reader
callback waited: GNSS epochs then reached the engines seconds late and in bursts (and the
pty's receive stamps with them). Both hand the loop on after :data:`TURN_S` of work
(:class:`Turns`), whatever one item costs.
"""

from __future__ import annotations

import asyncio
import gc
import logging
import math
import signal
import time
from collections import deque
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

import can
from can.typechecking import CanFilter

from drivers.backoff import Backoff
from drivers.errors import BusError
from drivers.frame_reader import FrameReader
from drivers.gnss_serial import GnssSerialReader
from drivers.host_clock import retimed
from drivers.imu_can import PGN_SA_MASK, ImuDecoder
from drivers.log_limit import LogLimiter
from drivers.nmea import NmeaDecoder
from drivers.samples import GnssFix, ImuAux, ImuSample
from gateway.config.driver_settings import imu_config
from gateway.config.gateway_config import GatewayConfig
from gateway.estimation.solution import Mode
from gateway.fusion.fusion_core import FusionCore
from gateway.isobus.address_claim import ClaimState
from gateway.service.bus_links import BusPlan, BusSpec, EchoFilter, claim_filters, is_bus_down
from gateway.service.input_recording import InputRecorder
from gateway.service.mounting_watch import MountingWatch, applied_text
from gateway.service.sdnotify import SdNotifier
from gateway.service.timebase import LIVE, TimeBase
from gateway.state.keeper import StateKeeper, effective_start
from gateway.state.store import Mounting

log = logging.getLogger(__name__)

INBOX_SIZE = 1024  # inputs between the readers and the core (5 s of IMU samples at 204.8 Hz)
TICK_S = 0.05  # claim-timer resolution while the IMU is silent, service seconds
HOLD_MAX_S = 0.2  # a GNSS fix waits at most this long for the IMU to reach its time
#: An IMU sample the core gets later than this after it was sampled is dropped (counted):
#: what it would send is stale (5 s of backlog put the tractor 15 m back), and shedding it
#: lets the core catch up; the engine bridges the gap and says DEGRADED if it is long.
MAX_SAMPLE_AGE_S = 0.1
#: A reader that sheds stale IMU frames again within this long is slower than its input (not
#: held up once): it sheds its whole backlog, service seconds.
SHED_AGAIN_S = 1.0
STATUS_INTERVAL_S = 2.0  # sd_notify STATUS, wall seconds
HEARTBEAT_MAX_S = 2.0  # the tick or the core stalled this long (wall): unhealthy
CLOCK_MISMATCH_S = 5.0  # frame timestamps this far from the host clock are not host time
#: A stop this long (its means, after the settling second) is saved at once, not at the next
#: save_interval_s: a gateway whose power is cut at key-off, without a clean stop, still
#: leaves the stop the next start checks its biases against. Shorter stops (reversing: 2 s)
#: are not worth a write each.
STOP_SAVE_S = 5.0
STATE_TICK_S = 1.0  # how often the state task looks for such a stop, service seconds
TURN_S = 0.001  # a task with work queued lets the loop run the others after this long

Input = ImuSample | ImuAux  # what the inbox carries (fixes wait in a queue of their own)


class Turns:
    """Lets a task that always has work queued hand the loop on every :data:`TURN_S`."""

    def __init__(self) -> None:
        self._since = time.perf_counter()

    async def take(self) -> None:
        """Yield to the loop if this task has had it for TURN_S."""
        if time.perf_counter() - self._since >= TURN_S:
            await asyncio.sleep(0)
            self._since = time.perf_counter()


class Inbox:
    """Bounded queue from the readers to the core. When full, the OLDEST input is dropped:
    a navigation output must follow the newest data, and a stale backlog only adds latency.
    Producers never wait, so no reader (and no buffer behind it) grows while the core stalls.
    """

    def __init__(self, maxsize: int = INBOX_SIZE) -> None:
        self._queue: asyncio.Queue[Input] = asyncio.Queue(maxsize)
        self.overloads = 0  # inputs dropped
        self._log = LogLimiter(log)

    def offer(self, item: Input) -> bool:
        """Queue ``item``, dropping the oldest input if the queue is full (then True)."""
        dropped = self._queue.full()
        if dropped:
            self._queue.get_nowait()
            self.overloads += 1
            self._log.warning(
                time.monotonic(),
                f"fusion loop overloaded: oldest input dropped ({self.overloads} in all)",
            )
        self._queue.put_nowait(item)
        return dropped

    async def get(self) -> Input:
        """The oldest input, waiting for one."""
        return await self._queue.get()

    def empty(self) -> bool:
        """True when nothing waits for the core."""
        return self._queue.empty()


@dataclass
class BusLink:
    """One distinct bus and the roles it plays; ``waiting`` says why it is not open."""

    spec: BusSpec
    imu: bool
    isobus: bool
    bus: can.BusABC | None = None
    reader: FrameReader | None = None
    waiting: str | None = "not opened yet"
    reopens: int = 0
    host_stamps: bool | None = None  # the interface stamps frames on the host clock (1st frame)
    source_filter: int | None = None  # our address as the open bus's filters pass it (ISOBUS)

    @property
    def roles(self) -> str:
        """'IMU', 'ISOBUS' or 'IMU + ISOBUS'."""
        return " + ".join(r for r, on in (("IMU", self.imu), ("ISOBUS", self.isobus)) if on)


@dataclass
class ServiceStats:
    """What the shell around the core counted (the core and the decoders count the rest)."""

    frames_sent: int = 0
    send_errors: int = 0
    frames_unsent: int = 0  # output while the ISOBUS was not open, or after stop
    can_frames_dropped: int = 0  # receive buffers full (the loop starved), closed readers
    stale_samples: int = 0  # IMU samples dropped for arriving at the core too late
    frames_shed: int = 0  # IMU frames dropped undecoded for being read too late
    imu_rate_hz: float = 0.0  # IMU samples per service second, over the last STATUS interval


class GatewayService:
    """The live gateway: ``await GatewayService(config).run()`` until :meth:`request_stop`."""

    def __init__(
        self,
        config: GatewayConfig,
        *,
        timebase: TimeBase = LIVE,
        notifier: SdNotifier | None = None,
    ) -> None:
        start = effective_start(config, config.state.directory if config.state.enabled else None)
        config = self.config = start.config  # the IMU mounting in effect for the whole run
        self.applied = start.applied
        self.timebase = timebase
        self.notifier = notifier if notifier is not None else SdNotifier({})
        plan = BusPlan.from_config(config)
        self.imu_decoder = ImuDecoder(imu_config(config))
        self.state = start.keeper
        self.core = FusionCore.from_config(
            config,
            self.imu_decoder.counters,
            warm_start=self.state.warm_start if self.state and self.state.stored else None,
            track_rest=self.state is not None,
        )
        self.mounting = (
            MountingWatch(config, config.calibration.report_interval_s, self.applied)
            if config.calibration.live
            else None
        )
        self.recorder = (
            InputRecorder(config.recording, plan.imu.channel, timebase.now)
            if config.recording.enabled
            else None
        )
        decoder = NmeaDecoder(
            config.gnss.port, on_sentence=self.recorder.sentence if self.recorder else None
        )
        self.gnss = GnssSerialReader(
            config.gnss.port, config.gnss.baudrate, decoder=decoder, clock=timebase.now
        )
        self.links = (
            [BusLink(plan.imu, imu=True, isobus=True)]
            if plan.shared
            else [BusLink(plan.imu, imu=True, isobus=False), BusLink(plan.isobus, False, True)]
        )
        self.isobus = self.links[-1]
        self.inbox = Inbox()
        self.echo = EchoFilter()
        self.stats = ServiceStats()
        self._imu_filters = self.imu_decoder.config.ids.can_filters()
        self._imu_ids = frozenset(f["can_id"] for f in self._imu_filters)
        self._stop = asyncio.Event()
        self._stopping = False
        self._tasks: list[asyncio.Task[None]] = []
        self._heartbeat = self._core_progress = time.monotonic()
        self._last_imu_t = -math.inf  # service time of the last IMU frame
        self._held: deque[GnssFix] = deque()  # fixes waiting for the IMU stream
        self._gnss_clock = self.imu_decoder.host_clock.stream()  # their receive times
        self._bus_clock = self.imu_decoder.host_clock.stream()  # other nodes' frames' times
        self._send_log = LogLimiter(log)
        self._stale_log = LogLimiter(log)
        self._shed_at = -math.inf  # host time of the last shedding of stale IMU frames

    # --- life cycle -----------------------------------------------------------------------

    def request_stop(self) -> None:
        """Ask :meth:`run` to stop (signal handlers call this)."""
        self._stop.set()

    async def run(self) -> int:
        """Run until :meth:`request_stop`: 0 after a clean stop, 1 if an internal task died.

        Raises OSError before starting if the recording directory cannot be used.
        """
        if self.recorder is not None:
            self.recorder.open()
        if warning := self.config.lever_arm_warning():
            log.warning(warning)
        jobs = {f"can {link.spec}": self._run_bus(link) for link in self.links}
        jobs |= {"gnss": self._run_gnss(), "core": self._run_core(), "tick": self._run_tick()}
        jobs["health"] = self._run_health()
        if self.state is not None and self.state.usable_directory:
            jobs["state"] = self._run_state(self.state)
        self._tasks = [asyncio.create_task(job, name=name) for name, job in jobs.items()]
        stop = asyncio.create_task(self._stop.wait(), name="stop")
        log.info("navgw running: %s", self.status_line())
        self.notifier.ready(self.status_line())
        try:
            done, _ = await asyncio.wait([stop, *self._tasks], return_when=asyncio.FIRST_COMPLETED)
        finally:
            await self._shutdown([stop, *self._tasks])
        died = [t for t in done if t is not stop]
        for task in died:
            exc = None if task.cancelled() else task.exception()
            log.error("internal task %r ended: %r", task.get_name(), exc, exc_info=exc)
        return 1 if died else 0

    async def _shutdown(self, tasks: list[asyncio.Task[Any]]) -> None:
        """Stop transmitting, stop the readers, close buses and recordings."""
        self._stopping = True
        self.notifier.stopping()
        self.gnss.close()
        for task in tasks:
            task.cancel()
        await asyncio.gather(*tasks, return_exceptions=True)
        if self.recorder is not None:
            self.recorder.close()
        if self.state is not None and self.state.save(self.core, True, self._mounting_learned()):
            log.info("learned state saved to %s", self.state.path)
        log.info("navgw stopped: %s", self.status_line())

    def healthy(self) -> bool:
        """The loop ticks, the core keeps up with its inbox, and no internal task has ended.

        Missing devices do not make the service unhealthy (STATUS says what is missing):
        restarting would not bring a receiver back.
        """
        now = time.monotonic()
        return (
            bool(self._tasks)
            and not any(t.done() for t in self._tasks)
            and now - self._heartbeat < HEARTBEAT_MAX_S
            and (self.inbox.empty() or now - self._core_progress < HEARTBEAT_MAX_S)
        )

    # --- tasks ----------------------------------------------------------------------------

    async def _run_bus(self, link: BusLink) -> None:
        backoff = Backoff()
        reported = False
        while True:
            try:
                bus = link.spec.open()
            except (can.CanError, OSError) as exc:
                if not reported:
                    log.warning("CAN %s (%s) not available: %s; retrying, at most every %g s",
                                link.spec, link.roles, exc, backoff.max_s)  # fmt: skip
                    reported = True
                link.waiting = f"waiting ({exc})"
                await asyncio.sleep(backoff.next())
                continue
            reported = False
            try:
                with bus:
                    async with FrameReader(bus, self._filters(link)) as reader:
                        link.bus, link.reader, link.waiting = bus, reader, None
                        link.host_stamps = None
                        log.info("CAN %s open (%s)", link.spec, link.roles)
                        backoff.reset()
                        if link.isobus:
                            self._send(self.core.start(self.core_now()))
                        turns = Turns()
                        async for msg in reader:
                            self._on_frame(link, msg)
                            await turns.take()
            except BusError as exc:
                link.reopens += 1
                link.waiting = f"reopening ({exc.__cause__ or exc})"
                log.warning("CAN %s failed: %s; reopening", link.spec, exc)
            finally:
                if link.reader is not None:
                    self.stats.can_frames_dropped += link.reader.dropped
                link.bus = link.reader = None
            await asyncio.sleep(backoff.next())

    async def _run_gnss(self) -> None:
        async for fix in self.gnss.fixes():
            self._held.append(fix)

    async def _run_core(self) -> None:
        turns = Turns()
        while True:
            item = await self.inbox.get()
            self._core_progress = time.monotonic()
            if isinstance(item, ImuSample):
                if not self.imu_decoder.step_pending:
                    self._release_fixes(item.t)
                if self.core_now() - self.imu_decoder.pending_step_s - item.t > MAX_SAMPLE_AGE_S:
                    self.stats.stale_samples += 1
                    self.core.stats.imu_dropped += 1
                    self._stale_log.warning(
                        time.monotonic(),
                        f"fusion loop behind: IMU samples older than {MAX_SAMPLE_AGE_S:g} s "
                        f"dropped ({self.stats.stale_samples} in all)",
                    )
                    await turns.take()
                    continue
            self.process(item)
            await turns.take()

    def process(self, item: Input | GnssFix) -> None:
        """One decoded input through the core (its frames sent), then to the mounting
        estimate: what the loop does with each input, in time order."""
        self._send(self.core.on_input(item))
        if self.mounting is not None:
            self.mounting.feed(item)

    def _release_fixes(self, before: float) -> None:
        """Feed the held GNSS fixes older than ``before`` (core time) to the core, each put
        on core time as it goes.

        The core gets its inputs in time order, as replay merges them: a fix read before the
        IMU frames of the same instant have been through the loop waits for them (normally
        less than one IMU period; at most HOLD_MAX_S while the IMU is silent), and one read
        after them goes in before the next sample.
        """
        held, clock = self._held, self._gnss_clock
        while held and (t := clock.core(held[0].t, held[0].t_utc)) < before:
            self.process(retimed(held.popleft(), t))

    async def _run_tick(self) -> None:
        while True:
            await asyncio.sleep(self.timebase.wall_s(TICK_S))
            self._heartbeat = time.monotonic()
            self.tick(self.timebase.now())

    def tick(self, now: float) -> None:
        """What the loop does without IMU input (service time ``now``): the core's timers, and
        FAULT once the IMU is silent; fixes held for the IMU go in."""
        if now - self._last_imu_t >= TICK_S and not self._imu_pending():
            now = self.core_time(now)
            self._send(self.core.poll(now))
            self._release_fixes(now - HOLD_MAX_S)

    def core_now(self) -> float:
        """The core's time now."""
        return self.core_time(self.timebase.now())

    def core_time(self, now: float) -> float:
        """The core's time at service time ``now``: less the host clock's steps found."""
        return now - self.imu_decoder.host_clock.correction_s

    def _imu_pending(self) -> bool:
        """IMU input waits in a reader or the inbox: the loop is behind its input, and the
        IMU is not silent (the core would take its last sample's age for a silence: FAULT)."""
        readers = (link.reader for link in self.links if link.imu)
        return not self.inbox.empty() or any(r is not None and r.pending for r in readers)

    async def _run_state(self, keeper: StateKeeper) -> None:
        """Save what the engine has learned every ``save_interval_s`` (service time), if
        better than what is stored, and each stop once it is :data:`STOP_SAVE_S` long; the
        blocking write in a worker thread."""
        interval_s = self.config.state.save_interval_s
        since_s = 0.0
        saved_stop_s: float | None = None  # start of the last stop saved
        while True:
            tick_s = min(STATE_TICK_S, interval_s)
            await asyncio.sleep(self.timebase.wall_s(tick_s))
            since_s += tick_s
            stop = self.core.rest.current() if self.core.rest is not None else None
            stop_s = None if stop is None else stop.t_s - stop.duration_s
            new_stop = stop is not None and stop.duration_s >= STOP_SAVE_S
            if since_s < interval_s and not (new_stop and stop_s != saved_stop_s):
                continue
            since_s = 0.0
            if new_stop:
                saved_stop_s = stop_s
            try:
                state = keeper.snapshot(self.core, mounting=self._mounting_learned())
            except Exception:  # never fatal: the gateway runs on without a saved state
                log.exception("learned state not saved to %s", keeper.path)
                continue
            if state is not None and await asyncio.to_thread(keeper.write, state):
                log.info("learned state saved to %s", keeper.path)

    def _mounting_learned(self) -> Mounting | None:
        """The live mounting estimate to keep: the last summary's, once determined."""
        return self.mounting.learned if self.mounting is not None else None

    async def _run_health(self) -> None:
        watchdog_s = self.notifier.watchdog_interval_s
        period = min(STATUS_INTERVAL_S, watchdog_s or math.inf)
        next_status = time.monotonic() + STATUS_INTERVAL_S
        claim, mode = self.core.claimer.state, self._mode()
        mark = (self.core_now(), self.core.stats.imu_samples)
        while True:
            await asyncio.sleep(period)
            if watchdog_s is not None and self.healthy():
                self.notifier.watchdog()
            if time.monotonic() >= next_status:
                next_status += STATUS_INTERVAL_S
                now, samples = self.core_now(), self.core.stats.imu_samples
                self.stats.imu_rate_hz = (samples - mark[1]) / max(now - mark[0], 1e-9)
                mark = (now, samples)
                line = self.status_line()
                self.notifier.status(line)
                log.debug("status: %s", line)
            if self.core.claimer.state is not claim:
                claim = self.core.claimer.state
                log.info("address claim %s: %s", claim.value, self._address_text())
            if self._mode() is not mode:
                mode = self._mode()
                log.info("mode %s", mode.name.lower())
            if self.mounting is not None and (text := self.mounting.update(self.core_now())):
                log.info("%s", text)

    # --- frames in and out ----------------------------------------------------------------

    def _filters(self, link: BusLink) -> list[CanFilter]:
        """The link's receive filters: the IMU's, and claims, requests and frames from our
        current address (noted in ``link.source_filter``) for the ISOBUS."""
        if not link.isobus:
            return list(self._imu_filters)
        link.source_filter = self.core.claimer.address
        imu = self._imu_filters if link.imu else []
        return imu + claim_filters(link.source_filter)

    def _follow_address(self) -> None:
        """Re-filter the ISOBUS when our address has changed (claimed, or moved)."""
        link = self.isobus
        if link.bus is not None and self.core.claimer.address != link.source_filter:
            link.bus.set_filters(self._filters(link))

    def _on_frame(self, link: BusLink, msg: can.Message) -> None:
        """Stamp a received frame with the service time and route it. Our echo is told by its
        arrival time: read late, behind a backlog, it is still ours (not a spoofed frame)."""
        host_time = self._host_time(link, msg)
        msg.timestamp = self.timebase.at(host_time)
        if link.imu and self._is_imu(msg):
            self._last_imu_t = msg.timestamp
            if link.host_stamps and self.timebase.now() - msg.timestamp > MAX_SAMPLE_AGE_S:
                self._shed(link, msg)
                return
            if self.recorder is not None:
                self.recorder.can(msg)
            for item in self.imu_decoder.feed(msg):
                if self.inbox.offer(item):
                    self.core.stats.imu_dropped += 1
        elif link.isobus and not self.echo.is_echo(msg, host_time):
            self._send(self.core.on_bus_frame(msg, self._bus_clock.core(msg.timestamp)))

    def _is_imu(self, msg: can.Message) -> bool:
        """True for a frame of the IMU bridge's (its ids, any source address)."""
        return msg.arbitration_id & PGN_SA_MASK in self._imu_ids

    def _shed(self, link: BusLink, msg: can.Message) -> None:
        """Drop ``msg``, an IMU frame read MAX_SAMPLE_AGE_S after it arrived, and the IMU
        frames behind it as stale, undecoded (the core would drop their samples): a reader
        held up once catches up at the cost of a receive per stale frame. Shedding again
        within :data:`SHED_AGAIN_S`, it is slower than its input: then the whole backlog
        goes, and it starts afresh. Decoding every frame, such a reader stayed a socket
        buffer behind and no sample reached the engine for 20 s (an emulated guest on a busy
        CI host); shedding only the stale ones, it stayed at the edge, and what it decoded
        was stale at the core. The IMU decoder is told how many were shed, and counts their
        samples lost (NAVGW_STATUS byte 6), whole SEQ wraps included; the recording keeps
        them, as the bus carried them."""
        assert link.reader is not None
        now = time.time()
        again = now - self._shed_at < self.timebase.wall_s(SHED_AGAIN_S)
        self._shed_at = now
        before = now if again else now - self.timebase.wall_s(MAX_SAMPLE_AGE_S)
        shed = link.reader.shed(before, keep=lambda m: not self._is_imu(m))
        self.stats.frames_shed += 1 + len(shed)
        self.imu_decoder.skipped(1 + len(shed))
        if self.recorder is not None:
            self.recorder.can(msg)
            for frame in shed:
                frame.timestamp = self.timebase.at(frame.timestamp)
                self.recorder.can(frame)
        self._stale_log.warning(
            time.monotonic(),
            f"fusion loop behind: IMU frames read more than {MAX_SAMPLE_AGE_S:g} s after they "
            f"arrived shed undecoded ({self.stats.frames_shed} in all)",
            "shed",
        )

    def _host_time(self, link: BusLink, msg: can.Message) -> float:
        """The frame's arrival time; the host clock if the interface stamps another clock.

        Decided once per opening, on the first frame (no backlog yet): deciding per frame
        replaced the true stamps of frames read late on a busy host by the time they were
        read, which is exactly the jitter the stamps are there to avoid.
        """
        now = time.time()
        if link.host_stamps is None:
            link.host_stamps = abs(msg.timestamp - now) < CLOCK_MISMATCH_S
            if not link.host_stamps:
                log.warning(
                    "CAN %s frame timestamps (%.3f) are not host time (%.3f): using the host "
                    "clock at reception",
                    link.spec, msg.timestamp, now,
                )  # fmt: skip
        return float(msg.timestamp) if link.host_stamps else now

    def _send(self, frames: Iterable[can.Message]) -> None:
        """Send on the ISOBUS as the frames are encoded; failures are counted, logged at a
        limited rate, never fatal."""
        link = self.isobus
        bus = None if self._stopping else link.bus
        for msg in frames:
            if bus is None:
                self.stats.frames_unsent += 1
                continue
            try:
                bus.send(msg, timeout=0)
            except (can.CanError, OSError) as exc:
                self.stats.send_errors += 1
                self._send_log.warning(
                    time.monotonic(),
                    f"send on CAN {link.spec} failed: {exc} "
                    f"({self.stats.send_errors} send errors in all)",
                )
                if is_bus_down(exc) and link.reader is not None:
                    link.reader.fail(exc)  # the CAN task reopens the bus
                    bus = None
            else:
                self.stats.frames_sent += 1
                self.echo.sent(msg, time.time())
        self._follow_address()

    # --- status ---------------------------------------------------------------------------

    def _address_text(self) -> str:
        claimer = self.core.claimer
        address = f"0x{claimer.address:02X}" if claimer.address is not None else "none"
        if claimer.state is ClaimState.CLAIMED:
            return f"address {address}"
        if claimer.state is ClaimState.FAILED:
            return "no address free (cannot claim)"
        return f"claiming {address}" if claimer.address is not None else "address not claimed"

    def _mode(self) -> Mode:
        """The mode on the bus: NAVGW_STATUS's last, the engine's before the first."""
        told = self.core.told_mode
        return told if told is not None else self.core.solution().mode

    def status_line(self) -> str:
        """One line: mode, fix, IMU rate, GNSS, address, frames out, and what is missing."""
        sol = self.core.solution()
        fix = sol.fix_quality.name.lower().replace("_", " ") if sol.fix_quality else "none"
        gnss = "GNSS connected" if self.gnss.connected else f"GNSS waiting for {self.gnss.port}"
        parts = [
            self._mode().name.lower(),
            f"fix {fix}",
            f"IMU {self.stats.imu_rate_hz:.1f} Hz",
            gnss,
            self._address_text(),
            f"{self.stats.frames_sent} frames out",
        ]
        parts += [f"CAN {link.spec} {link.waiting}" for link in self.links if link.waiting]
        if self.inbox.overloads:
            parts.append(f"{self.inbox.overloads} inputs dropped (overload)")
        if self.stats.stale_samples:
            parts.append(f"{self.stats.stale_samples} stale IMU samples dropped")
        if self.stats.frames_shed:
            parts.append(f"{self.stats.frames_shed} stale IMU frames shed")
        if self.core.guard.withheld:
            parts.append(f"{self.core.guard.withheld} implausible outputs withheld")
        if self.stats.send_errors:
            parts.append(f"{self.stats.send_errors} send errors")
        if self.core.claimer.name_conflicts:
            parts.append(f"{self.core.claimer.name_conflicts} claims with our NAME (a clone)")
        if self.core.claimer.spoofed_frames:
            parts.append(f"{self.core.claimer.spoofed_frames} frames from our address not ours")
        if (check := self.core.mounting) is not None and check.off:
            off = "; ".join(o.text() for o in check.found)
            parts.append(f"degraded: the drive shows the IMU mounting in effect off ({off})")
        if (arm := self.core.lever_arm) is not None and arm.found is not None:
            parts.append(f"degraded: the drive shows the antenna at {arm.found.text()}")
        if self.mounting is not None:
            parts.append(self.mounting.summary)  # says if a mounting was applied from state
        elif self.applied is not None:
            parts.append(applied_text(self.applied))
        return ", ".join(parts)


async def serve(config: GatewayConfig, notifier: SdNotifier | None = None) -> int:
    """Run the live service until SIGTERM or SIGINT; the exit status."""
    service = GatewayService(config, notifier=notifier or SdNotifier())
    # Everything loaded so far (numpy, cantools' database, the engines) lives as long as the
    # process: out of the collector's generations, a full collection no longer walks it (one
    # was measured at about 17 ms in the hot loop on a 2-core host).
    gc.collect()
    gc.freeze()
    loop = asyncio.get_running_loop()
    for sig in (signal.SIGTERM, signal.SIGINT):
        loop.add_signal_handler(sig, service.request_stop)
    try:
        return await service.run()
    finally:
        for sig in (signal.SIGTERM, signal.SIGINT):
            loop.remove_signal_handler(sig)
