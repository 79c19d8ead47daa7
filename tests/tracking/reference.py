"""A TrackManager that applies a frame's updates one at a time, as it did before screening was batched.

Each ADS-B report is checked for plausibility at its turn and every measurement goes through
``TrackManager._apply`` (screen, then update) in the frame's order, so an ``on_event`` callback sees a
track's filter exactly at the event; the oracle of the batched path (``TrackFilter.screen_many``).
"""

import math

from radartracker.domain import AdsbReport
from radartracker.tracking.manager import TrackManager


class OneAtATimeManager(TrackManager):
    def _apply_all(self, updates):
        for _, _, tr, row, src in updates:
            if type(src) is AdsbReport and self.config.screening.enabled:
                m = self._meas
                why = self.adsb_check.check(src.icao24, src.time, m.z[row], math.sqrt(m.R[row, 0, 0]), src.nacp)
                if why is not None:
                    self.counts[why] += 1
                    continue
            self._apply(tr, row, src)
