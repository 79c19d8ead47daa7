"""Control track → geometric track (the seed's ``PostrTrekaSTekUchUprPrymo``, seed 000 §2.3).

Every segment is integrated in closed form by :func:`radartracker.kinematics.propagate`
(straight line, circular arc for w = 0, the logarithmic-spiral form for w ≠ 0), so there is no
step-size error at all; the tests hold it to a fine ``scipy.integrate.solve_ivp`` solution.
:func:`states_at` samples a track at given times (the search's bookkeeping: splits, weights, χ²);
:func:`geo_track` builds the seed's uniform-grid geometric track with each segment's span (nTr/kTr).
The optimiser's own integration, thousands of times per fit, is the compiled :func:`._kernels.flow`.
"""

from __future__ import annotations

import attrs
import numpy as np

from radartracker.api import propagate
from radartracker_plugins.reconstruction.objects import ControlTrack, GeoTrack


def states_at(x0: float, y0: float, phi0: float, v0: float, u, w, bounds, times) -> np.ndarray:
    """States (n, 4) = (x, y, φ, v) at sorted ``times`` for controls u[k], w[k] on [bounds[k], bounds[k+1]).

    ``bounds`` has K + 1 increasing times; times outside are extrapolated with the first / last
    segment's controls.
    """
    times = np.asarray(times, float)
    out = np.empty((len(times), 4))
    K = len(u)
    cut = np.searchsorted(times, bounds[1:-1], side="left")
    lo = 0
    state = (x0, y0, phi0, v0)
    for k in range(K):
        hi = cut[k] if k < K - 1 else len(times)
        if hi > lo:
            out[lo:hi] = np.column_stack(propagate(*state, u[k], w[k], times[lo:hi] - bounds[k]))
        if k < K - 1:
            end = propagate(*state, u[k], w[k], np.array([bounds[k + 1] - bounds[k]]))
            state = tuple(float(c[0]) for c in end)
        lo = hi
    return out


def control_arrays(ct: ControlTrack) -> tuple[tuple[float, float, float, float], np.ndarray, np.ndarray, np.ndarray]:
    """(initial (x, y, φ, v), u, w, bounds) of a control track."""
    p = ct.initial
    bounds = np.array([s.t_start for s in ct] + [ct.t_end])
    return (p.x, p.y, p.phi, p.v), ct.u, ct.w, bounds


def sample(ct: ControlTrack, times) -> np.ndarray:
    """States (n, 4) = (x, y, φ, v) of control track ``ct`` at sorted ``times``."""
    init, u, w, bounds = control_arrays(ct)
    return states_at(*init, u, w, bounds, times)


def geo_track(ct: ControlTrack, dt: float, height=None) -> GeoTrack:
    """The geometric track of ``ct`` on the grid t_start + i·dt covering [t_start, t_end].

    ``height`` maps times to heights (the model is horizontal; h is carried along), default 0.
    The returned track's ``control`` is ``ct`` with each segment's ``geo_span`` filled in.
    """
    if dt <= 0:
        raise ValueError(f"dt: must be > 0, got {dt!r}")
    n = int(np.floor((ct.t_end - ct.t_start) / dt + 1e-9)) + 1
    t = ct.t_start + dt * np.arange(n)
    s = sample(ct, t)
    seg = ct.segment_index(t)
    spans = []
    for k in range(len(ct)):
        idx = np.flatnonzero(seg == k)
        spans.append(slice(int(idx[0]), int(idx[-1]) + 1) if len(idx) else slice(0, 0))
    linked = attrs.evolve(ct, segments=[attrs.evolve(sg, geo_span=sp) for sg, sp in zip(ct, spans)])
    h = np.zeros(n) if height is None else np.asarray(height(t), float)
    return GeoTrack(ct.t_start, dt, s[:, 0], s[:, 1], h, s[:, 2], s[:, 3], seg, linked)
