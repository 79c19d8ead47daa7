"""Conformance checks of motion-model plugins (:func:`check_motion_model`; the list in :mod:`radartracker.testing`)."""

from __future__ import annotations

import copy
from collections.abc import Iterable

import numpy as np
from scipy.stats import chi2

from radartracker.errors import ConfigurationError
from radartracker.estimation.motion import MotionModel
from radartracker.testing.common import (H, CheckFailed, check_kernels, close, fail, identical, kalman_filter_class,
                                         noise_cov, run_checks)
from radartracker.tracking.filters import MotionConfig, TrackFilter

MOTION_CHECKS = ("contract", "errors", "reads", "screen", "filterpy", "hygiene", "consistency",
                 "snapshot", "kernels")


def _run_filter(f: TrackFilter, t: np.ndarray, zs: np.ndarray, Rs: np.ndarray) -> list[float]:
    f.start(t[0], zs[0], Rs[0])
    return [f.update(t[k], zs[k], Rs[k]) for k in range(1, len(t))]


def _track(rng: np.random.Generator, n: int, q: float, sd_v: float, manoeuvre: bool = False):
    """(times, truth, z, R) of a CV flight (optionally with a 2 g turn in the middle)."""
    t = np.concatenate([[0.0], np.cumsum(rng.uniform(1.0, 6.0, n - 1))])
    x = np.array([1e4, -2e4, *rng.normal(0.0, sd_v, 2)])
    truth = [x.copy()]
    for k in range(1, n):
        A, Q = MotionModel(q).transition(t[k] - t[k - 1])
        x = A @ x + rng.multivariate_normal(np.zeros(4), Q)
        if manoeuvre and n // 3 <= k < n // 2:
            v = x[2:] / max(np.hypot(*x[2:]), 1.0)
            dv = 20.0 * (t[k] - t[k - 1]) * np.array([-v[1], v[0]])
            x[2:] += dv
        truth.append(x.copy())
    Rs = np.array([noise_cov(rng, 50.0) for _ in range(n)])
    zs = np.array([rng.multivariate_normal(s[:2], R) for s, R in zip(truth, Rs)])
    return t, np.array(truth), zs, Rs


def _filter_state(f: TrackFilter) -> list[np.ndarray]:
    t, x, P = f.estimate()
    return [np.array([t]), x, P]


def _check_motion_contract(cls: type[TrackFilter], config: MotionConfig, owner: str) -> None:
    check = "contract"
    if not (isinstance(cls.config_class, type) and issubclass(cls.config_class, MotionConfig)):
        raise fail(owner, check, "config_class must be a MotionConfig subclass")
    if not isinstance(cls().config, cls.config_class):
        raise fail(owner, check, "a filter built without a config must hold config_class() as .config")
    if cls.config_class is not MotionConfig:
        try:
            cls(MotionConfig())
        except ConfigurationError:
            pass
        else:
            raise fail(owner, check, "a config of another type must be refused with ConfigurationError")
    f = cls(config)
    if f.config is not config:
        raise fail(owner, check, "does not keep the config it was given as .config")
    try:
        f.predict(1.0)
    except ValueError:
        pass
    else:
        raise fail(owner, check, "predict before start must raise ValueError")
    R = 50.0**2 * np.eye(2)
    f.start(0.0, np.array([1e4, 2e4]), R)
    t, x, P = f.estimate()
    if t != 0.0 or np.shape(x) != (4,) or np.shape(P) != (4, 4) or not np.allclose(x[:2], [1e4, 2e4]):
        raise fail(owner, check, f"estimate() after start must be (0.0, χ (4,) at z, P (4, 4)), got {(t, x, P)}")
    if not all(type(a) is np.ndarray and a.dtype == np.float64 for a in (x, P)):
        raise fail(owner, check, f"estimate() must give χ and P as float64 numpy arrays, got {type(x)}, {type(P)}")
    sd_v = config.prior_sd_velocity_mps
    if not (np.allclose(P[:2, :2], R) and np.allclose(np.diag(P)[2:], sd_v**2) and np.allclose(x[2:], 0.0)):
        raise fail(owner, check, f"start must give χ = [z, 0, 0], P = diag(R, σ_v² I) with σ_v = {sd_v}, got {x}, {P}")
    nis = f.update(4.0, np.array([1e4 + 800.0, 2e4]), R)
    if not (isinstance(nis, float) and np.isfinite(nis) and nis >= 0.0):
        raise fail(owner, check, f"update must return the NIS as a float ≥ 0, got {nis!r}")


