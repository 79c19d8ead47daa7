"""Driving several estimators with the same plots while aircraft come and go: the helper the exact-equality
tests of ``coupled-sparse`` against ``coupled`` share."""

from __future__ import annotations

from collections.abc import Callable, Iterable

import attrs
import numpy as np

from radartracker.api import Estimator, PlaneMeasurement

P0 = np.diag([1e4**2, 1e4**2, 300.0**2, 300.0**2])  # an aircraft's prior: position unknown, speed ± 300 m/s


def drive(ests: list[Estimator], plots: Iterable[PlaneMeasurement], lifetime: float, batch: int,
          update: Callable[[list[Estimator], list[PlaneMeasurement]], None],
          prior: Callable[[PlaneMeasurement], np.ndarray]) -> list[list[tuple]]:
    """The same plots to every estimator, ``batch`` at a time through ``update(ests, plots)`` (which applies
    them to each and compares what it must); an aircraft's track is removed (marginalised) and restarted under
    a new key every ``lifetime`` s, at the position ``prior(m)`` of its first plot then with zero velocity and
    covariance :data:`P0`. Returns every estimator's ``joint()`` after each removal and at the end."""
    gen: dict[object, tuple[str, float]] = {}
    joints: list[list[tuple]] = []
    pending: list[PlaneMeasurement] = []

    def flush() -> None:
        if pending:
            update(ests, pending)
            pending.clear()

    for m in plots:
        key, start = gen.get(m.aircraft, (None, 0.0))
        if key is None or m.time - start > lifetime:
            flush()
            if key is not None:
                for e in ests:
                    e.remove_aircraft(key)
                joints.append([e.joint() for e in ests])
            key = f"{m.aircraft}@{m.time:.1f}"
            gen[m.aircraft] = (key, m.time)
            state = np.array([*prior(m), 0.0, 0.0])  # one draw for every estimator
            for e in ests:
                e.add_aircraft(key, m.time, state, P0)
        pending.append(attrs.evolve(m, aircraft=key))
        if len(pending) >= batch:
            flush()
    flush()
    joints.append([e.joint() for e in ests])
    return joints
