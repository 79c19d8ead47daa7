"""Conformance checks for plugins, in the spirit of scikit-learn's ``check_estimator``.

``check_estimator(cls, **options)`` and ``check_motion_model(cls)`` run the contract and oracle tests
the built-in plugins pass against any plugin class, and raise :class:`CheckFailed` (an
``AssertionError``) naming the plugin, the check and what differed. Each returns the names of the
checks it ran. Use them in a plugin's own test suite::

    from radartracker.testing import check_estimator
    def test_conforms():
        check_estimator(MyEstimator, forgetting=0.99)

Estimator checks (``ESTIMATOR_CHECKS``):

* ``contract`` — constructible with an :class:`EstimatorConfig` (and its options), lists its radars
  and aircraft, refuses a second ``add_aircraft`` of a key (ValueError) and updates of unknown aircraft
  or radars (KeyError/ValueError), returns :class:`BiasState` / :class:`AircraftEstimate` of the
  documented shapes;
* ``filterpy`` — one aircraft measured only by unbiased positions (C_s = 0): every update equals
  FilterPy's ``KalmanFilter`` (F, Q from ``config.motion.transition(dt)``) to 1e-9, innovation ν, Λ
  and NIS included, and the uncorrelated bias does not move;
* ``consistency`` — Monte Carlo over the same unbiased case, where the model is right (truth drawn
  from the prior and the motion model): the summed NEES (4 dof) and NIS (2 dof) fall inside their
  two-sided 99.9 % χ² intervals;
* ``reads`` — reads (``aircraft``, ``bias``, ``predict``, the key lists) leave the state unchanged
  (an untouched deep copy continues identically) and return copies;
* ``lifecycle`` — aircraft are added and removed mid-stream, a removed key can be added again and
  starts from its new prior, the others carry on;
* ``update_many`` — the batch call equals one ``update`` after another (1e-9);
* ``snapshot`` — a ``copy.deepcopy`` and, where the estimator has ``state_dict``, a new instance
  given ``load_state_dict(state_dict())`` continue bit for bit.

Motion-model checks (``MOTION_CHECKS``): ``contract`` (typed ``config_class``, refuses another
config type, ``predict`` before ``start`` fails), ``errors`` (non-finite or malformed z, R, time and a
gap beyond ``max_gap_s`` raise ValueError and leave the filter unchanged), ``reads`` (``predict`` and
``estimate`` change nothing; ``update``'s NIS is that of ``predict``'s output), ``filterpy`` (for a
single-Gaussian filter, ``kalman_update=True``: the update is FilterPy's Kalman correction of
``predict``'s (χ̄, P̄)), ``hygiene`` (symmetric positive definite finite covariances through a 2 g
manoeuvre, repeated times and a long gap), ``consistency`` (on straight constant-velocity flight with
q = 1 m²/s³ and the truth's initial velocity drawn from the prior, the mean NEES and NIS are not
above their 99.9 % χ² bounds: a model may be cautious, not overconfident) and ``snapshot``.

All data are generated here from fixed seeds, so a check gives the same verdict every time; each
takes well under a few seconds.
"""

from __future__ import annotations

import copy
from collections.abc import Callable, Hashable, Iterable
from typing import Any

import attrs
import numpy as np
from scipy.stats import chi2

from radartracker.domain import BiasState
from radartracker.errors import ConfigurationError
from radartracker.estimation.base import AircraftEstimate, Estimator, EstimatorConfig, Innovation, PlaneMeasurement
from radartracker.estimation.motion import MotionModel
from radartracker.registry import parse_value, option_fields
from radartracker.tracking.filters import MotionConfig, TrackFilter

ESTIMATOR_CHECKS = ("contract", "filterpy", "consistency", "reads", "lifecycle", "update_many", "snapshot")
MOTION_CHECKS = ("contract", "errors", "reads", "filterpy", "hygiene", "consistency", "snapshot")
_TOL = 1e-9
_H = np.hstack([np.eye(2), np.zeros((2, 2))])


