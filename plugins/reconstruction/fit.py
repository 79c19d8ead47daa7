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

from radartracker.api import propagate
from radartracker_plugins.reconstruction.config import ReconstructionConfig
from radartracker_plugins.reconstruction.hooke_jeeves import hooke_jeeves
from radartracker_plugins.reconstruction.objects import ControlSegment, ControlTrack, GeoPoint
from radartracker_plugins.reconstruction.shooting import MultipleShooting
from radartracker_plugins.reconstruction.weight import TrackWeight


class ControlObjective:
    """f(θ) for K segments over [t0, t_end] and the plots at ``times`` (weighted by ``weight``).

    ``initial`` = (x, y, φ, v) fixes the initial state; None makes it part of θ.
    """

    def __init__(self, weight: TrackWeight, times: np.ndarray, t0: float, t_end: float, K: int,
                 cfg: ReconstructionConfig, initial: tuple[float, float, float, float] | None = None) -> None:
        if t_end - t0 < K * cfg.dt_min - 1e-9:
            raise ValueError(f"K: {K} segments of ≥ {cfg.dt_min} s do not fit in {t_end - t0:.1f} s")
        self.weight, self.times, self.t0, self.t_end, self.K, self.cfg = weight, times, t0, t_end, K, cfg
        self.initial = initial
        k = np.arange(1, K)
        self.lower = t0 + k * cfg.dt_min
        self.upper = t_end - (K - k) * cfg.dt_min

    @property
    def n_init(self) -> int:
        return 4 if self.initial is None else 0

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
        """(initial state, u, w, bounds, violation) of θ projected onto the constraints."""
        c, K, n0 = self.cfg, self.K, self.n_init
        init = tuple(theta[:4]) if self.initial is None else self.initial
        u, w, s = theta[n0:n0 + K], theta[n0 + K:n0 + 2 * K], theta[n0 + 2 * K:]
        up, wp = np.clip(u, -c.max_u, c.max_u), np.clip(w, -c.max_w, c.max_w)
        sp = np.clip(s, self.lower, self.upper)
        for k in range(1, K - 1):
            sp[k] = max(sp[k], sp[k - 1] + c.dt_min)
        for k in range(K - 3, -1, -1):
            sp[k] = min(sp[k], sp[k + 1] - c.dt_min)
        viol = (np.abs(u - up).sum() / c.du1 + np.abs(w - wp).sum() / c.dw1
                + np.abs(s - sp).sum() / c.dt1)
        if init[3] < c.v_min:
            viol += (c.v_min - init[3]) / c.dv1
            init = (*init[:3], c.v_min)
        return init, up, wp, np.concatenate([[self.t0], sp, [self.t_end]]), viol

    def positions(self, init, u, w, bounds) -> tuple[np.ndarray, np.ndarray, float]:
        """Plane positions at the plot times, the speed-clamped w, and the speed violation."""
        c, times = self.cfg, self.times
        p = np.empty((len(times), 2))
        cut = np.concatenate([[0], np.searchsorted(times, bounds[1:-1], side="left"), [len(times)]])
        state, w_eff, viol = init, w.copy(), 0.0
        for k in range(self.K):
            dur = bounds[k + 1] - bounds[k]
            floor = (c.v_min - state[3]) / dur
            if w_eff[k] < floor:
                viol += (floor - w_eff[k]) / c.dw1
                w_eff[k] = floor
            tau = np.append(times[cut[k]:cut[k + 1]] - bounds[k], dur)
            x, y, phi, v = propagate(*state, u[k], w_eff[k], tau)
            p[cut[k]:cut[k + 1], 0], p[cut[k]:cut[k + 1], 1] = x[:-1], y[:-1]
            state = (x[-1], y[-1], phi[-1], v[-1])
        return p, w_eff, viol

    def prior_residuals(self, u: np.ndarray, w: np.ndarray) -> np.ndarray:
        """Control jumps over their prior sd, (Δu, Δw)/jump_sd (empty when the prior is off)."""
        if not self.cfg.jump_sd or self.K < 2:
            return np.empty(0)
        return np.concatenate([np.diff(u), np.diff(w)]) / self.cfg.jump_sd

    def residuals(self, theta: np.ndarray) -> np.ndarray:
        """Whitened residuals L⁻¹(z − p) of every plot (flattened), the control-jump prior's
        (:meth:`prior_residuals`) and √(2·penalty·violation): half their sum of squares is the Gaussian f(θ)."""
        init, u, w, bounds, viol = self.unpack(theta)
        p, _, v2 = self.positions(init, u, w, bounds)
        r = np.einsum("nij,nj->ni", self.weight.Linv, self.weight.z - p).ravel()
        return np.concatenate([r, self.prior_residuals(u, w), [np.sqrt(2 * self.cfg.penalty * (viol + v2))]])

    def jacobian(self, theta: np.ndarray) -> np.ndarray:
        """∂ residuals / ∂θ by the chain rule along the segments (the penalty row is zero).

        With S_k the state at the start of segment k, Φ_k = ∂S_{k+1}/∂S_k, Ψ_k = ∂S_{k+1}/∂(u_k, w_k),
        G_k, H_k the same for the positions at segment k's plot times (central differences of the
        closed form within one segment): dS_{k+1}/dθ = Φ_k dS_k/dθ (+ Ψ_k on u_k, w_k), and a switch
        time t_k enters as the jump f_{k−1}(S_k) − f_k(S_k) of the model's right-hand side.
        One Jacobian costs about nine integrations instead of one per parameter.
        """
        init, u, w, bounds, _ = self.unpack(theta)
        _, w_eff, _ = self.positions(init, u, w, bounds)
        K, n0, times = self.K, self.n_init, self.times
        cut = np.concatenate([[0], np.searchsorted(times, bounds[1:-1], side="left"), [len(times)]])
        dp = np.zeros((len(times), 2, len(theta)))
        M = np.zeros((4, len(theta)))
        if self.initial is None:
            M[:, :4] = np.eye(4)
        S = np.array(init, float)

        def rhs(S, uk, wk):
            return np.array([S[3] * np.sin(S[2]), S[3] * np.cos(S[2]), uk / S[3], wk])

        for k in range(K):
            cu, cw = n0 + k, n0 + K + k
            if k > 0:
                M[:, n0 + 2 * K + k - 1] += rhs(S, u[k - 1], w_eff[k - 1]) - rhs(S, u[k], w_eff[k])
            tau = np.append(times[cut[k]:cut[k + 1]] - bounds[k], bounds[k + 1] - bounds[k])
            D = np.zeros((4, len(tau), 6))  # ∂(x, y, φ, v)(τ) / ∂(x0, y0, φ0, v0, u, w)
            D[0, :, 0] = D[1, :, 1] = 1.0
            for j, h in ((2, 1e-6), (3, 1e-4), (4, 1e-5), (5, 1e-5)):
                args = [*S, u[k], w_eff[k]]
                hi, lo = list(args), list(args)
                hi[j] += h
                lo[j] -= h
                D[:, :, j] = (np.array(propagate(*hi[:4], hi[4], hi[5], tau))
                              - np.array(propagate(*lo[:4], lo[4], lo[5], tau))) / (2 * h)
            G = D[:2, :-1, :4].transpose(1, 0, 2)
            sl = slice(cut[k], cut[k + 1])
            dp[sl] = G @ M
            dp[sl, :, cu] += D[:2, :-1, 4].T
            dp[sl, :, cw] += D[:2, :-1, 5].T
            end = np.array(propagate(*S, u[k], w_eff[k], tau[-1:]))[:, 0]
            M = D[:, -1, :4] @ M
            M[:, cu] += D[:, -1, 4]
            M[:, cw] += D[:, -1, 5]
            S = end
        J = -np.einsum("nij,njp->nip", self.weight.Linv, dp).reshape(2 * len(times), len(theta))
        # a coordinate the projection holds at a constraint does not move the track
        # (active set: also a control on its bound that the descent direction pushes outwards)
        if self.cfg.jump_sd and K > 1:  # prior rows: ∂(u_k − u_{k−1})/∂u = ±1/jump_sd
            D = (np.eye(K, k=1) - np.eye(K))[:-1] / self.cfg.jump_sd
            P = np.zeros((2 * (K - 1), len(theta)))
            P[:K - 1, n0:n0 + K], P[K - 1:, n0 + K:n0 + 2 * K] = D, D
            J = np.vstack([J, P])
        g = J.T @ self.residuals(theta)[:-1]
        held = np.zeros(len(theta), bool)
        for sl, cap in ((slice(n0, n0 + K), self.cfg.max_u), (slice(n0 + K, n0 + 2 * K), self.cfg.max_w)):
            th = theta[sl]
            held[sl] = (np.abs(th) > cap) | ((th >= cap - 1e-9) & (g[sl] < 0)) | ((th <= -cap + 1e-9) & (g[sl] > 0))
        held[n0 + 2 * K:] = np.abs(theta[n0 + 2 * K:] - bounds[1:-1]) > 1e-9
        J[:, held] = 0.0
        return np.vstack([J, np.zeros((1, len(theta)))])

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
        init, u, w, bounds, viol = self.unpack(theta)
        p, _, v2 = self.positions(init, u, w, bounds)
        return self.weight(p) + 0.5 * float(np.sum(self.prior_residuals(u, w) ** 2)) + self.cfg.penalty * (viol + v2)

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
        x, y, phi, v = propagate(*state, u[j], w[j], np.array([bounds[j + 1] - bounds[j]]))
        state = (float(x[0]), float(y[0]), float(phi[0]), float(v[0]))
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
    """Joint least-squares refinement of θ: Levenberg–Marquardt (MINPACK) for the Gaussian weight,
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
    if loss == "linear":  # MINPACK Levenberg–Marquardt; the projection inside f keeps the bounds
        res = least_squares(obj.residuals, theta, jac=obj.jacobian, method="lm", x_scale="jac", ftol=1e-8, xtol=1e-12,
                            max_nfev=obj.cfg.refine_iterations)
        return res.x, int(res.nfev)
    res = least_squares(obj.residuals, x0, bounds=(lo, hi), method="trf", loss=loss,
                        f_scale=obj.cfg.loss_c, x_scale="jac", max_nfev=obj.cfg.refine_iterations, jac=obj.jacobian)
    return res.x, int(res.nfev)
