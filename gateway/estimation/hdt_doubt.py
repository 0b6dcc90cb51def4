"""A dual-antenna heading (HDT) the courses contradict: not used until they agree again.

Both engines take an HDT as their best heading reference, and each screens it for jumps
(the observer against the gyro's turn, the EKF in its innovation gate). An HDT that drifts
(0.2 deg/s for a minute: multipath on one antenna, a baseline solution walking) passes
either epoch by epoch: the heading followed it 12-14 deg off, NAVIGATING (custom `field`
seed 669 with HDT, both engines). The courses over ground tell it: their mean over the
heading window (:class:`gateway.estimation.bias_change.CorrectionWindow`) left the heading
the HDT steered. Such an HDT is used again once the courses agree with it: HDT less course
over a window of its own, within ``K_EXCESS`` of that mean's sigma, the courses spanning
``COURSES_SPAN_S``. Agreeing with the heading held instead let it back at a stop 10 s
later, the heading's sigma re-opened by the doubt wide enough to pass an HDT 1.7 deg off
(`steep-turns` seed 670, 0.1 deg/s): NAVIGATING 2.6 deg off until the courses found it
again.
"""

from __future__ import annotations

from drivers.units import DEG_TO_RAD
from gateway.estimation.bias_change import WINDOW_S, CorrectionWindow


class HdtDoubt:
    """Whether an HDT may be used: always, but from a doubt (:meth:`doubt`) until the
    courses since agree with the HDTs (:meth:`add_course`)."""

    def __init__(self) -> None:
        self._doubted = False
        self._courses = CorrectionWindow("hdt")  # HDT less course while doubted

    def doubt(self) -> None:
        """The courses contradicted the heading an HDT steered."""
        self._doubted = True
        self._courses.clear()

    def add_course(
        self,
        t_s: float,
        hdt_less_course_rad: float,
        sigma_rad: float,
        yaw_rate_rps: float,
        interval_s: float,
    ) -> None:
        """An epoch's HDT less its course, rad, their joint 1-sigma, the yaw rate and the
        epoch interval (:meth:`CorrectionWindow.add_course`); kept while doubted."""
        if self._doubted:
            self._courses.add_course(t_s, hdt_less_course_rad, sigma_rad, yaw_rate_rps, interval_s)

    def admits(self) -> bool:
        """Use the epoch's HDT? Not while doubted, until the courses agree with it."""
        if self._doubted and self._courses.courses_agree():
            self._doubted = False
        return not self._doubted


def hdt_doubt_text(t_s: float, offset_rad: float) -> str:
    """The warning when an HDT is doubted (both engines)."""
    return (
        f"HDT at t={t_s:.3f}: the courses over ground were {offset_rad / DEG_TO_RAD:.2f} deg "
        f"off the heading it steered over the last {WINDOW_S:g} s (a drifting dual-antenna "
        "solution); HDT not used until the courses agree with it again"
    )
