"""Conformance checks of estimator plugins (:func:`check_estimator`; the list in :mod:`radartracker.testing`)."""

from __future__ import annotations

import copy
from collections.abc import Callable, Hashable, Iterable
from typing import Any

import attrs
import numpy as np

from radartracker.domain import BiasState
from radartracker.errors import ConfigurationError
from radartracker.estimation.base import AircraftEstimate, Estimator, EstimatorConfig, Innovation, PlaneMeasurement
from radartracker.estimation.motion import MotionModel
from radartracker.registry import option_fields, parse_value
from radartracker.testing.common import (H, CheckFailed, check_kernels, chi2_inside, close, fail, identical,
                                         kalman_filter_class, noise_cov, run_checks)

ESTIMATOR_CHECKS = ("contract", "filterpy", "consistency", "reads", "lifecycle", "update_many", "snapshot", "kernels")
# for an exact joint filter (every cross-covariance kept): consistent on biased measurements too
EXACT_CHECKS = ESTIMATOR_CHECKS + ("joint_consistency",)


# --- synthetic data ------------------------------------------------------------------------------

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
    biases: dict = attrs.field(factory=dict)  # radar -> true [Δr, Δθ]


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
        R = noise_cov(rng)
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
                R = noise_cov(rng)
                ms.append(PlaneMeasurement(float(times[k]), key, None, rng.multivariate_normal(xs[k, :2], R), np.zeros((2, 2)), R))
                continue
            rid = "R1" if k % 2 else "R2"
            d = xs[k, :2] - _RADARS[rid]
            rho, theta = float(np.hypot(*d)), float(np.arctan2(d[0], d[1]))
            C = np.array([[np.sin(theta), rho * np.cos(theta)], [np.cos(theta), -rho * np.sin(theta)]])
            z = xs[k, :2] + C @ (bias[rid] + rng.multivariate_normal(np.zeros(2), _W))
            ms.append(PlaneMeasurement(float(times[k]), key, rid, z, C, C @ _W @ C.T))
    ms.sort(key=lambda m: m.time)
    return _Stream(priors, ms, truth, bias)


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


def _half_run(make: Callable[[], Estimator], config: EstimatorConfig, seed: int) -> tuple[Estimator, list]:
    """An estimator started on a two-aircraft mixed stream (``seed``) and updated with its first half; the
    measurements of the second half (for the checks that copy an estimator midway and go on)."""
    stream = _mixed_stream(np.random.default_rng(seed), config, 12, ["a1", "a2"])
    est = _started(make, stream, _RADARS)
    half = len(stream.measurements) // 2
    for m in stream.measurements[:half]:
        est.update(m)
    return est, stream.measurements[half:]


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


def _check_contract(make: Callable[[], Estimator], config: EstimatorConfig, owner: str) -> None:
    check = "contract"
    est = make()
    if not isinstance(est, Estimator):
        raise fail(owner, check, f"constructs a {type(est).__name__}, not an Estimator")
    if est.config is not config:
        raise fail(owner, check, "does not keep the EstimatorConfig it was given as .config")
    est.add_radar("R1")
    est.add_radar("R2")
    if sorted(est.radars) != ["R1", "R2"] or est.aircraft_keys:
        raise fail(owner, check, f"radars {est.radars} / aircraft {est.aircraft_keys} after adding R1, R2")
    for r in ("R1", "R2"):
        b = est.bias(r)
        if not isinstance(b, BiasState) or np.shape(b.bias) != (2,) or np.shape(b.cov) != (2, 2):
            raise fail(owner, check, f"bias({r!r}) must be a BiasState with bias (2,) and cov (2, 2), got {b!r}")
        if not close(b.cov, config.bias_prior()) or np.any(b.bias != 0.0):
            raise fail(owner, check, f"bias({r!r}) must start at 0 with the configured prior covariance, got {b!r}")
    x0, P0 = np.array([1e4, 2e4, 100.0, -50.0]), np.diag([1e4, 1e4, 400.0, 400.0])
    est.add_aircraft("a", 5.0, x0, P0)
    a = est.aircraft("a")
    if not isinstance(a, AircraftEstimate) or a.time != 5.0 or not close(a.state, x0) or not close(a.cov, P0):
        raise fail(owner, check, f"aircraft('a') right after add_aircraft must be the prior, got {a!r}")
    if list(est.aircraft_keys) != ["a"]:
        raise fail(owner, check, f"aircraft_keys {est.aircraft_keys} after adding 'a'")
    try:
        est.add_aircraft("a", 5.0, x0, P0)
    except ValueError:
        pass
    else:
        raise fail(owner, check, "a second add_aircraft('a') must raise ValueError")
    R = 100.0 * np.eye(2)
    for bad, what in ((PlaneMeasurement(6.0, "nobody", None, x0[:2], np.zeros((2, 2)), R), "an unknown aircraft"),
                      (PlaneMeasurement(6.0, "a", "R9", x0[:2], np.eye(2), R), "an unknown radar")):
        try:
            est.update(bad)
        except (KeyError, ValueError):
            pass
        else:
            raise fail(owner, check, f"update of {what} must raise KeyError or ValueError")
    inn = est.update(PlaneMeasurement(6.0, "a", "R1", x0[:2] + 100.0, np.array([[1.0, 0.0], [0.0, 1e4]]), R))
    if not (isinstance(inn, Innovation) and np.shape(inn.nu) == (2,) and np.shape(inn.S) == (2, 2)
            and np.isfinite(inn.nis) and inn.nis >= 0.0):
        raise fail(owner, check, f"update must return Innovation(nu (2,), S (2, 2), nis ≥ 0), got {inn!r}")
    est.remove_aircraft("a")
    if est.aircraft_keys:
        raise fail(owner, check, f"aircraft_keys {est.aircraft_keys} after removing the only aircraft")


