"""Conformance checks of associator plugins (``radartracker.associators``): ``check_associator``.

* ``contract`` — ``name`` is set, the class builds from an :class:`AssociationSettings`, ``associate``
  returns an :class:`Association` with one entry per plot: a track index, ``NEW_TRACK`` or ``REFUSED``
  with a named reason, no track given two plots of one radar's sweep;
* ``obvious`` — well separated tracks, each with one plot at its predicted position (and its truth
  label): every plot goes to its own track; plots hundreds of kilometres from every track (without a
  label) go to none; a plot of impossible geometry (``valid`` False) goes to none;
* ``manager`` — a TrackManager with the associator on a small built-in scenario confirms tracks and
  accounts for every input (used or counted under a reason).
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

from radartracker.domain import Plot
from radartracker.registry import make_filter_factory, make_manager
from radartracker.testing.common import fail, run_checks
from radartracker.tracking.associators import NEW_TRACK, REFUSED, Association, AssociationSettings, Associator, RadarPlots
from radartracker.tracking.config import ManagerConfig
from radartracker.tracking.frame import Prediction
from radartracker.tracking.track import Track

ASSOCIATOR_CHECKS = ["contract", "obvious", "manager"]


def _tracks(rng: np.random.Generator, n: int) -> list[Track]:
    """``n`` confirmed CV tracks 20 km apart, estimated at t = 0 with 30 m position σ."""
    make = make_filter_factory("cv")
    out = []
    for i in range(n):
        f = make()
        f.start(0.0, np.array([20_000.0 * i, 5_000.0 * (i % 3)]), 900.0 * np.eye(2))
        out.append(Track(i + 1, f, "confirmed", 0.0, 0.0, target=f"a{i}"))
    return out


def _plots(z: np.ndarray, valid: np.ndarray | None = None, targets: list | None = None) -> RadarPlots:
    """Plots at ``z`` (truth labels ``targets``, for an associator that reads them)."""
    n = len(z)
    targets = targets or [None] * n
    plots = [Plot(0.5, "r1", 10_000.0, 0.1, target=targets[k]) for k in range(n)]
    C = np.zeros((n, 2, 2))
    R = np.repeat((50.0**2 * np.eye(2))[None], n, 0)
    return RadarPlots("r1", plots, np.asarray(z, float), C, R, np.ones(n, bool) if valid is None else valid,
                      np.zeros(2), np.zeros((2, 2)))


def _valid_answer(owner: str, ans: object, n: int, m: int) -> Association:
    if not isinstance(ans, tuple) or not hasattr(ans, "track") or not hasattr(ans, "reasons"):
        raise fail(owner, "contract", f"associate returned {type(ans).__name__}, not an Association")
    track = np.asarray(ans.track)
    if track.shape != (n,) or track.dtype.kind not in "iu":
        raise fail(owner, "contract", f"track: {n} integers expected, got shape {track.shape} of {track.dtype}")
    if not np.all((track == NEW_TRACK) | (track == REFUSED) | ((track >= 0) & (track < m))):
        raise fail(owner, "contract", f"track indices outside [0, {m}) and not NEW_TRACK/REFUSED: {track.tolist()}")
    used = track[track >= 0]
    if len(set(used.tolist())) != len(used):
        raise fail(owner, "contract", f"a track was given two plots of one sweep: {track.tolist()}")
    refused = set(np.flatnonzero(track == REFUSED).tolist())
    if set(ans.reasons) != refused or not all(isinstance(r, str) and r for r in ans.reasons.values()):
        raise fail(owner, "contract", "each refused plot needs a named reason, and only those")
    return ans


def _check_contract(cls: type[Associator], owner: str) -> None:
    if not isinstance(getattr(cls, "name", None), str) or cls.name in ("", "?"):
        raise fail(owner, "contract", "the class sets no name")
    assoc = cls(AssociationSettings())
    rng = np.random.default_rng(1)
    tracks = _tracks(rng, 4)
    z = rng.normal(0.0, 40_000.0, (9, 2))
    _valid_answer(owner, assoc.associate(_plots(z), Prediction(tracks, 0.5)), 9, 4)
    _valid_answer(owner, assoc.associate(_plots(z), Prediction([], 0.5)), 9, 0)


def _check_obvious(cls: type[Associator], owner: str) -> None:
    assoc = cls(AssociationSettings())
    rng = np.random.default_rng(2)
    tracks = _tracks(rng, 5)
    pred = Prediction(tracks, 0.5)
    order = rng.permutation(5)
    far = np.array([[1e6, 1e6], [-1e6, 5e5]])
    z = np.concatenate([pred.position[order] + rng.normal(0.0, 20.0, (5, 2)), far, pred.position[:1]])
    valid = np.ones(8, bool)
    valid[7] = False
    targets = [f"a{i}" for i in order.tolist()] + [None, None, "a0"]
    ans = _valid_answer(owner, assoc.associate(_plots(z, valid, targets), pred), 8, 5)
    if ans.track[:5].tolist() != order.tolist():
        raise fail(owner, "obvious", f"plots at tracks {order.tolist()} were given {ans.track[:5].tolist()}")
    if (ans.track[5:] >= 0).any():
        raise fail(owner, "obvious", f"far plots or an impossible one given a track: {ans.track[5:].tolist()}")


def _check_manager(cls: type[Associator], owner: str) -> None:
    from radartracker.pipeline.stream import scenario_stream
    from radartracker.simulation.scenarios import build_scenario

    data = build_scenario("demo", seed=3, duration=120.0).run()
    items = scenario_stream(data)
    mgr = make_manager(data.radars, data.reference, ManagerConfig(), associator=cls(AssociationSettings()))
    events = mgr.process_many(items)
    if not any(e.kind == "confirmed" for e in events):
        raise fail(owner, "manager", "no track was confirmed on the demo scenario")
    counted = sum(v for k, v in mgr.accounting().items())
    if counted != len(items):
        raise fail(owner, "manager", f"{len(items)} inputs, {counted} used or counted")


_RUNNERS = {"contract": _check_contract, "obvious": _check_obvious, "manager": _check_manager}


def check_associator(cls: type[Associator], *, checks: Iterable[str] = ASSOCIATOR_CHECKS) -> list[str]:
    """Run the associator checks (module docstring) on class ``cls``; raises :class:`CheckFailed`."""
    owner = f"associator {getattr(cls, 'name', '?')!r} ({cls.__module__}.{cls.__qualname__})"
    if not (isinstance(cls, type) and issubclass(cls, Associator)):
        raise fail(owner, "contract", f"{cls!r} is not an Associator subclass")
    return run_checks(owner, _RUNNERS, list(checks), cls)
