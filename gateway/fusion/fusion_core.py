"""The fusion core: decoded inputs in time order in, frames to send out. No I/O, no clock.

Live service, replay and demo all drive this one class; only the sources of inputs and
time differ. Per IMU sample: propagate the engine, advance the address claim, and when a
PGN is due (and the address is held) pass the current solution through the
:class:`~gateway.fusion.output_guard.OutputGuard` and encode it. GNSS fixes go to the engine as they
come; frames received from the ISOBUS go to the address claim, then to the
:class:`~gateway.isobus.network.NetworkManager` (requests, commanded address), which also
sends the heartbeat (looked at per IMU sample and poll with one comparison). While the claim
has seen a clone of us (our NAME, or frames from our address that we did not send),
NAVGW_STATUS says DEGRADED; so it does once the drive has shown the IMU mounting in effect
tilted off the vehicle's axes (:mod:`gateway.fusion.mounting_check`), or the antenna's height
above the reference point off the configured lever arm (:mod:`gateway.fusion.lever_arm_check`),
each fed each fix with the engine's next solution made for the bus: none made for it alone.

Frames come back as iterators that encode as they are taken: a caller that sends while it
iterates puts the attitude on the bus first (see :meth:`OutputScheduler.frames`).

The IMU drives the outputs, so without it nothing would go out: when no sample has come for
:data:`IMU_SILENT_S`, every other input and timer tick (the live loop's, a GNSS fix in replay)
sends NAVGW_STATUS alone at its rate, saying FAULT with the IMU not ok and the samples missing
in byte 6 (SPEC 4: an outage is reported, not silent). A gap of :data:`RESTART_GAP_S` or more
restarts the engine: the motion over it is unknown, and a solution carried across it would be
a guess. Inputs come on core time, the host clock less its steps (:mod:`drivers.host_clock`); a
step forward by whole SEQ wraps the IMU decoder takes for an outage, and the epoch clock is
told when sample times jump with the SEQ going on. A saturated sample (an axis at the end of
its register) or a stuck one (an axis's word unchanged sample after sample,
:mod:`drivers.axis_checks`) is no measurement: it is not fed to the engine, NAVGW_STATUS says
FAULT from that sample on, and when the IMU measures again the engine restarts (the rotation
meanwhile is unknown: 2 s of full-scale gyro left the attitude 179 deg off, then above 1 deg
for 35 s, while STATUS said navigating; a 10 s freeze left roll 4 deg off).
A restarted engine starts from what the one it replaces had learned of the IMU's biases
(:meth:`LearningEstimator.learned_state`, with its sigmas): the IMU is the same. An engine
that raises (a bug some input reached) is replaced too, from cold, and NAVGW_STATUS says
FAULT until the new one has aligned: the gateway goes on (:meth:`FusionCore._engine_raised`).

Warm start: the shell may give a ``warm_start`` callback (:mod:`gateway.state`), which the
core asks once, with the IMU's temperature and the time of the first IMU_AUX (1 Hz), for
the learned state to seed the engine with; without IMU_AUX within :data:`WARM_START_WAIT_S`
of the first sample the engine stays cold (the state is kept per temperature, and a guess
of the temperature would be a guess of the biases). The seed is used only once the vehicle
has stood still a few seconds (:mod:`gateway.fusion.rest_check`: 1 s to settle, 3 s of means)
on the spot where it last stopped and the IMU measures there what it measured then
(:func:`gateway.fusion.rest_check.check_seed`):
a new power-on may have moved the biases. Driven off before, the start is cold. The rest
itself is followed (:attr:`FusionCore.rest`) whenever the shell keeps a state.
"""

from __future__ import annotations

import logging
import math
import random
from collections import deque
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, replace
from functools import partial
from importlib import metadata
from itertools import chain
from typing import Protocol

import can

