"""What both engines share around their maths: IMU health, held-back epochs, common fields.

The observer and the EKF differ in how they estimate; they do not differ in how they judge
the IMU stream, wait for the IMU to cover a GNSS epoch, or report the receiver's fix and the
IMU's state. One implementation each here, so the two cannot drift apart.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Iterator
from typing import Any, Protocol

from drivers.samples import FixQuality, GnssFix, ImuSample
from drivers.units import GRAVITY_MPS2
from gateway.estimation.lever_arm import LEVER_RATE_HALF_WIDTH_S
from gateway.estimation.solution import MAX_IMU_STEP_S, ImuTiming

#: Epochs ahead of the IMU kept at most (a receiver far ahead of the IMU is a time fault).
MAX_HELD_EPOCHS = 16


class CoastLimits(Protocol):
    """The outage limits both engines' configs carry (SPEC 4's integrity rule)."""

    @property
    def max_coast_s(self) -> float: ...
    @property
    def coast_sigma_m(self) -> float: ...
    @property
    def max_coast_sigma_m(self) -> float: ...


def gap_beyond_s(t_s: float | None, t_rx_s: float | None, timeout_s: float) -> float:
    """Time at ``t_s`` since the receive time ``t_rx_s`` if beyond ``timeout_s``, else 0
    (also before any): how long an engine has been coasting on what ``t_rx_s`` stamps.

    Both engines coast the position from the last epoch that carried one, whatever
    velocities came since. The first epoch after an outage may carry a velocity and no
    position (the GGA lost with the outage, its RMC and VTG through): ending the coast on
    it, the observer sent its dead reckoning 2.0 m off, NAVIGATING, until the next epoch
    (`short` seed 5, a 20 s outage over a headland turn)."""
    if t_s is None or t_rx_s is None:
        return 0.0
    gap = t_s - t_rx_s
    return gap if gap > timeout_s else 0.0


def dead_reckoning_output(
    coasting_s: float, sigma_h_m: float, limits: CoastLimits
) -> tuple[bool, bool]:
    """(the position may go out, it is within COASTING's accuracy) ``coasting_s`` into an
    outage, its horizontal 1-sigma ``sigma_h_m``.

    A dead-reckoned position is sent as COASTING while its 1-sigma is within
    ``coast_sigma_m``, as DEGRADED up to ``max_coast_sigma_m``, then "not available"; and
    never after ``max_coast_s``, whatever the engine believes of its own sigma.
    """
    return (
        coasting_s <= limits.max_coast_s and sigma_h_m <= limits.max_coast_sigma_m,
        sigma_h_m <= limits.coast_sigma_m,
    )


def levelling_correction(
    c_bn9: tuple[float, ...], dba_mps2: tuple[float, float, float]
) -> tuple[float, float, float]:
    """The small rotation phi (NED, rad) that turns an attitude levelled on the mean specific
    force with the accelerometer bias taken as b into the one levelled with b + ``dba``:
    C <- exp([phi]x) C.

    Levelling reads a bias error for tilt: C dba = g (-phi_E, phi_N, .), so phi_N =
    (C dba)_E / g, phi_E = -(C dba)_N / g (the EKF's tilt-bias correlation at alignment, the
    same relation). ``c_bn9``: C_b^n as 9 row-major floats.
    """
    c = c_bn9
    dn = c[0] * dba_mps2[0] + c[1] * dba_mps2[1] + c[2] * dba_mps2[2]
    de = c[3] * dba_mps2[0] + c[4] * dba_mps2[1] + c[5] * dba_mps2[2]
    return (de / GRAVITY_MPS2, -dn / GRAVITY_MPS2, 0.0)


def seeded_exponent(sigma0: float, sigma: float) -> float:
    """The learning exponent at which a sigma model sigma0 exp(-x) says ``sigma``: what a
    seeded observer has learned, in its own terms (never negative: a seed worse than the
    turn-on guess teaches nothing)."""
    return max(0.0, math.log(sigma0 / sigma))


class ImuHealth:
    """The IMU stream judged sample by sample: the step to integrate over (:class:`ImuTiming`),
    and runs of unusable samples (non-finite numbers or time, a saturated or stuck axis) that
    are a FAULT once they last ``fault_s``. The EA alarm (some DIAG_STAT flag, SPEC 1: also the
    user alarm thresholds) leaves the data usable: DEGRADED and bias learning frozen, not a
    FAULT."""

    def __init__(self, fault_s: float) -> None:
        self.fault_s = fault_s
        self.timing = ImuTiming()
        self.alarm = False  # the last sample's EA bit
        # an alarm, saturation or a bridged gap since the engine last cleared it: a tilt
        # error that is none of the biases' (a gap of 0.8 s left 2.8 deg, and eq. (15)'s
        # learning of its decay left 0.07 deg/s of gyro bias error: 0.5 deg of pitch for 10 s)
        self.upset = False
        self.bad_since_s: float | None = None  # start of the current run of unusable samples
        self._bad_for_s = 0.0

    def accept(self, sample: ImuSample) -> float | None:
        """The step to integrate ``sample``'s w_ib_b and f_ib_b over, s, or None for a sample
        to skip (not finite)."""
        t = sample.t
        dt = self.timing.step(sample)
        w = sample.w_ib_b
        f = sample.f_ib_b
        if not (dt > 0.0 and math.isfinite(w[0] + w[1] + w[2] + f[0] + f[1] + f[2] + t)):
            self._mark_bad(t)
            return None
        self.alarm = sample.alarm
        unusable = sample.saturated or sample.stuck
        self.upset |= sample.alarm or unusable or dt > MAX_IMU_STEP_S
        if unusable:
            self._mark_bad(t)
        else:
            self.bad_since_s, self._bad_for_s = None, 0.0
        return dt

    @property
    def fault(self) -> bool:
        """Unusable samples for ``fault_s`` or longer, up to the last one."""
        return self._bad_for_s >= self.fault_s

    @property
    def ok(self) -> bool:
        """The last sample was usable (STATUS 'IMU ok')."""
        return self.bad_since_s is None

    def _mark_bad(self, t: float) -> None:
        if self.bad_since_s is None:
            self.bad_since_s = t
        self._bad_for_s = t - self.bad_since_s


class HeldEpochs(deque[tuple[float, GnssFix]]):
    """GNSS epochs whose time is not yet covered by the IMU, and
    :data:`~gateway.estimation.lever_arm.LEVER_RATE_HALF_WIDTH_S` after it, wait here (a
    receiver less late than that, or a latency under-stated): a correction then compares
    quantities of one instant, and the antenna's lever-arm velocity takes the body rate of
    a window centred on the epoch. With the samples after it missing (a receiver 0-20 ms
    late), the window was the 25 ms before it, 12 ms behind the rate: on ground rocking the
    body +/-2 deg at 2 Hz that put 0.1 m/s into the observer's velocities, and its roll and
    pitch went 3-9 deg off with about 1 deg stated. Held, a correction waits at most that
    half width for its IMU samples; the outputs go on from the inertial solution meanwhile.
    A deque of (epoch time, fix): the engines test it per IMU sample, and a deque's truth
    is tested without a Python call."""

    def __init__(self) -> None:
        super().__init__(maxlen=MAX_HELD_EPOCHS)

    def hold(self, t_e: float, fix: GnssFix, t_imu: float | None) -> bool:
        """Keep the epoch of time ``t_e`` if the IMU has not covered it and the half window
        after it; True if kept."""
        if t_imu is not None and t_e + LEVER_RATE_HALF_WIDTH_S <= t_imu:
            return False
        self.append((t_e, fix))
        return True

    def due(self, t_imu: float) -> Iterator[tuple[float, GnssFix]]:
        """(epoch time, fix) of each held epoch the IMU has now covered, oldest first."""
        while self and self[0][0] + LEVER_RATE_HALF_WIDTH_S <= t_imu:
            yield self.popleft()


#: :class:`Solution`'s fields of the receiver's last fix, in their order (:func:`fix_fields`).
FIX_FIELDS = (
    "fix_quality", "num_sats", "hdop", "age_s", "geoid_sep_m", "reference_station_id", "talker",
)  # fmt: skip
FixFields = tuple[FixQuality | None, int | None, float | None, float | None, float | None,
                  int | None, str | None]  # fmt: skip
_NO_FIX: FixFields = (None, None, None, None, None, None, None)


def fix_fields(fix: GnssFix | None) -> FixFields:
    """The receiver's last fix as every engine reports it, in the order of :data:`FIX_FIELDS`
    (a tuple: the engines build a solution 50 times a second, positionally)."""
    if fix is None:
        return _NO_FIX
    return (
        fix.quality, fix.num_sats, fix.hdop, fix.age_s, fix.geoid_sep_m,
        fix.reference_station_id, fix.talker,
    )  # fmt: skip


def common_fields(t: float | None, fix: GnssFix | None, imu: ImuHealth) -> dict[str, Any]:
    """The :class:`Solution` fields every engine reports the same way, as keywords: the
    receiver's last fix (:func:`fix_fields`) and the IMU's state, at the time of the last IMU
    sample (0 before any)."""
    common: dict[str, Any] = dict(zip(FIX_FIELDS, fix_fields(fix), strict=True))
    common.update(
        t=t if t is not None else 0.0, imu_alarm=imu.alarm, imu_ok=t is not None and imu.ok
    )
    return common