def _check_motion_errors(cls: type[TrackFilter], config: MotionConfig, owner: str) -> None:
    check = "errors"
    f = cls(config)
    f.start(0.0, np.zeros(2), np.eye(2))
    f.update(2.0, np.array([1.0, 0.5]), np.eye(2))
    before = _filter_state(f)
    bad = [(2.5, np.array([np.nan, 0.0]), np.eye(2), "a non-finite z"), (2.5, np.zeros(3), np.eye(2), "a z of 3 values"),
           (2.5, np.zeros(2), -np.eye(2), "a negative definite R"),
           (2.5, np.zeros(2), np.array([[1.0, 2.0], [0.0, 1.0]]), "an asymmetric R"),
           (float("nan"), np.zeros(2), np.eye(2), "time NaN"), (float("inf"), np.zeros(2), np.eye(2), "time inf"),
           (2.0 + 2.0 * config.max_gap_s, np.zeros(2), np.eye(2), "a gap beyond max_gap_s")]
    for t, z, R, what in bad:
        try:
            f.update(t, z, R)
        except ValueError:
            pass
        else:
            raise fail(owner, check, f"update with {what} must raise ValueError")
        if not identical(_filter_state(f), before):
            raise fail(owner, check, f"a refused update ({what}) changed the filter")


def _check_motion_reads(cls: type[TrackFilter], config: MotionConfig, owner: str) -> None:
    check = "reads"
    t, _, zs, Rs = _track(np.random.default_rng(30), 12, 1.0, config.prior_sd_velocity_mps)
    f = cls(config)
    _run_filter(f, t[:6], zs[:6], Rs[:6])
    twin = copy.deepcopy(f)
    x1, P1 = f.predict(t[6])
    x2, P2 = f.predict(t[6])
    for arr in (*_filter_state(f), x1, P1):
        arr[...] = np.nan
    if not (np.array_equal(x2, f.predict(t[6])[0]) and identical(_filter_state(f), _filter_state(twin))):
        raise fail(owner, check, "predict/estimate changed the filter or returned views of its state")
    x, P = f.predict(t[6])
    nu = zs[6] - x[:2]
    expected = float(nu @ np.linalg.solve(P[:2, :2] + Rs[6], nu))
    got = f.update(t[6], zs[6], Rs[6])
    if not close(got, expected):
        raise fail(owner, check, f"update's NIS {got} is not that of predict's output ({expected})")


def _check_motion_screen(cls: type[TrackFilter], config: MotionConfig, owner: str) -> None:
    check = "screen"
    rng = np.random.default_rng(31)
    t, _, zs, Rs = _track(rng, 12, 1.0, config.prior_sd_velocity_mps)
    f = cls(config)
    _run_filter(f, t[:6], zs[:6], Rs[:6])
    C, bias, bias_cov = np.array([[0.8, 2e4], [-0.6, 3e4]]), np.array([30.0, -4e-4]), np.diag([50.0, 2e-8])
    z = zs[6] + C @ bias
    zc, Rc = z - C @ bias, Rs[6] + C @ bias_cov @ C.T
    x, P = f.predict(t[6])
    nu = zc - x[:2]
    d2 = float(nu @ np.linalg.solve(P[:2, :2] + Rc, nu))
    before, twin = _filter_state(f), copy.deepcopy(f)
    for gate in (None, 0.5 * d2):
        got = f.screen(t[6], z, C, Rs[6], bias, bias_cov, gate)
        if not (close(got[0], d2) and close(got[1], zc) and close(got[2], Rc) and got[3] is False):
            raise fail(owner, check, f"screen with gate {gate} gave {got}, expected d² {d2}, z_c {zc}, R_c {Rc}, "
                                     "not updated")
        if not identical(_filter_state(f), before):
            raise fail(owner, check, "a measurement outside the gate changed the filter")
    got = f.screen(t[6], z, C, Rs[6], bias, bias_cov, 2.0 * d2)
    twin.update(t[6], zc, Rc)
    if not (got[3] is True and all(close(a, b) for a, b in zip(_filter_state(f), _filter_state(twin)))):
        raise fail(owner, check, "a measurement in the gate must update the filter as update(time, z_c, R_c) does")


def _check_motion_filterpy(cls: type[TrackFilter], config: MotionConfig, owner: str) -> None:
    KalmanFilter = kalman_filter_class()
    check = "filterpy"
    t, _, zs, Rs = _track(np.random.default_rng(31), 30, 1.0, config.prior_sd_velocity_mps, manoeuvre=True)
    f = cls(config)
    f.start(t[0], zs[0], Rs[0])
    for k in range(1, len(t)):
        x, P = f.predict(t[k])
        kf = KalmanFilter(dim_x=4, dim_z=2)
        kf.x, kf.P, kf.H, kf.R = x.copy(), P.copy(), H.copy(), Rs[k]
        kf.update(zs[k])
        nis = f.update(t[k], zs[k], Rs[k])
        _, xu, Pu = f.estimate()
        if not (close(xu, kf.x) and close(Pu, kf.P) and close(nis, float(kf.y @ np.linalg.solve(kf.S, kf.y)))):
            raise fail(owner, check, f"update {k} is not FilterPy's Kalman correction of predict()'s (χ̄, P̄) "
                                      "(pass kalman_update=False for a multiple-model filter)")


