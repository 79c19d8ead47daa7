"""Global-nearest-neighbour association with bias-corrected gates (the TrackManager's default).

A plot with a Mode S address goes to the live track with that address (a new track if there is none; a
second plot of one address in a radar's sweep is refused, ``plots_duplicate_in_scan``). The others are
gated against the tracks without a Mode S address whose Mode 3/A code agrees or is unknown: for plot k
and track t predicted to the plot's time, with the radar's bias estimate (ς̂, P_ς)::

    ν = z_k − (p̄_t + C_k ς̂),   S = P̄_pp + C_k P_ς C_kᵀ + R_k,   d² = νᵀ S⁻¹ ν ≤ gate

With Mode C on both sides d_h² (χ²₁) gates the pair too and joins the cost d² + ln det S. Confirmed
and coasting tracks take the plots they gate first, tentative tracks compete for the rest
(``assign_tiers``); a plot within ``new_track_exclusion`` of a confirmed track that is not its plot
starts no track (``plots_near_confirmed_track``).
"""

from __future__ import annotations

import numpy as np

from radartracker.api import (ALTITUDE_GATE, NEW_TRACK, REFUSED, Association, Associator, Prediction, RadarPlots,
                              altitude_d2, assign_tiers, candidate_pairs, gate_costs)


class GnnAssociator(Associator):
    """Mode S first, then global nearest neighbour in tiers (module docstring)."""

    name = "gnn"

    def associate(self, plots: RadarPlots, tracks: Prediction) -> Association:
        out = np.full(len(plots.plots), NEW_TRACK, np.int64)
        reasons: dict[int, str] = {}
        taken: set[int] = set()
        rest: list[int] = []
        valid = plots.valid.tolist()
        for k, p in enumerate(plots.plots):
            if not valid[k]:
                out[k], reasons[k] = REFUSED, "plots_impossible_geometry"
            elif p.mode_s is None:
                rest.append(k)
            elif (i := tracks.by_mode_s.get(p.mode_s)) is None:
                continue
            elif i in taken:
                out[k], reasons[k] = REFUSED, "plots_duplicate_in_scan"
            else:
                taken.add(i)
                out[k] = i
        if rest and len(tracks):
            self._gate(plots, rest, taken, tracks, out, reasons)
        return Association(out, reasons)

    def _gate(self, plots: RadarPlots, rest: list[int], taken: set[int], tracks: Prediction, out: np.ndarray,
              reasons: dict[int, str]) -> None:
        """The plots ``rest`` (no Mode S address) by gating, into ``out`` and ``reasons``."""
        s = self.settings
        free = ~tracks.identified
        free[list(taken)] = False
        codes = tracks.mode_3a
        allowed = np.array([free & ((codes == None) | (codes == plots.plots[k].mode_3a)  # noqa: E711
                                    | (plots.plots[k].mode_3a is None)) for k in rest]).reshape(len(rest), len(tracks))
        zr = plots.z[rest]
        pairs = candidate_pairs(zr, tracks.position, s.search_radius_m, allowed)
        if not len(pairs):
            return
        k_of = np.asarray(rest)[pairs[:, 0]]
        pos, vel, cov = tracks.exact(pairs[:, 1])
        dt = plots.time[k_of] - tracks.time
        d2, cost = gate_costs(zr[pairs[:, 0]], plots.C[k_of], plots.R[k_of], plots.bias, plots.bias_cov,
                              pos + vel * dt[:, None], cov)
        h = np.array([np.nan if plots.plots[k].altitude_m is None else plots.plots[k].altitude_m for k in k_of])
        d2h = altitude_d2(h, [tracks.tracks[i].vertical for i in pairs[:, 1]], dt + tracks.time)
        d2 = np.where(d2h > ALTITUDE_GATE, np.inf, d2)
        cost = cost + np.where(np.isnan(d2h), 1.0, d2h)  # d_h²'s mean where the altitude is unknown
        matches, in_gate = assign_tiers(pairs, d2, cost, s.gate, tracks.tentative.astype(int), s.new_track_exclusion)
        for j, k in enumerate(rest):
            if j in matches:
                out[k] = matches[j]
                taken.add(matches[j])
            elif j < len(in_gate) and in_gate[j]:
                out[k], reasons[k] = REFUSED, "plots_near_confirmed_track"
