"""Fitting one control-track hypothesis to the plots by Hooke–Jeeves (seed 000 §2.5).

Parameters θ = [x₀, y₀, φ₀, v₀ (when free), u₁…u_K, w₁…w_K, t₁…t_{K−1}] (interior switch times).
The minimised function is the seed's: a temporary control track is formed from θ; where θ breaks
a constraint (|u| ≤ u_max, |w| ≤ w_max, segments ≥ dt_min, speed ≥ v_min) the track is built from
θ projected onto the constraints and a penalty proportional to the violation (in units of the
initial steps) is added, so a start that violates the constraints slides back into the feasible
region; the track is integrated (:mod:`.integrate`) and its weight (:mod:`.weight`) returned.

Search: Hooke–Jeeves with the seed's steps over one window of two consecutive segments at a time
(segment k with its initial state fixed by segments < k, segment k+1 as a look-ahead, the plots
of both); each window is cheap, and the chain is walked once. Then (``refine``, on by default)
a multiple-shooting refinement (:mod:`.shooting`, ``shooting``) and a joint Levenberg–Marquardt
refinement of all of θ with the chain-rule Jacobian
(:meth:`ControlObjective.jacobian`): the seed's final steps (0.01 m/s² in u) leave hundreds of
metres of drift over a long segment, and coordinate moves crawl along the valleys that couple an
early control with every later position.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import least_squares

from radartracker_plugins.reconstruction import _kernels as kern
from radartracker_plugins.reconstruction.config import ReconstructionConfig
from radartracker_plugins.reconstruction.hooke_jeeves import hooke_jeeves
from radartracker_plugins.reconstruction.lm import levenberg_marquardt
from radartracker_plugins.reconstruction.objects import ControlSegment, ControlTrack, GeoPoint
from radartracker_plugins.reconstruction.shooting import MultipleShooting
from radartracker_plugins.reconstruction.weight import TrackWeight


_LOSS_CODE = {"gauss": 0.0, "huber": 1.0, "cauchy": 2.0}


class ControlObjective:
    """f(θ) for K segments over [t0, t_end] and the plots at ``times`` (weighted by ``weight``).

    ``initial`` = (x, y, φ, v) fixes the initial state; None makes it part of θ. The numerics are the
    compiled kernels of :mod:`._kernels` (one call per evaluation); this class holds their settings
    and work arrays.
    """

    def __init__(self, weight: TrackWeight, times: np.ndarray, t0: float, t_end: float, K: int,
                 cfg: ReconstructionConfig, initial: tuple[float, float, float, float] | None = None) -> None:
        if t_end - t0 < K * cfg.dt_min - 1e-9:
            raise ValueError(f"K: {K} segments of ≥ {cfg.dt_min} s do not fit in {t_end - t0:.1f} s")
        self.weight, self.t0, self.t_end, self.K, self.cfg = weight, t0, t_end, K, cfg
        self.times = np.ascontiguousarray(times, float)
        self.initial = initial
        k = np.arange(1, K)
        self.lower = t0 + k * cfg.dt_min
        self.upper = t_end - (K - k) * cfg.dt_min
        settings = {"t0": t0, "t_end": t_end, "loss": _LOSS_CODE[weight.loss], "loss_c": weight.c, "const": weight.const}
        self.cs = np.array([settings[f] if f in settings else getattr(cfg, f) for f in kern.CS_FIELDS], float)
        self.z = np.ascontiguousarray(weight.z, float)
        self.Linv = np.ascontiguousarray(weight.Linv, float)
        self.fixed = np.zeros(4) if initial is None else np.array(initial, float)
        self.wk = np.empty(4 * K + 5)
        self.p = np.empty((len(self.times), 2))

    @property
    def n_init(self) -> int:
        return 4 if self.initial is None else 0

    def _init_in(self, theta: np.ndarray) -> np.ndarray:
        """Where the kernels read (x₀, y₀, φ₀, v₀): θ's first four entries when free, else the fixed state."""
        return theta if self.initial is None else self.fixed

    def pack(self, init, u, w, bounds) -> np.ndarray:
        head = list(init) if self.initial is None else []
        return np.concatenate([head, u, w, bounds[1:-1]])

    def steps(self) -> tuple[np.ndarray, np.ndarray]:
        """Initial and final Hooke–Jeeves steps for θ (the seed's constants)."""
        c, K = self.cfg, self.K
        s0 = [c.dxy1, c.dxy1, c.dphi1, c.dv1] if self.initial is None else []
        s1 = [c.dxy_fin, c.dxy_fin, c.dphi_fin, c.dv_fin] if self.initial is None else []
        first = np.concatenate([s0, [c.du1] * K, [c.dw1] * K, [c.dt1] * (K - 1)])
        final = np.concatenate([s1, [c.du_fin] * K, [c.dw_fin] * K, [c.dt_fin] * (K - 1)])
        return np.maximum(first, final), final

    def unpack(self, theta: np.ndarray):
        """(initial state, u, w, bounds, violation) of θ projected onto the constraints
        (:func:`._kernels.project`: controls clipped to their bounds, switch times to [lower, upper] and
        ≥ dt_min apart, v₀ ≥ v_min; the violation in units of the initial steps)."""
        theta = np.ascontiguousarray(theta, float)
        viol = kern.project(theta, self.n_init, self.K, self._init_in(theta), self.lower, self.upper, self.cs, self.wk)
        init, u, w, bounds, _ = kern.views(self.wk, self.K)
        return tuple(float(a) for a in init), u.copy(), w.copy(), bounds.copy(), viol

    def positions(self, init, u, w, bounds) -> tuple[np.ndarray, np.ndarray, float]:
        """Plane positions at the plot times, the speed-clamped w, and the speed violation
        (:func:`._kernels.positions`)."""
        i0, uk, wk, bk, w_eff = kern.views(self.wk, self.K)
        i0[:], uk[:], wk[:], bk[:] = init, u, w, bounds
        viol = kern.positions(self.K, self.times, self.cs, self.wk, self.p)
        return self.p.copy(), w_eff.copy(), viol

    def n_residuals(self) -> int:
        """2n plot rows, 2(K − 1) prior rows when the prior is on, one penalty row."""
        return 2 * len(self.times) + (2 * (self.K - 1) if self.cfg.jump_sd else 0) + 1

    def residuals(self, theta: np.ndarray) -> np.ndarray:
        """Whitened residuals L⁻¹(z − p) of every plot (flattened), the control-jump prior's
        (Δu, Δw)/jump_sd and √(2·penalty·violation): half their sum of squares is the Gaussian
        f(θ) (:func:`._kernels.ss_residuals`)."""
        theta = np.ascontiguousarray(theta, float)
        r = np.empty(self.n_residuals())
        kern.ss_residuals(theta, self.n_init, self.K, self._init_in(theta), self.lower, self.upper, self.cs,
                          self.times, self.z, self.Linv, self.wk, self.p, r)
        return r

    def jacobian(self, theta: np.ndarray) -> np.ndarray:
        """∂ residuals / ∂θ by the chain rule along the segments (:func:`._kernels.ss_jacobian`; the
        penalty row is zero, the prior's rows are ±1/jump_sd). One Jacobian costs about four integrations
        per plot (central differences in v₀, u, w of the closed form) instead of one per parameter.
        A coordinate the projection holds at a constraint does not move the track: its column is zero
        (active set: also a control on its bound that the descent direction pushes outwards)."""
        theta = np.ascontiguousarray(theta, float)
        K, n0, n = self.K, self.n_init, len(self.times)
        J = np.zeros((self.n_residuals(), len(theta)))
        kern.ss_jacobian(theta, n0, K, self._init_in(theta), self.lower, self.upper, self.cs, self.times, self.Linv,
                         self.wk, self.p, np.empty((4, len(theta))), np.empty((4, 6)), J)
        bounds = kern.views(self.wk, K)[3].copy()
        if self.cfg.jump_sd and K > 1:  # prior rows: ∂(u_k − u_{k−1})/∂u = ±1/jump_sd
            D = (np.eye(K, k=1) - np.eye(K))[:-1] / self.cfg.jump_sd
            J[2 * n:2 * n + K - 1, n0:n0 + K], J[2 * n + K - 1:2 * n + 2 * K - 2, n0 + K:n0 + 2 * K] = D, D
        g = J.T @ self.residuals(theta)
        held = np.zeros(len(theta), bool)
        for sl, cap in ((slice(n0, n0 + K), self.cfg.max_u), (slice(n0 + K, n0 + 2 * K), self.cfg.max_w)):
            th = theta[sl]
            held[sl] = (np.abs(th) > cap) | ((th >= cap - 1e-9) & (g[sl] < 0)) | ((th <= -cap + 1e-9) & (g[sl] > 0))
        held[n0 + 2 * K:] = np.abs(theta[n0 + 2 * K:] - bounds[1:-1]) > 1e-9
        J[:, held] = 0.0
        return J

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Box constraints of θ (the switch-time order is kept by the projection)."""
        c, K = self.cfg, self.K
        inf = np.inf
        lo = [-inf, -inf, -inf, c.v_min] if self.initial is None else []
        hi = [inf] * 4 if self.initial is None else []
        lo = np.concatenate([lo, [-c.max_u] * K, [-c.max_w] * K, self.lower])
        hi = np.concatenate([hi, [c.max_u] * K, [c.max_w] * K, self.upper])
        return lo, hi

    def __call__(self, theta: np.ndarray) -> float:
        """f(θ) = weight + jump prior + penalty · violation (:func:`._kernels.objective`)."""
        theta = np.ascontiguousarray(theta, float)
        return kern.objective(theta, self.n_init, self.K, self._init_in(theta), self.lower, self.upper, self.cs,
                              self.times, self.z, self.Linv, self.wk, self.p)

    def control_track(self, theta: np.ndarray) -> ControlTrack:
        """The (feasible) control track of θ."""
        init, u, w, bounds, _ = self.unpack(theta)
        _, w_eff, _ = self.positions(init, u, w, bounds)
        start = GeoPoint(self.t0, init[0], init[1], init[2], init[3])
        return ControlTrack(start, [ControlSegment(u[k], w_eff[k], bounds[k], bounds[k + 1]) for k in range(self.K)])


def jump_prior(ct: ControlTrack, cfg: ReconstructionConfig) -> float:
    """−log prior of the control jumps (up to a constant): ½ Σ_k (Δu_k² + Δw_k²) / jump_sd².

    Piecewise-constant-acceleration process noise: at each switch the controls jump by a
    N(0, jump_sd²) amount; with it the fit is a MAP fit and extra segments must buy their jumps.
    """
    if not cfg.jump_sd:
        return 0.0
    return 0.5 * float(np.sum(np.diff(ct.u) ** 2) + np.sum(np.diff(ct.w) ** 2)) / cfg.jump_sd**2


def _state_after(init, u, w, bounds, k: int) -> tuple[float, float, float, float]:
    state = init
    for j in range(k):
        state = kern.flow(*state, u[j], w[j], bounds[j + 1] - bounds[j])
    return state


def fit_hypothesis(ct: ControlTrack, times: np.ndarray, weight: TrackWeight,
                   cfg: ReconstructionConfig, windows: bool = True) -> tuple[ControlTrack, float, int]:
    """Optimise the starting control track ``ct``: (best track, its weight, evaluations).

    ``windows=False`` skips the Hooke–Jeeves window pass (for a start that already fits well,
    e.g. a split of a fitted track: the refinement alone can only improve on it).
    """
    init = (ct.initial.x, ct.initial.y, ct.initial.phi, ct.initial.v)
    u, w = ct.u.copy(), ct.w.copy()
    bounds = np.array([s.t_start for s in ct] + [ct.t_end])
    K, nfev = len(ct), 0
    for k in range(K if windows else 0):
        last = min(k + 2, K)
        t_a, t_b = bounds[k], bounds[last]
        sel = (times >= t_a) & (times < t_b) if last < K else times >= t_a
        if sel.sum() < 3:
            continue
        fixed = None if k == 0 else _state_after(init, u, w, bounds, k)
        obj = ControlObjective(weight.subset(sel), times[sel], t_a, t_b, last - k, cfg, fixed)
        theta0 = obj.pack(init, u[k:last], w[k:last], bounds[k:last + 1])
        first, final = obj.steps()
        res = hooke_jeeves(obj, theta0, first, final, cfg.dh)
        nfev += res.nfev
        i0, uk, wk, bk, _ = obj.unpack(res.x)
        _, wk, _ = obj.positions(i0, uk, wk, bk)
        if k == 0:
            init = i0
        u[k:last], w[k:last], bounds[k:last + 1] = uk, wk, bk
    obj = ControlObjective(weight, times, bounds[0], bounds[-1], K, cfg)
    theta = obj.pack(init, u, w, bounds)
    if cfg.refine:
        if cfg.shooting and K > 1 and cfg.loss == "gauss":
            theta, n = MultipleShooting(obj).refine(theta, cfg.shooting_iterations)
            i0, up, wp, bp, _ = obj.unpack(theta)
            theta = obj.pack(i0, up, obj.positions(i0, up, wp, bp)[1], bp)
            nfev += n
        theta, n = refine(obj, theta)
        nfev += n
    return obj.control_track(theta), obj(theta), nfev


def refine(obj: ControlObjective, theta: np.ndarray) -> tuple[np.ndarray, int]:
    """Joint least-squares refinement of θ: Levenberg–Marquardt (:mod:`.lm`) for the Gaussian weight,
    scipy's ``trf`` with the box bounds for the robust losses; the chain-rule Jacobian either way.

    Beyond the seed: Hooke–Jeeves stops at the seed's final steps (0.01 m/s² in u is ≈ 200 m of
    lateral drift after 200 s), and coordinate moves crawl along the valleys that couple an
    early control with every later position. The robust losses are applied to each whitened
    component here (scipy's ``huber``/``cauchy`` with f_scale = c).
    """
    lo, hi = obj.bounds()
    span = hi - lo
    margin = 1e-6 * np.where(np.isfinite(span), span, 1.0)
    x0 = np.clip(theta, lo + margin, hi - margin)
    loss = {"gauss": "linear"}.get(obj.cfg.loss, obj.cfg.loss)
    if loss == "linear":  # the projection inside f keeps the bounds
        return levenberg_marquardt(obj.residuals, obj.jacobian, theta, obj.cfg.refine_iterations)
    res = least_squares(obj.residuals, x0, bounds=(lo, hi), method="trf", loss=loss,
                        f_scale=obj.cfg.loss_c, x_scale="jac", max_nfev=obj.cfg.refine_iterations, jac=obj.jacobian)
    return res.x, int(res.nfev)