def _check_filterpy(make: Callable[[], Estimator], config: EstimatorConfig, owner: str) -> None:
    KalmanFilter = kalman_filter_class()
    check = "filterpy"
    stream = _unbiased_stream(np.random.default_rng(20), config.motion, 40)
    est = _started(make, stream, ["R1"])
    bias0 = est.bias("R1")
    t0, x0, P0 = stream.priors["a1"]
    kf = KalmanFilter(dim_x=4, dim_z=2)
    kf.x, kf.P, kf.H = x0.copy(), P0.copy(), H.copy()
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
            if not close(ours, ref):
                raise fail(owner, check, f"update {k}: {what} differs from FilterPy's KalmanFilter: {ours} vs {ref}")
    b = est.bias("R1")
    if not (close(b.bias, bias0.bias) and close(b.cov, bias0.cov)):
        raise fail(owner, check, f"unbiased measurements moved the uncorrelated bias of R1: {b!r} (was {bias0!r})")


def _check_consistency(make: Callable[[], Estimator], config: EstimatorConfig, owner: str, runs: int = 40) -> None:
    """NIS of every update (white for a consistent filter: the sum is χ²(2N)) and NEES after the 3rd and
    the last update of each run (independent across runs: each sum is χ²(4·runs))."""
    check = "consistency"
    sums = {"NIS": [0.0, 0], "NEES after 3 updates": [0.0, 0], "NEES at the end": [0.0, 0]}
    for r in range(runs):
        stream = _unbiased_stream(np.random.default_rng([21, r]), config.motion, 25)
        est = _started(make, stream, ["R1"])
        truth = stream.truth["a1"][1]
        for k, m in enumerate(stream.measurements, start=1):
            sums["NIS"][0] += est.update(m).nis
            sums["NIS"][1] += 2
            if k in (3, len(stream.measurements)):
                a = est.aircraft("a1")
                e = a.state - truth[k]
                sums["NEES after 3 updates" if k == 3 else "NEES at the end"][0] += float(e @ np.linalg.solve(a.cov, e))
                sums["NEES after 3 updates" if k == 3 else "NEES at the end"][1] += 4
    _chi2_verdict(owner, check, sums)


def _chi2_verdict(owner: str, check: str, sums: dict[str, list]) -> None:
    for what, (total, dof) in sums.items():
        ok, lo, hi = chi2_inside(total, dof)
        if not ok:
            raise fail(owner, check, f"summed {what} {total:.1f} outside the 99.9 % χ²({dof}) interval [{lo:.1f}, "
                                     f"{hi:.1f}]: the reported covariances are not those of the errors")