class CheckFailed(AssertionError):
    """A plugin failed a conformance check; the message names the plugin, the check and the fault."""


def _fail(owner: str, check: str, message: str) -> CheckFailed:
    return CheckFailed(f"{owner}: check '{check}' failed: {message}")


def _close(a: Any, b: Any, tol: float = _TOL) -> bool:
    a, b = np.asarray(a, float), np.asarray(b, float)
    return a.shape == b.shape and bool(np.allclose(a, b, rtol=tol, atol=tol * max(1.0, float(np.max(np.abs(b), initial=0.0)))))


# --- synthetic data ------------------------------------------------------------------------------

def _noise_cov(rng: np.random.Generator, sd: float = 60.0) -> np.ndarray:
    L = rng.normal(0.0, sd, (2, 2))
    return L @ L.T + (0.5 * sd) ** 2 * np.eye(2)


def _cv_truth(rng: np.random.Generator, motion: MotionModel, x0: np.ndarray, times: np.ndarray) -> np.ndarray:
    xs = [np.asarray(x0, float)]
    for k in range(1, len(times)):
        A, Q = motion.transition(times[k] - times[k - 1])
        xs.append(A @ xs[-1] + (rng.multivariate_normal(np.zeros(4), Q) if Q.any() else 0.0))
    return np.array(xs)


@attrs.frozen
class _Stream:
    """Measurements of several aircraft by radars (biased, C_s ≠ 0) and unbiased sources, in time order."""

    priors: dict  # key -> (time, state, cov)
    measurements: list  # PlaneMeasurement
    truth: dict  # key -> (times, states)


