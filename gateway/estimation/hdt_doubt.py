"""A dual-antenna heading (HDT) the courses contradict: not used until it agrees again.

Both engines take an HDT as their best heading reference, and each screens it for jumps
(the observer against the gyro's turn, the EKF in its innovation gate). An HDT that drifts
(0.2 deg/s for a minute: multipath on one antenna, a baseline solution walking) passes
either epoch by epoch: the heading followed it 12-14 deg off, NAVIGATING (custom `field`
seed 669 with HDT, both engines). The courses over ground tell it: their mean over the
heading window (:class:`gateway.estimation.bias_change.CorrectionWindow`) left the heading
the HDT steered. Such an HDT is not used for :data:`DOUBT_HOLD_S`, in which the courses
bring the heading back, and after that only once it agrees with the heading held (its
offset within ``k`` sigma of the two, plus :data:`AGREE_FLOOR_RAD`, as the observer's HDT
screen asks within a spell of rejections).
"""

from __future__ import annotations

import math

from drivers.units import DEG_TO_RAD
from gateway.estimation.bias_change import WINDOW_S

#: Courses take a heading 2-3 deg off back within seconds (at 3 m/s a course is 0.4 deg
#: 1-sigma, ten of them a second); an HDT tried again sooner met a heading still off and
#: a heading sigma still open, and was taken back.
DOUBT_HOLD_S = 10.0
#: Beyond the two sigmas: the receiver's own smoothing and timing of its heading.
AGREE_FLOOR_RAD = 0.5 * DEG_TO_RAD


class HdtDoubt:
    """Whether an HDT may be used: always, but from a doubt (:meth:`doubt`) for
    :data:`DOUBT_HOLD_S`, and then until one agrees with the heading held."""

    def __init__(self) -> None:
        self._since_s: float | None = None

    def doubt(self, t_s: float) -> None:
        """The courses contradicted the heading an HDT steered at ``t_s``."""
        self._since_s = t_s

    def admits(
        self, t_s: float, offset_rad: float, sigma_psi_rad: float, sigma_hdt_rad: float, k: float
    ) -> bool:
        """Use the HDT of epoch ``t_s``, ``offset_rad`` off the heading held (1-sigma
        ``sigma_psi_rad``; the HDT's ``sigma_hdt_rad``)? Agreeing within ``k`` sigma after
        the hold ends the doubt."""
        if self._since_s is None:
            return True
        if t_s - self._since_s < DOUBT_HOLD_S:
            return False
        if abs(offset_rad) > k * math.hypot(sigma_psi_rad, sigma_hdt_rad) + AGREE_FLOOR_RAD:
            return False
        self._since_s = None
        return True


def hdt_doubt_text(t_s: float, offset_rad: float) -> str:
    """The warning when an HDT is doubted (both engines)."""
    return (
        f"HDT at t={t_s:.3f}: the courses over ground were {offset_rad / DEG_TO_RAD:.2f} deg "
        f"off the heading it steered over the last {WINDOW_S:g} s (a drifting dual-antenna "
        "solution); "
        f"HDT not used for {DOUBT_HOLD_S:g} s and then until it agrees with the heading held"
    )