from drivers.samples import Float3, GnssFix, ImuAux, ImuCounters, ImuSample
from gateway.config.gateway_config import GatewayConfig
from gateway.estimation.epoch_clock import EpochClock
from gateway.estimation.heading_hint import HeadingHint
from gateway.estimation.imu_noise import ImuNoiseMeter
from gateway.estimation.solution import LearnedState, LearningEstimator, Mode, Solution
from gateway.fusion.engines import epoch_clock, make_engine
from gateway.fusion.lever_arm_check import LeverArmCheck
from gateway.fusion.mounting_check import MountingCheck
from gateway.fusion.output_guard import OutputGuard
from gateway.fusion.rest_check import (
    MIN_REST_S,
    SETTLE_S,
    RestMean,
    WarmSeed,
    check_seed,
    drove_off,
)
from gateway.isobus.address_claim import AddressClaimer, Name
from gateway.isobus.device_info import ProductInfo
from gateway.isobus.j1939 import DEFAULT_SOURCE_ADDRESS, Pgn
from gateway.isobus.n2k_encode import LoopStatus, OutputEncoder
from gateway.isobus.network import NetworkManager
from gateway.isobus.output_scheduler import OutputScheduler

log = logging.getLogger(__name__)

LOST_WINDOW_S = 1.0  # NAVGW_STATUS byte 6: IMU samples lost in the last second
#: No IMU sample for this long: NAVGW_STATUS goes on alone, saying FAULT (40 periods at
#: 204.8 Hz; the service's tick looks every 50 ms).
IMU_SILENT_S = 0.2
#: A gap this long in the IMU stream, or time going back this much, restarts the engine
#: (30 s of silence carried across put the EKF's first position 84 m off while navigating).
RESTART_GAP_S = 1.0
#: IMU sample times this much apart, either way, with the SEQ going on jumped with the host
#: clock's: a step forward by whole SEQ wraps (at least 0.3125 s, at 819.2 Hz) or an outage
#: of as many samples, or a step before the IMU's anchor had settled
#: (:meth:`gateway.estimation.epoch_clock.EpochClock.host_jumped`).
JUMP_S = 0.25
#: A warm start waits this long after the first IMU sample for the IMU's temperature (the
#: first IMU_AUX; the bridge sends it at 1 Hz), then the engine stays cold.
WARM_START_WAIT_S = 3.0

#: (IMU temperature degC, time s) -> the learned state to seed the engine with, and the rest
#: to check it against; or None.
WarmStart = Callable[[float, float], WarmSeed | None]


#: What an input that sends nothing returns (no generator per IMU sample); callers may skip
#: it by identity.
NOTHING: Iterator[can.Message] = iter(())


@dataclass(frozen=True, slots=True)
class BusFrame:
    """An ISOBUS frame from a recording (another node's address claim or request), at the
    time it was received: replay feeds it to the network as the live service does."""

    t: float
    msg: can.Message


@dataclass
class FusionStats:
    """Counts of what went through the core."""

    imu_samples: int = 0
    imu_aux: int = 0
    gnss_fixes: int = 0
    frames_out: int = 0
    imu_dropped: int = 0  # samples the live loop dropped before the engine (overload, stale)
    engine_restarts: int = 0  # after a gap of RESTART_GAP_S in the IMU stream, or unusable samples
    engine_faults: int = 0  # the engine raised: logged, FAULT, a new engine from cold
    imu_saturated: int = 0  # samples withheld from the engine: an axis at its range's end
    imu_stuck: int = 0  # samples withheld from the engine: an axis's word stuck
    imu_timing_unknown: int = 0  # ... and samples whose time the driver does not know yet


class ImuLossCount(Protocol):
    """Where the core reads how many IMU samples were lost on the bus so far: live, the
    decoder's :class:`~drivers.samples.ImuCounters`; in replay, which decodes ahead, the count
    as of the input in hand (:class:`~gateway.offline.log_inputs.SeenLoss`)."""

    @property
    def lost(self) -> int: ...


