"""What a replay was fed, counted on the way in: GNSS fix qualities and IMU temperatures.

Neither reaches the output log, so the tally rides on replay's ``progress`` hook
(:data:`gateway.offline.log_replay.Progress`): it sees every merged input once, as the
fusion core does, and passes it on unchanged.
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field

from drivers.samples import FixQuality, GnssFix, ImuAux
from gateway.offline.log_inputs import Input, LogInputs


@dataclass
class InputTally:
    """Counts GNSS fixes by quality and keeps the IMU temperature's range (deg C)."""

    fixes: Counter[FixQuality] = field(default_factory=Counter)
    temp_min_c: float = math.inf
    temp_max_c: float = -math.inf

    def __call__(self, items: Iterable[Input], inputs: LogInputs) -> Iterator[Input]:
        """Replay's progress hook: yields ``items`` as they come, tallying on the way."""
        for item in items:
            if isinstance(item, GnssFix):
                self.fixes[item.quality] += 1
            elif isinstance(item, ImuAux):
                self.temp_min_c = min(self.temp_min_c, item.temp_c)
                self.temp_max_c = max(self.temp_max_c, item.temp_c)
            yield item

    def share(self, *qualities: FixQuality) -> float:
        """Fraction of the fixes that had one of ``qualities`` (NaN without fixes)."""
        total = sum(self.fixes.values())
        return sum(self.fixes[q] for q in qualities) / total if total else math.nan