def _check_motion_hygiene(cls: type[TrackFilter], config: MotionConfig, owner: str) -> None:
    check = "hygiene"
    t, _, zs, Rs = _track(np.random.default_rng(32), 60, 1.0, config.prior_sd_velocity_mps, manoeuvre=True)
    t = np.concatenate([t, [t[-1], t[-1] + 0.9 * config.max_gap_s, t[-1] + 0.9 * config.max_gap_s + 4.0]])
    zs = np.concatenate([zs, zs[-1:], zs[-1:] + 1e3, zs[-1:] + 1.1e3])
    Rs = np.concatenate([Rs, Rs[-3:]])
    f = cls(config)
    f.start(t[0], zs[0], Rs[0])
    for k in range(1, len(t)):
        nis = f.update(t[k], zs[k], Rs[k])
        _, x, P = f.estimate()
        ok = np.isfinite(nis) and np.isfinite(x).all() and np.isfinite(P).all() and np.array_equal(P, P.T)
        try:
            np.linalg.cholesky(P)
        except np.linalg.LinAlgError:
            ok = False
        if not ok:
            raise fail(owner, check, f"update {k} (t={t[k]}): covariance not symmetric positive definite or not finite")


def _check_motion_consistency(cls: type[TrackFilter], config: MotionConfig, owner: str, runs: int = 40) -> None:
    """One-sided: the NIS of every update and the NEES at the end of each (independent) run, summed,
    not above their 99.9 % χ² bounds."""
    check = "consistency"
    sums = {"NIS": [0.0, 0], "NEES at the end": [0.0, 0]}
    for r in range(runs):
        t, truth, zs, Rs = _track(np.random.default_rng([33, r]), 25, 1.0, config.prior_sd_velocity_mps)
        f = cls(config)
        f.start(t[0], zs[0], Rs[0])
        for k in range(1, len(t)):
            sums["NIS"][0] += f.update(t[k], zs[k], Rs[k])
            sums["NIS"][1] += 2
        _, x, P = f.estimate()
        e = x - truth[-1]
        sums["NEES at the end"][0] += float(e @ np.linalg.solve(P, e))
        sums["NEES at the end"][1] += 4
    for what, (total, dof) in sums.items():
        hi = chi2.ppf(0.999, dof)
        if total > hi:
            raise fail(owner, check, f"summed {what} {total:.1f} above the 99.9 % χ²({dof}) bound {hi:.1f} "
                                     f"(mean per degree of freedom {total / dof:.2f}, expected ≤ 1): overconfident")


def _check_motion_snapshot(cls: type[TrackFilter], config: MotionConfig, owner: str) -> None:
    check = "snapshot"
    t, _, zs, Rs = _track(np.random.default_rng(34), 30, 1.0, config.prior_sd_velocity_mps, manoeuvre=True)
    f = cls(config)
    _run_filter(f, t[:15], zs[:15], Rs[:15])
    copies = {"copy.deepcopy": copy.deepcopy(f)}
    if callable(getattr(f, "state_dict", None)):
        g = cls(config)
        g.load_state_dict(copy.deepcopy(f.state_dict()))
        copies["state_dict/load_state_dict"] = g
    for k in range(15, len(t)):
        ref = f.update(t[k], zs[k], Rs[k])
        for how, other in copies.items():
            if other.update(t[k], zs[k], Rs[k]) != ref or not identical(_filter_state(other), _filter_state(f)):
                raise fail(owner, check, f"a {how} round trip does not continue bit for bit (update at t={t[k]})")


_MOTION_RUNNERS = {"contract": _check_motion_contract, "errors": _check_motion_errors, "reads": _check_motion_reads,
                   "screen": _check_motion_screen,
                   "filterpy": _check_motion_filterpy, "hygiene": _check_motion_hygiene,
                   "consistency": _check_motion_consistency, "snapshot": _check_motion_snapshot,
                   "kernels": lambda cls, config, owner: check_kernels(cls, owner)}


def check_motion_model(cls: type[TrackFilter], config: MotionConfig | None = None, *, kalman_update: bool = True,
                       checks: Iterable[str] = MOTION_CHECKS) -> list[str]:
    """Run the motion-model checks (module docstring) on TrackFilter class ``cls`` with ``config``
    (default ``cls.config_class()``). ``kalman_update=False`` skips the FilterPy check, which holds
    only for a filter whose estimate is one Gaussian corrected by Kalman's equations (not an IMM
    mixture). Raises :class:`CheckFailed`."""
    owner = f"motion model {getattr(cls, 'name', '?')!r} ({cls.__module__}.{cls.__qualname__})"
    if not (isinstance(cls, type) and issubclass(cls, TrackFilter)):
        raise CheckFailed(f"{cls!r} is not a TrackFilter subclass")
    config = config if config is not None else cls.config_class()
    checks = [c for c in checks if kalman_update or c != "filterpy"]
    return run_checks(owner, _MOTION_RUNNERS, checks, cls, config)