def _prior(rng: np.random.Generator, sd_v: float, sd_p: float = 300.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(prior mean, prior covariance, true state drawn from it)."""
    cov = np.diag([sd_p**2, sd_p**2, sd_v**2, sd_v**2])
    mean = np.array([rng.uniform(-4e4, 4e4), rng.uniform(-4e4, 4e4), 0.0, 0.0])
    return mean, cov, rng.multivariate_normal(mean, cov)


def _unbiased_stream(rng: np.random.Generator, motion: MotionModel, n: int, key: Hashable = "a1",
                     sd_v: float = 150.0) -> _Stream:
    """One aircraft measured only by unbiased positions (C_s = 0) at irregular times."""
    times = np.concatenate([[0.0], np.cumsum(rng.uniform(0.5, 6.0, n))])
    mean, cov, x0 = _prior(rng, sd_v)
    truth = _cv_truth(rng, motion, x0, times)
    ms = []
    for k in range(1, len(times)):
        R = _noise_cov(rng)
        ms.append(PlaneMeasurement(float(times[k]), key, None, rng.multivariate_normal(truth[k, :2], R), np.zeros((2, 2)), R))
    return _Stream({key: (0.0, mean, cov)}, ms, {key: (times, truth)})


_RADARS = {"R1": np.array([-6e4, -2e4]), "R2": np.array([5e4, 3e4])}
_W = np.diag([70.0**2, np.radians(0.08) ** 2])


def _mixed_stream(rng: np.random.Generator, config: EstimatorConfig, n: int, keys: Iterable[Hashable]) -> _Stream:
    """Aircraft plotted by radars R1, R2 with biases drawn from the prior (C_s = ∂z/∂[Δr, Δθ] at the
    plot, R = C_s W C_sᵀ), and every fourth measurement an unbiased position."""
    keys = list(keys)
    bias = {r: rng.multivariate_normal(np.zeros(2), config.bias_prior()) for r in _RADARS}
    priors, truth, ms = {}, {}, []
    for i, key in enumerate(keys):
        times = np.concatenate([[float(i)], float(i) + np.cumsum(rng.uniform(1.0, 5.0, n))])
        mean, cov, x0 = _prior(rng, 150.0)
        xs = _cv_truth(rng, config.motion, x0, times)
        priors[key], truth[key] = (float(times[0]), mean, cov), (times, xs)
        for k in range(1, len(times)):
            if k % 4 == 0:
                R = _noise_cov(rng)
                ms.append(PlaneMeasurement(float(times[k]), key, None, rng.multivariate_normal(xs[k, :2], R), np.zeros((2, 2)), R))
                continue
            rid = "R1" if k % 2 else "R2"
            d = xs[k, :2] - _RADARS[rid]
            rho, theta = float(np.hypot(*d)), float(np.arctan2(d[0], d[1]))
            C = np.array([[np.sin(theta), rho * np.cos(theta)], [np.cos(theta), -rho * np.sin(theta)]])
            z = xs[k, :2] + C @ (bias[rid] + rng.multivariate_normal(np.zeros(2), _W))
            ms.append(PlaneMeasurement(float(times[k]), key, rid, z, C, C @ _W @ C.T))
    ms.sort(key=lambda m: m.time)
    return _Stream(priors, ms, truth)


# --- estimators ----------------------------------------------------------------------------------

def _estimator_factory(cls: type[Estimator], config: EstimatorConfig, options: dict[str, Any]) -> Callable[[], Estimator]:
    owner = f"estimator {getattr(cls, 'name', cls.__name__)!r}"
    if cls.options_class is None:
        if options:
            raise ConfigurationError(f"{owner} takes no options; got {sorted(options)}")
        return lambda: cls(config)
    fields = option_fields(cls.options_class)
    unknown = sorted(set(options) - set(fields))
    if unknown:
        raise ConfigurationError(f"{owner}: unknown option {unknown[0]!r}; valid options: {', '.join(sorted(fields))}")
    values = {k: parse_value(v, fields[k].type) if isinstance(v, str) else v for k, v in options.items()}
    opts = cls.options_class(**values)
    return lambda: cls(config, opts)


def _started(make: Callable[[], Estimator], stream: _Stream, radars: Iterable[str] = ()) -> Estimator:
    est = make()
    for r in radars:
        est.add_radar(r)
    for key, (t, x, P) in stream.priors.items():
        est.add_aircraft(key, t, x.copy(), P.copy())
    return est


def _reads(est: Estimator) -> list[np.ndarray]:
    """Everything an estimator reports, as arrays (for bit-for-bit comparisons)."""
    out: list[np.ndarray] = []
    for key in est.aircraft_keys:
        a = est.aircraft(key)
        out += [np.array([a.time]), a.state, a.cov]
    for r in est.radars:
        b = est.bias(r)
        out += [b.bias, b.cov]
    return out


def _identical(a: list[np.ndarray], b: list[np.ndarray]) -> bool:
    return len(a) == len(b) and all(np.array_equal(x, y, equal_nan=True) for x, y in zip(a, b))


def _check_contract(make: Callable[[], Estimator], config: EstimatorConfig, owner: str) -> None:
    check = "contract"
    est = make()
    if not isinstance(est, Estimator):
        raise _fail(owner, check, f"constructs a {type(est).__name__}, not an Estimator")
    if est.config is not config:
        raise _fail(owner, check, "does not keep the EstimatorConfig it was given as .config")
    est.add_radar("R1")
    est.add_radar("R2")
    if sorted(est.radars) != ["R1", "R2"] or est.aircraft_keys:
        raise _fail(owner, check, f"radars {est.radars} / aircraft {est.aircraft_keys} after adding R1, R2")
    for r in ("R1", "R2"):
        b = est.bias(r)
        if not isinstance(b, BiasState) or np.shape(b.bias) != (2,) or np.shape(b.cov) != (2, 2):
            raise _fail(owner, check, f"bias({r!r}) must be a BiasState with bias (2,) and cov (2, 2), got {b!r}")
        if not _close(b.cov, config.bias_prior()) or np.any(b.bias != 0.0):
            raise _fail(owner, check, f"bias({r!r}) must start at 0 with the configured prior covariance, got {b!r}")
    x0, P0 = np.array([1e4, 2e4, 100.0, -50.0]), np.diag([1e4, 1e4, 400.0, 400.0])
    est.add_aircraft("a", 5.0, x0, P0)
    a = est.aircraft("a")
    if not isinstance(a, AircraftEstimate) or a.time != 5.0 or not _close(a.state, x0) or not _close(a.cov, P0):
        raise _fail(owner, check, f"aircraft('a') right after add_aircraft must be the prior, got {a!r}")
    if list(est.aircraft_keys) != ["a"]:
        raise _fail(owner, check, f"aircraft_keys {est.aircraft_keys} after adding 'a'")
    try:
        est.add_aircraft("a", 5.0, x0, P0)
    except ValueError:
        pass
    else:
        raise _fail(owner, check, "a second add_aircraft('a') must raise ValueError")
    R = 100.0 * np.eye(2)
    for bad, what in ((PlaneMeasurement(6.0, "nobody", None, x0[:2], np.zeros((2, 2)), R), "an unknown aircraft"),
                      (PlaneMeasurement(6.0, "a", "R9", x0[:2], np.eye(2), R), "an unknown radar")):
        try:
            est.update(bad)
        except (KeyError, ValueError):
            pass
        else:
            raise _fail(owner, check, f"update of {what} must raise KeyError or ValueError")
    inn = est.update(PlaneMeasurement(6.0, "a", "R1", x0[:2] + 100.0, np.array([[1.0, 0.0], [0.0, 1e4]]), R))
    if not (isinstance(inn, Innovation) and np.shape(inn.nu) == (2,) and np.shape(inn.S) == (2, 2)
            and np.isfinite(inn.nis) and inn.nis >= 0.0):
        raise _fail(owner, check, f"update must return Innovation(nu (2,), S (2, 2), nis ≥ 0), got {inn!r}")
    est.remove_aircraft("a")
    if est.aircraft_keys:
        raise _fail(owner, check, f"aircraft_keys {est.aircraft_keys} after removing the only aircraft")


def _check_filterpy(make: Callable[[], Estimator], config: EstimatorConfig, owner: str) -> None:
    from filterpy.kalman import KalmanFilter

    check = "filterpy"
    stream = _unbiased_stream(np.random.default_rng(20), config.motion, 40)
    est = _started(make, stream, ["R1"])
    bias0 = est.bias("R1")
    t0, x0, P0 = stream.priors["a1"]
    kf = KalmanFilter(dim_x=4, dim_z=2)
    kf.x, kf.P, kf.H = x0.copy(), P0.copy(), _H.copy()
    t = t0
    for k, m in enumerate(stream.measurements):
        kf.F, kf.Q = config.motion.transition(m.time - t)
        kf.predict()
        kf.R = m.R
        kf.update(m.z)
        t = m.time
        inn = est.update(m)
        a = est.aircraft("a1")
        nis = float(kf.y @ np.linalg.solve(kf.S, kf.y))
        for what, ours, ref in (("state", a.state, kf.x), ("covariance", a.cov, kf.P), ("innovation ν", inn.nu, kf.y),
                                ("innovation covariance Λ", inn.S, kf.S), ("NIS", inn.nis, nis), ("time", a.time, m.time)):
            if not _close(ours, ref):
                raise _fail(owner, check, f"update {k}: {what} differs from FilterPy's KalmanFilter: {ours} vs {ref}")
    b = est.bias("R1")
    if not (_close(b.bias, bias0.bias) and _close(b.cov, bias0.cov)):
        raise _fail(owner, check, f"unbiased measurements moved the uncorrelated bias of R1: {b!r} (was {bias0!r})")


def _chi2_inside(total: float, dof: int, p: float = 1e-3) -> tuple[bool, float, float]:
    lo, hi = chi2.ppf(p / 2, dof), chi2.ppf(1 - p / 2, dof)
    return lo <= total <= hi, lo, hi


def _check_consistency(make: Callable[[], Estimator], config: EstimatorConfig, owner: str, runs: int = 30) -> None:
    check = "consistency"
    nees, nis, n = 0.0, 0.0, 0
    for r in range(runs):
        stream = _unbiased_stream(np.random.default_rng([21, r]), config.motion, 25)
        est = _started(make, stream, ["R1"])
        times, truth = stream.truth["a1"]
        for k, m in enumerate(stream.measurements, start=1):
            nis += est.update(m).nis
            a = est.aircraft("a1")
            e = a.state - truth[k]
            nees += float(e @ np.linalg.solve(a.cov, e))
            n += 1
    for what, total, dof in (("NEES", nees, 4 * n), ("NIS", nis, 2 * n)):
        ok, lo, hi = _chi2_inside(total, dof)
        if not ok:
            raise _fail(owner, check, f"summed {what} {total:.1f} over {n} updates outside the 99.9 % χ²({dof}) "
                                      f"interval [{lo:.1f}, {hi:.1f}] (mean {total / n:.2f}, expected {dof // n})")


def _check_reads(make: Callable[[], Estimator], config: EstimatorConfig, owner: str) -> None:
    check = "reads"
    stream = _mixed_stream(np.random.default_rng(22), config, 12, ["a1", "a2"])
    est = _started(make, stream, _RADARS)
    half = len(stream.measurements) // 2
    for m in stream.measurements[:half]:
        est.update(m)
    twin = copy.deepcopy(est)
    for _ in range(2):  # read everything twice, and scribble on what comes back
        got = _reads(est)
        for key in est.aircraft_keys:
            est.predict(key, est.aircraft(key).time + 30.0)
        for listing in (est.aircraft_keys, est.radars):
            if isinstance(listing, list):
                listing.clear()
        for arr in got:
            arr[...] = np.nan
    if not _identical(_reads(est), _reads(twin)):
        raise _fail(owner, check, "reads changed the state or returned views of it (aircraft/bias arrays must be copies)")
    for m in stream.measurements[half:]:
        ia, ib = est.update(m), twin.update(m)
        if not _identical([ia.nu, ia.S, np.array([ia.nis])], [ib.nu, ib.S, np.array([ib.nis])]):
            raise _fail(owner, check, f"after reads, the update at t={m.time} differs from an untouched copy's")
    if not _identical(_reads(est), _reads(twin)):
        raise _fail(owner, check, "after reads, the estimates differ from an untouched copy's")


def _check_lifecycle(make: Callable[[], Estimator], config: EstimatorConfig, owner: str) -> None:
    check = "lifecycle"
    stream = _mixed_stream(np.random.default_rng(23), config, 10, ["a1", "a2", "a3"])
    est = _started(make, _Stream({k: v for k, v in stream.priors.items() if k != "a3"}, [], {}), _RADARS)
    removed_at = stream.measurements[len(stream.measurements) // 2].time
    added = removed = False
    for m in stream.measurements:
        if m.aircraft == "a3" and not added:
            est.add_aircraft("a3", *[np.copy(v) if isinstance(v, np.ndarray) else v for v in stream.priors["a3"]])
            added = True
        if m.time >= removed_at and not removed:
            est.remove_aircraft("a1")
            removed = True
            if "a1" in est.aircraft_keys:
                raise _fail(owner, check, "a removed aircraft is still listed in aircraft_keys")
            try:
                est.aircraft("a1")
            except (KeyError, ValueError):
                pass
            else:
                raise _fail(owner, check, "aircraft() of a removed key must raise KeyError or ValueError")
        if m.aircraft == "a1" and removed:
            continue
        inn = est.update(m)
        if not np.isfinite(inn.nis):
            raise _fail(owner, check, f"non-finite NIS at t={m.time} after aircraft were added and removed")
    if sorted(est.aircraft_keys) != ["a2", "a3"]:
        raise _fail(owner, check, f"aircraft_keys {sorted(est.aircraft_keys)}, expected ['a2', 'a3']")
    x0, P0 = np.array([1.0, 2.0, 3.0, 4.0]), np.diag([1e4, 1e4, 100.0, 100.0])
    est.add_aircraft("a1", stream.measurements[-1].time, x0, P0)
    a = est.aircraft("a1")
    if not (_close(a.state, x0) and _close(a.cov, P0)):
        raise _fail(owner, check, f"a key added again must start from its new prior, got {a!r}")
    for key in est.aircraft_keys:
        a = est.aircraft(key)
        if not (np.isfinite(a.state).all() and np.isfinite(a.cov).all() and _close(a.cov, a.cov.T)):
            raise _fail(owner, check, f"aircraft {key!r}: non-finite or asymmetric estimate {a!r}")


def _check_update_many(make: Callable[[], Estimator], config: EstimatorConfig, owner: str) -> None:
    check = "update_many"
    stream = _mixed_stream(np.random.default_rng(24), config, 10, ["a1", "a2"])
    one, batch = _started(make, stream, _RADARS), _started(make, stream, _RADARS)
    ms = stream.measurements
    seq = [one.update(m) for m in ms]
    inn = batch.update_many([m.time for m in ms], [m.aircraft for m in ms], [m.radar for m in ms],
                            np.array([m.z for m in ms]), np.array([m.C for m in ms]), np.array([m.R for m in ms]))
    for what, a, b in (("ν", inn.nu, [s.nu for s in seq]), ("Λ", inn.S, [s.S for s in seq]),
                       ("NIS", inn.nis, [s.nis for s in seq])):
        if not _close(a, b):
            raise _fail(owner, check, f"update_many's {what} differs from one update after another")
    for x, y in zip(_reads(batch), _reads(one)):
        if not _close(x, y):
            raise _fail(owner, check, "estimates after update_many differ from one update after another")


def _check_snapshot(make: Callable[[], Estimator], config: EstimatorConfig, owner: str) -> None:
    check = "snapshot"
    stream = _mixed_stream(np.random.default_rng(25), config, 12, ["a1", "a2"])
    est = _started(make, stream, _RADARS)
    half = len(stream.measurements) // 2
    for m in stream.measurements[:half]:
        est.update(m)
    copies = {"copy.deepcopy": copy.deepcopy(est)}
    if callable(getattr(est, "state_dict", None)):
        fresh = make()
        for r in est.radars:
            fresh.add_radar(r)
        fresh.load_state_dict(copy.deepcopy(est.state_dict()))
        copies["state_dict/load_state_dict"] = fresh
    for m in stream.measurements[half:]:
        ref = est.update(m)
        for how, other in copies.items():
            inn = other.update(m)
            if not _identical([inn.nu, inn.S, np.array([inn.nis])], [ref.nu, ref.S, np.array([ref.nis])]):
                raise _fail(owner, check, f"a {how} round trip does not continue bit for bit (update at t={m.time})")
    for how, other in copies.items():
        if not _identical(_reads(other), _reads(est)):
            raise _fail(owner, check, f"after a {how} round trip the estimates differ")


_ESTIMATOR_RUNNERS = {"contract": _check_contract, "filterpy": _check_filterpy, "consistency": _check_consistency,
                      "reads": _check_reads, "lifecycle": _check_lifecycle, "update_many": _check_update_many,
                      "snapshot": _check_snapshot}


def check_estimator(cls: type[Estimator], *, config: EstimatorConfig | None = None,
                    checks: Iterable[str] = ESTIMATOR_CHECKS, **options: Any) -> list[str]:
    """Run the estimator checks (module docstring) on plugin class ``cls`` built with ``config``
    (default: constant velocity with q = 1 m²/s³ and the default bias priors) and ``options`` (typed
    values, or ``KEY=VALUE`` strings, of its ``options_class``). Raises :class:`CheckFailed`."""
    owner = f"estimator {getattr(cls, 'name', '?')!r} ({cls.__module__}.{cls.__qualname__})"
    if not (isinstance(cls, type) and issubclass(cls, Estimator)):
        raise CheckFailed(f"{cls!r} is not an Estimator subclass")
    config = config if config is not None else EstimatorConfig(motion=MotionModel(1.0))
    make = _estimator_factory(cls, config, options)
    unknown = set(checks) - set(_ESTIMATOR_RUNNERS)
    if unknown:
        raise ValueError(f"unknown checks {sorted(unknown)}; known: {', '.join(ESTIMATOR_CHECKS)}")
    done = []
    for name in checks:
        try:
            _ESTIMATOR_RUNNERS[name](make, config, owner)
        except CheckFailed:
            raise
        except Exception as exc:
            raise _fail(owner, name, f"raised {type(exc).__name__}: {exc}") from exc
        done.append(name)
    return done


# --- motion models -------------------------------------------------------------------------------

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
    Rs = np.array([_noise_cov(rng, 50.0) for _ in range(n)])
    zs = np.array([rng.multivariate_normal(s[:2], R) for s, R in zip(truth, Rs)])
    return t, np.array(truth), zs, Rs


def _filter_state(f: TrackFilter) -> list[np.ndarray]:
    t, x, P = f.estimate()
    return [np.array([t]), x, P]


def _check_motion_contract(cls: type[TrackFilter], config: MotionConfig, owner: str) -> None:
    check = "contract"
    if not (isinstance(cls.config_class, type) and issubclass(cls.config_class, MotionConfig)):
        raise _fail(owner, check, "config_class must be a MotionConfig subclass")
    if not isinstance(cls().config, cls.config_class):
        raise _fail(owner, check, "a filter built without a config must hold config_class() as .config")
    if cls.config_class is not MotionConfig:
        try:
            cls(MotionConfig())
        except ConfigurationError:
            pass
        else:
            raise _fail(owner, check, "a config of another type must be refused with ConfigurationError")
    f = cls(config)
    if f.config is not config:
        raise _fail(owner, check, "does not keep the config it was given as .config")
    try:
        f.predict(1.0)
    except ValueError:
        pass
    else:
        raise _fail(owner, check, "predict before start must raise ValueError")
    R = 50.0**2 * np.eye(2)
    f.start(0.0, np.array([1e4, 2e4]), R)
    t, x, P = f.estimate()
    if t != 0.0 or np.shape(x) != (4,) or np.shape(P) != (4, 4) or not np.allclose(x[:2], [1e4, 2e4]):
        raise _fail(owner, check, f"estimate() after start must be (0.0, χ (4,) at z, P (4, 4)), got {(t, x, P)}")
    sd_v = config.prior_sd_velocity_mps
    if not (np.allclose(P[:2, :2], R) and np.allclose(np.diag(P)[2:], sd_v**2) and np.allclose(x[2:], 0.0)):
        raise _fail(owner, check, f"start must give χ = [z, 0, 0], P = diag(R, σ_v² I) with σ_v = {sd_v}, got {x}, {P}")
    nis = f.update(4.0, np.array([1e4 + 800.0, 2e4]), R)
    if not (isinstance(nis, float) and np.isfinite(nis) and nis >= 0.0):
        raise _fail(owner, check, f"update must return the NIS as a float ≥ 0, got {nis!r}")


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
            raise _fail(owner, check, f"update with {what} must raise ValueError")
        if not _identical(_filter_state(f), before):
            raise _fail(owner, check, f"a refused update ({what}) changed the filter")


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
    if not (np.array_equal(x2, f.predict(t[6])[0]) and _identical(_filter_state(f), _filter_state(twin))):
        raise _fail(owner, check, "predict/estimate changed the filter or returned views of its state")
    x, P = f.predict(t[6])
    nu = zs[6] - x[:2]
    expected = float(nu @ np.linalg.solve(P[:2, :2] + Rs[6], nu))
    got = f.update(t[6], zs[6], Rs[6])
    if not _close(got, expected):
        raise _fail(owner, check, f"update's NIS {got} is not that of predict's output ({expected})")


def _check_motion_filterpy(cls: type[TrackFilter], config: MotionConfig, owner: str) -> None:
    from filterpy.kalman import KalmanFilter

    check = "filterpy"
    t, _, zs, Rs = _track(np.random.default_rng(31), 30, 1.0, config.prior_sd_velocity_mps, manoeuvre=True)
    f = cls(config)
    f.start(t[0], zs[0], Rs[0])
    for k in range(1, len(t)):
        x, P = f.predict(t[k])
        kf = KalmanFilter(dim_x=4, dim_z=2)
        kf.x, kf.P, kf.H, kf.R = x.copy(), P.copy(), _H.copy(), Rs[k]
        kf.update(zs[k])
        nis = f.update(t[k], zs[k], Rs[k])
        _, xu, Pu = f.estimate()
        if not (_close(xu, kf.x) and _close(Pu, kf.P) and _close(nis, float(kf.y @ np.linalg.solve(kf.S, kf.y)))):
            raise _fail(owner, check, f"update {k} is not FilterPy's Kalman correction of predict()'s (χ̄, P̄) "
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
            raise _fail(owner, check, f"update {k} (t={t[k]}): covariance not symmetric positive definite or not finite")


def _check_motion_consistency(cls: type[TrackFilter], config: MotionConfig, owner: str, runs: int = 25) -> None:
    check = "consistency"
    nees = nis = 0.0
    n = 0
    for r in range(runs):
        t, truth, zs, Rs = _track(np.random.default_rng([33, r]), 25, 1.0, config.prior_sd_velocity_mps)
        f = cls(config)
        f.start(t[0], zs[0], Rs[0])
        for k in range(1, len(t)):
            nis += f.update(t[k], zs[k], Rs[k])
            _, x, P = f.estimate()
            e = x - truth[k]
            nees += float(e @ np.linalg.solve(P, e))
            n += 1
    for what, total, dof in (("NEES", nees, 4 * n), ("NIS", nis, 2 * n)):
        hi = chi2.ppf(0.999, dof)
        if total > hi:
            raise _fail(owner, check, f"summed {what} {total:.1f} over {n} updates above the 99.9 % χ²({dof}) "
                                      f"bound {hi:.1f} (mean {total / n:.2f}, expected ≤ {dof // n}): overconfident")


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
            if other.update(t[k], zs[k], Rs[k]) != ref or not _identical(_filter_state(other), _filter_state(f)):
                raise _fail(owner, check, f"a {how} round trip does not continue bit for bit (update at t={t[k]})")


_MOTION_RUNNERS = {"contract": _check_motion_contract, "errors": _check_motion_errors, "reads": _check_motion_reads,
                   "filterpy": _check_motion_filterpy, "hygiene": _check_motion_hygiene,
                   "consistency": _check_motion_consistency, "snapshot": _check_motion_snapshot}


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
    unknown = set(checks) - set(_MOTION_RUNNERS)
    if unknown:
        raise ValueError(f"unknown checks {sorted(unknown)}; known: {', '.join(MOTION_CHECKS)}")
    done = []
    for name in checks:
        try:
            _MOTION_RUNNERS[name](cls, config, owner)
        except CheckFailed:
            raise
        except Exception as exc:
            raise _fail(owner, name, f"raised {type(exc).__name__}: {exc}") from exc
        done.append(name)
    return done