class FusionCore:
    """Feeds the engine, runs the address claim and the output scheduler."""

    def __init__(
        self,
        engine: LearningEstimator,
        scheduler: OutputScheduler,
        claimer: AddressClaimer,
        network: NetworkManager,
        imu_lost: ImuLossCount | None = None,
        make_engine: Callable[[], LearningEstimator] | None = None,
        warm_start: WarmStart | None = None,
        track_rest: bool = False,
        mounting: MountingCheck | None = None,
        lever_arm: LeverArmCheck | None = None,
        lever_arm_ant_m: Float3 = (0.0, 0.0, 0.0),
        epoch_clock: EpochClock | None = None,
    ) -> None:
        """``track_rest``: follow the rests for the learned state (the shell keeps one);
        ``mounting``, ``lever_arm``: the checks of the IMU mounting and of the antenna lever
        arm in effect (None: none); ``lever_arm_ant_m``: the configured antenna lever arm
        (the guard's position accuracy); ``epoch_clock``: the engines' (told when the IMU's
        times jump with the host clock's)."""
        self.engine = engine
        self._make_engine = make_engine  # for a restart; None: the engine carries on
        self.scheduler = scheduler
        self.claimer = claimer
        self.network = network
        self.guard = OutputGuard(lever_arm_ant_m=lever_arm_ant_m)
        self.stats = FusionStats()
        self._imu_lost = imu_lost or ImuCounters()
        self._lost_marks: deque[tuple[float, int]] = deque()  # (t, cumulative lost)
        self._last_sample: ImuSample | None = None
        self._unusable = False  # saturated or stuck samples since the last good one
        self._told_mode: Mode | None = None  # mode of the last NAVGW_STATUS sent
        self._loop = LoopStatus()  # the last loop status made (:meth:`loop_status`)
        self._last_unusable_log = -math.inf
        self._last_fault_log = -math.inf
        self._faulted = False  # the engine raised: FAULT until the new one has aligned
        self._warm_start = warm_start  # asked once, at the first IMU_AUX
        self._t_first_imu: float | None = None
        self.imu_temp_c: float | None = None  # the last IMU_AUX's temperature
        self.warm_started = False  # the engine started from a learned state
        self.rest = RestMean() if track_rest or warm_start is not None else None
        self._pending_seed: WarmSeed | None = None  # to check at rest on the same spot
        self.mounting = mounting
        self.lever_arm = lever_arm
        self._fix_to_check: GnssFix | None = None  # for the checks, with the next solution
        self.epoch_clock = epoch_clock

    @classmethod
    def from_config(
        cls,
        config: GatewayConfig,
        imu_lost: ImuLossCount | None = None,
        warm_start: WarmStart | None = None,
        track_rest: bool = False,
    ) -> FusionCore:
        """Engine, scheduler, claimer and network as the config says; ``warm_start``: where
        the learned state comes from (None: every start is cold); ``track_rest``: follow the
        rests for the learned state."""
        clock = epoch_clock(config)  # one for every engine of this core (restarts included)
        noise = ImuNoiseMeter()  # the same
        isobus = config.isobus
        name = Name(
            identity_number=isobus.identity_number,
            manufacturer_code=isobus.manufacturer_code,
            ecu_instance=isobus.ecu_instance,
            function_instance=isobus.function_instance,
            function=isobus.device_function,
            vehicle_system=isobus.device_class,
        )
        scheduler = OutputScheduler(
            config.output.rates_hz(), OutputEncoder(isobus.manufacturer_code)
        )
        # Seeded by the NAME: replay is deterministic, and two units differ in identity.
        claimer = AddressClaimer(
            name,
            isobus.preferred_address,
            random.Random(name.value()),
            reserved=(config.imu.bridge_source_address,),
        )
        product = ProductInfo(
            product_code=isobus.product_code,
            model_id=isobus.model_id,
            software_version=metadata.version("navgw"),
            model_version=isobus.model_version,
            serial_code=str(isobus.identity_number),
            load_equivalency=isobus.load_equivalency,
        )
        return cls(
            engine=make_engine(config, clock, noise),
            make_engine=partial(make_engine, config, clock, noise),
            scheduler=scheduler,
            claimer=claimer,
            network=NetworkManager(claimer, product, periodic=scheduler.rates_hz),
            imu_lost=imu_lost,
            warm_start=warm_start,
            track_rest=track_rest,
            mounting=MountingCheck(
                config.vehicle.antenna_lever_arm_m, config.vehicle.imu_mounting_sigma_deg
            ),
            lever_arm=LeverArmCheck(config.vehicle.antenna_lever_arm_m),
            lever_arm_ant_m=config.vehicle.antenna_lever_arm_m,
            epoch_clock=clock,
        )

    def start(self, now: float) -> Iterator[can.Message]:
        """Begin the address claim; nothing else is sent until it completes."""
        return self._counted(self.claimer.start(now))

    def on_input(self, item: ImuSample | ImuAux | GnssFix | BusFrame) -> Iterator[can.Message]:
        """Dispatch one decoded input; returns the frames to send now."""
        if isinstance(item, ImuSample):
            return self.on_imu(item)
        if isinstance(item, BusFrame):
            return self.on_bus_frame(item.msg, item.t)
        if isinstance(item, GnssFix):
            self.stats.gnss_fixes += 1
            try:
                self.engine.gnss(item)
            except Exception as err:  # a bug must not stop the gateway: _engine_raised
                return self._counted(self._engine_raised(item.t, "a GNSS fix", err))
            if item.measures and (self.mounting is not None or self.lever_arm is not None):
                self._fix_to_check = item
            if self.rest is not None:
                self.rest.gnss(item)
                if self._pending_seed is not None:
                    self._drove_off(item)
        else:
            self.stats.imu_aux += 1  # temperature, supply, DIAG_STAT: counted by the decoder
            self.imu_temp_c = item.temp_c
            try:
                self.engine.temperature(item.t, item.temp_c)
            except Exception as err:  # a bug must not stop the gateway: _engine_raised
                return self._counted(self._engine_raised(item.t, "an IMU temperature", err))
            if self._warm_start is not None:
                self._seed_engine(item.temp_c, item.t)
        return self._counted(self._silent_status(item.t))

    def _seed_engine(self, temp_c: float, t: float) -> None:
        """The learned state for ``temp_c`` (asked once), to check at rest before use."""
        warm_start, self._warm_start = self._warm_start, None
        assert warm_start is not None
        self._pending_seed = warm_start(temp_c, t)
        if self._pending_seed is not None:
            self._check_seed(t)

    def _check_seed(self, t: float) -> None:
        """Seed the engine once a rest of the start can be compared with the stored one."""
        seed, rest = self._pending_seed, self.rest
        assert seed is not None and rest is not None
        now = rest.current()
        if seed.rest is None:
            learned, why = None, "no rest stored with it to check it against"
        else:
            if now is None:
                return
            learned, why = check_seed(seed.learned, seed.rest, now)
        self._pending_seed = None
        if learned is None:
            log.warning("learned state not used at t=%.3f: %s; cold start", t, why)
        elif self.engine.seed(learned, None if now is None else now.f_b_mps2):
            self.warm_started = True
            log.info("warm start at t=%.3f, %s: %s", t, why, learned_text(learned))
        else:
            log.warning(
                "warm start at t=%.3f not applied: the engine had begun to learn on its own "
                "(or the learned state is not valid); cold start", t,
            )  # fmt: skip

    def _drove_off(self, fix: GnssFix) -> None:
        """A fix of a moving vehicle before the seed was checked: a cold start."""
        if drove_off(fix):
            self._pending_seed = None
            log.warning(
                "learned state not used at t=%.3f: the vehicle drove off before it had stood "
                "%.0f s on the spot where it last stopped, which would have checked it; cold "
                "start", fix.t, SETTLE_S + MIN_REST_S,
            )  # fmt: skip

    def on_imu(self, sample: ImuSample) -> Iterator[can.Message]:
        """Propagate with one sample, then send whatever is due at its time."""
        self.stats.imu_samples += 1
        t = sample.t
        if sample.saturated or sample.stuck or sample.timing_unknown:
            return self._on_unusable(sample)
        if self._warm_start is not None:
            self._wait_for_temperature(t)
        last = self._last_sample
        gap = False
        if last is not None and abs(t - last.t) > JUMP_S:  # a RESTART_GAP_S gap is over it too
            gap = abs(t - last.t) >= RESTART_GAP_S
            if (sample.seq - last.seq) & 0xFF == 1 and self.epoch_clock is not None:
                self.epoch_clock.host_jumped(t - last.t - sample.dt)
        if gap or self._unusable:
            self._restart_engine(last if gap else None, t)
        self._last_sample = sample
        try:
            self.engine.imu(sample)
        except Exception as err:  # a bug must not stop the gateway: _engine_raised
            return self._counted(self._engine_raised(t, "an IMU sample", err))
        if self.lever_arm is not None:
            self.lever_arm.imu(t, sample.w_ib_b)
        rest = self.rest
        if rest is not None:
            rest.imu(sample)
            if self._pending_seed is not None:
                self._check_seed(t)
        # Most samples send nothing: a few comparisons, no call, no generator.
        claimer = self.claimer
        polled = (
            self._timers(t) if t >= claimer.timer_t or t >= self.network.next_heartbeat_t else None
        )
        if not (t >= self.scheduler.next_due_t and claimer.claimed):
            return self._counted(polled) if polled else NOTHING
        try:
            sol = self.engine.solution()
        except Exception as err:  # a bug must not stop the gateway: _engine_raised
            fault = self._engine_raised(t, "its solution", err)
            return self._counted(chain(polled, fault) if polled else fault)
        if self.mounting is not None:
            self.mounting.solution(sol)
        if self._fix_to_check is not None:
            self._check_geometry(sol)
        if self._faulted:
            sol = self._fault_held(sol)
        sent = self._attributable(self.guard.check(sol), t)
        frames = self.scheduler.frames(sent, self.loop_status(t), now=self._told(sent.mode))
        return self._counted(chain(polled, frames) if polled else frames)

    def _check_geometry(self, sol: Solution) -> None:
        """The last fix, with the first solution after it (one output period at most), to
        the checks of the mounting and the lever arm."""
        fix = self._fix_to_check
        assert fix is not None
        if self.mounting is not None:
            self.mounting.epoch(fix, sol)
        if self.lever_arm is not None:
            self.lever_arm.epoch(fix, sol)
        self._fix_to_check = None

    @property
    def geometry_off(self) -> bool:
        """The drive has shown the IMU mounting or the antenna lever arm in effect off."""
        return (self.mounting is not None and self.mounting.off) or (
            self.lever_arm is not None and self.lever_arm.off
        )

    def _on_unusable(self, sample: ImuSample) -> Iterator[can.Message]:
        """A saturated or stuck sample, or one whose time the driver does not know yet: not
        fed to the engine; NAVGW_STATUS says FAULT.

        Why the time: after an outage of the IMU's frames longer than a SEQ wrap (1.25 s at
        204.8 Hz) the driver takes a quarter second of arrivals to tell it from a host stall,
        and until then stamps the samples a wrap early. Fed to the engine, they turned the
        platform by the motion after the outage as if none had passed: pitch 1.9 deg off
        with 0.59 stated (`short` seed 421, a 1.3 s outage at 33 s), both engines."""
        if sample.saturated:
            self.stats.imu_saturated += 1
            what = "saturated (an axis at the end of its range)"
        elif sample.stuck:
            self.stats.imu_stuck += 1
            what = "stuck (an axis's output unchanged sample after sample)"
        else:
            self.stats.imu_timing_unknown += 1
            what = "sample time unknown (frames late after a SEQ gap: an outage or a stall)"
        if not self._unusable and sample.t - self._last_unusable_log >= 10.0:
            log.warning(
                "IMU %s at t=%.3f: attitude unknown, FAULT until the engine has re-aligned",
                what,
                sample.t,
            )
            self._last_unusable_log = sample.t
        self._unusable = True
        return self._counted(chain(self._timers(sample.t), self._fault(sample.t)))

    def _restart_engine(self, last: ImuSample | None, t: float) -> None:
        """A new engine after a gap since ``last`` (None: after unusable samples), seeded with
        what the old one had learned; without a factory the engine carries on."""
        self._unusable = False
        if self._make_engine is None:
            return
        learned = self.engine.learned_state()
        old = self.engine.solution()
        self.engine = self._make_engine()
        if learned is not None:
            self.engine.seed(learned)
        if not old.stationary:
            self.engine.moving_before()
        if last is not None and old.yaw_rad is not None:
            hint = HeadingHint.over_gap(old.yaw_rad, old.yaw_rate_rps or 0.0, t - last.t)
            if hint is not None:
                self.engine.heading_before(hint)
        self.guard.forget_track()
        self.stats.engine_restarts += 1
        if last is not None:
            log.warning(
                "IMU samples resumed %.3f s after the last one at t=%.3f: the engine "
                "restarts (re-aligned before anything is sent)", t - last.t, last.t,
            )  # fmt: skip

    def _engine_raised(self, t: float, what: str, err: Exception) -> Iterable[can.Message]:
        """The engine raised on ``what`` at ``t``: a bug that some input reached. It must
        not stop the gateway: the bus would go silent until systemd restarted the service,
        and the input that reached it may come again (an overloaded host's epochs out of
        time order had the observer raise, stopping the service, before the epoch clock was
        made to drop them). Logged with its traceback (at most once per 10 s), counted, and
        replaced by a new engine from cold (what the failed one learned is not trusted),
        which aligns again; NAVGW_STATUS says FAULT until it has (:meth:`_fault_held`: its
        INITIALISING and ALIGNING would look like a normal start). Without a factory there
        is no engine to go on with: ``err`` is raised."""
        if self._make_engine is None:
            raise err
        self.stats.engine_faults += 1
        if t - self._last_fault_log >= 10.0:
            log.error(
                "the engine raised on %s at t=%.3f (%s: %s): a new engine from cold, FAULT "
                "until it has aligned (%d in all)", what, t,
                type(err).__name__, err, self.stats.engine_faults, exc_info=err,
            )  # fmt: skip
            self._last_fault_log = t
        self.engine = self._make_engine()
        self.engine.moving_before()
        self.guard.forget_track()
        self._fix_to_check = None
        self._faulted = True
        return self._fault(t)

    def _fault_held(self, sol: Solution) -> Solution:
        """``sol`` of the engine that replaced one that raised: FAULT while it initialises
        and aligns, then as it is."""
        if sol.mode in (Mode.INITIALISING, Mode.ALIGNING):
            return replace(sol, mode=Mode.FAULT)
        self._faulted = False
        return sol

    def _wait_for_temperature(self, t: float) -> None:
        """No IMU_AUX within WARM_START_WAIT_S of the first IMU sample: stay cold."""
        if self._t_first_imu is None:
            self._t_first_imu = t
        elif t - self._t_first_imu > WARM_START_WAIT_S:
            self._warm_start = None
            log.warning(
                "no IMU temperature (IMU_AUX) within %g s of the first IMU sample: cold start "
                "(learned biases are kept per temperature)", WARM_START_WAIT_S,
            )  # fmt: skip

    def on_bus_frame(self, msg: can.Message, now: float) -> Iterator[can.Message]:
        """A frame received from the ISOBUS (address claims, requests, transport frames,
        frames from our address), not our own echo: the claimer first, then the network."""
        claimed = self.claimer.on_frame(msg, now)
        return self._counted(claimed + self.network.on_frame(msg, now))

    def _attributable(self, sol: Solution, now: float) -> Solution:
        """``sol``, DEGRADED (or worse) while another node recently claimed our NAME or sent
        from our address: a controller cannot tell which frames with our address are ours.
        DEGRADED, not FAULT: our own solution is sound, and FAULT would say it is not. So
        too once the mounting or the lever arm in effect was seen off: roll and pitch are off
        by it."""
        if self.claimer.conflict(now) or self.geometry_off:
            return replace(sol, mode=max(sol.mode, Mode.DEGRADED))
        return sol

    def poll(self, now: float) -> Iterator[can.Message]:
        """Advance timers without an input (the live loop calls this when the IMU is silent)."""
        return self._counted(chain(self._timers(now), self._silent_status(now)))

    def _timers(self, now: float) -> list[can.Message]:
        """What the claim's timers send, and the heartbeat when it is due (one comparison
        per sample otherwise), equipment status FAULT while NAVGW_STATUS says FAULT."""
        polled = self.claimer.poll(now)
        if now >= self.network.next_heartbeat_t:
            polled += self.network.heartbeat(now, fault=self._told_mode is Mode.FAULT)
        return polled

    def _silent_status(self, now: float) -> Iterable[can.Message]:
        """NAVGW_STATUS alone, FAULT, when no IMU sample has come for IMU_SILENT_S."""
        last = self._last_sample
        if last is not None and now - last.t < IMU_SILENT_S:
            return ()
        return self._fault(now)

    def _fault(self, now: float) -> Iterable[can.Message]:
        """NAVGW_STATUS alone at its rate: FAULT, IMU not ok, the samples missing since the
        last good one in byte 6."""
        if not self.claimer.claimed:
            return ()
        last = self._last_sample
        sol = self.engine.solution()
        silent = Solution(
            t=now,
            mode=Mode.FAULT,
            fix_quality=sol.fix_quality,
            gnss_ok=sol.gnss_ok,
            is_ekf=sol.is_ekf,
            convergence=sol.convergence,
        )
        loop = self.loop_status(now)
        if last is not None:
            missing = math.floor(min(now - last.t, LOST_WINDOW_S) / last.dt)
            loop = replace(loop, imu_samples_lost=loop.imu_samples_lost + missing)
        else:
            loop = replace(loop, imu_samples_lost=255)
        only = (Pgn.NAVGW_STATUS,)
        return self.scheduler.frames(silent, loop, only=only, now=self._told(Mode.FAULT))

    def _told(self, mode: Mode) -> tuple[Pgn, ...]:
        """NAVGW_STATUS at once when ``mode`` is not the one the bus was last told, else
        nothing beyond its 10 Hz: a frame sent in a new mode (DEGRADED after a gap, FAULT)
        goes out with the status that says so, not up to 0.1 s before it."""
        if mode is self._told_mode:
            return ()
        self._told_mode = mode
        return (Pgn.NAVGW_STATUS,)

    def _counted(self, frames: Iterable[can.Message]) -> Iterator[can.Message]:
        for msg in frames:
            self.stats.frames_out += 1
            yield msg

    def solution(self) -> Solution:
        """The engine's current solution."""
        return self.engine.solution()

    @property
    def told_mode(self) -> Mode | None:
        """The mode NAVGW_STATUS last said (the engine's, or worse: a clone of us, the
        mounting seen off, the IMU silent; None before the first)."""
        return self._told_mode

    def loop_status(self, t: float) -> LoopStatus:
        """What the loop adds to the solution: address, claim state, recent IMU losses (on
        the bus, and dropped by the live loop). The same object while none of it changes."""
        lost = self._imu_lost.lost + self.stats.imu_dropped
        marks = self._lost_marks
        marks.append((t, lost))
        while marks and marks[0][0] < t - LOST_WINDOW_S:
            marks.popleft()
        claimer = self.claimer
        loop = self._loop
        address = claimer.address or DEFAULT_SOURCE_ADDRESS
        lost_s = lost - marks[0][1]
        if (
            loop.source_address != address
            or loop.address_claimed is not claimer.claimed
            or loop.imu_samples_lost != lost_s
        ):
            loop = self._loop = LoopStatus(address, claimer.claimed, lost_s)
        return loop


def learned_text(learned: LearnedState) -> str:
    """Biases with their 1-sigma, one line: gyro deg/s, accelerometer m/s^2."""
    g = ", ".join(
        f"{math.degrees(b):+.4f}+/-{math.degrees(sd):.4f}"
        for b, sd in zip(learned.bias_g_rps, learned.sigma_g_rps, strict=True)
    )
    a = ", ".join(
        f"{b:+.4f}+/-{sd:.4f}"
        for b, sd in zip(learned.bias_a_mps2, learned.sigma_a_mps2, strict=True)
    )
    return f"gyro bias {g} deg/s, accelerometer bias {a} m/s^2"