def _check_reads(make: Callable[[], Estimator], config: EstimatorConfig, owner: str) -> None:
    check = "reads"
    est, rest = _half_run(make, config, 22)
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
    if not identical(_reads(est), _reads(twin)):
        raise fail(owner, check, "reads changed the state or returned views of it (aircraft/bias arrays must be copies)")
    for m in rest:
        ia, ib = est.update(m), twin.update(m)
        if not identical([ia.nu, ia.S, np.array([ia.nis])], [ib.nu, ib.S, np.array([ib.nis])]):
            raise fail(owner, check, f"after reads, the update at t={m.time} differs from an untouched copy's")
    if not identical(_reads(est), _reads(twin)):
        raise fail(owner, check, "after reads, the estimates differ from an untouched copy's")


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
                raise fail(owner, check, "a removed aircraft is still listed in aircraft_keys")
            try:
                est.aircraft("a1")
            except (KeyError, ValueError):
                pass
            else:
                raise fail(owner, check, "aircraft() of a removed key must raise KeyError or ValueError")
        if m.aircraft == "a1" and removed:
            continue
        inn = est.update(m)
        if not np.isfinite(inn.nis):
            raise fail(owner, check, f"non-finite NIS at t={m.time} after aircraft were added and removed")
    if sorted(est.aircraft_keys) != ["a2", "a3"]:
        raise fail(owner, check, f"aircraft_keys {sorted(est.aircraft_keys)}, expected ['a2', 'a3']")
    x0, P0 = np.array([1.0, 2.0, 3.0, 4.0]), np.diag([1e4, 1e4, 100.0, 100.0])
    est.add_aircraft("a1", stream.measurements[-1].time, x0, P0)
    a = est.aircraft("a1")
    if not (close(a.state, x0) and close(a.cov, P0)):
        raise fail(owner, check, f"a key added again must start from its new prior, got {a!r}")
    for key in est.aircraft_keys:
        a = est.aircraft(key)
        if not (np.isfinite(a.state).all() and np.isfinite(a.cov).all() and close(a.cov, a.cov.T)):
            raise fail(owner, check, f"aircraft {key!r}: non-finite or asymmetric estimate {a!r}")


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
        if not close(a, b):
            raise fail(owner, check, f"update_many's {what} differs from one update after another")
    for x, y in zip(_reads(batch), _reads(one)):
        if not close(x, y):
            raise fail(owner, check, "estimates after update_many differ from one update after another")


def _check_snapshot(make: Callable[[], Estimator], config: EstimatorConfig, owner: str) -> None:
    check = "snapshot"
    est, rest = _half_run(make, config, 25)
    copies = {"copy.deepcopy": copy.deepcopy(est)}
    if callable(getattr(est, "state_dict", None)):
        fresh = make()
        for r in est.radars:
            fresh.add_radar(r)
        fresh.load_state_dict(copy.deepcopy(est.state_dict()))
        copies["state_dict/load_state_dict"] = fresh
    for m in rest:
        ref = est.update(m)
        for how, other in copies.items():
            inn = other.update(m)
            if not identical([inn.nu, inn.S, np.array([inn.nis])], [ref.nu, ref.S, np.array([ref.nis])]):
                raise fail(owner, check, f"a {how} round trip does not continue bit for bit (update at t={m.time})")
    for how, other in copies.items():
        if not identical(_reads(other), _reads(est)):
            raise fail(owner, check, f"after a {how} round trip the estimates differ")


def _check_joint_consistency(make: Callable[[], Estimator], config: EstimatorConfig, owner: str,
                             runs: int = 40) -> None:
    """Three aircraft, two biased radars and unbiased positions, truth and biases drawn from the priors:
    the NIS of every update (χ²(2N)), and at the end of each run the NEES of one aircraft (χ²(4) per run)
    and of one radar's bias (χ²(2) per run), each summed over the independent runs."""
    check = "joint_consistency"
    sums = {"NIS": [0.0, 0], "aircraft NEES at the end": [0.0, 0], "bias NEES at the end": [0.0, 0]}
    for r in range(runs):
        stream = _mixed_stream(np.random.default_rng([26, r]), config, 12, ["a1", "a2", "a3"])
        est = _started(make, stream, _RADARS)
        for m in stream.measurements:
            sums["NIS"][0] += est.update(m).nis
            sums["NIS"][1] += 2
        a, b = est.aircraft("a1"), est.bias("R1")
        ea = a.state - stream.truth["a1"][1][-1]
        eb = b.bias - stream.biases["R1"]
        sums["aircraft NEES at the end"][0] += float(ea @ np.linalg.solve(a.cov, ea))
        sums["aircraft NEES at the end"][1] += 4
        sums["bias NEES at the end"][0] += float(eb @ np.linalg.solve(b.cov, eb))
        sums["bias NEES at the end"][1] += 2
    _chi2_verdict(owner, check, sums)


_ESTIMATOR_RUNNERS = {"contract": _check_contract, "filterpy": _check_filterpy, "consistency": _check_consistency,
                      "reads": _check_reads, "lifecycle": _check_lifecycle, "update_many": _check_update_many,
                      "snapshot": _check_snapshot, "joint_consistency": _check_joint_consistency,
                      "kernels": lambda make, config, owner: check_kernels(type(make()), owner)}


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
    return run_checks(owner, _ESTIMATOR_RUNNERS, list(checks), make, config)
