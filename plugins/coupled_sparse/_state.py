"""The state of ``coupled-sparse`` as it is restored: untrusted input checked whole before it is used.

The compiled kernels index the stored arrays with slots, radar indices and counts taken from the state
(``rk[s, :nk[s]]`` picks bias entries, a slot picks an aircraft's blocks) without bounds checks, so the
state is accepted only if every array has its dtype and its shape for the capacity and the radars,
every slot and radar index is in range, the live slots (``aircraft``) and the ``free`` ones partition the
capacity, a live slot lists distinct radars (``nk`` of them, at most m) and a free one none (−1), the
counters agree with the options and the number of aircraft, every value is finite, the information
blocks Y_ii and the Schur complement S are positive definite, and P_ς is exactly symmetric (the update
reads its columns as rows) and positive semi-definite.
"""

from __future__ import annotations

import numpy as np

from radartracker.api import StateCheck

from ._layout import C_ALIVE, C_REBUILD_FACTOR, C_REFRESH_EVERY, C_SINCE_REBUILD, C_SINCE_REFRESH, STORE

FIELDS = ("radars", "aircraft", "free", "bias_time") + STORE
MAX_SLOTS = 1 << 24  # aircraft slots a state may claim (the storage grows by doubling from 16)
MAX_COUNT = 1 << 53  # update counters (the kernels multiply rebuild_factor by the aircraft count: no overflow)


def checked_state(state: object, radars: list[str], widths: list[int], refresh_every: int,
                  rebuild_factor: int) -> dict:
    """The fields of ``state`` (``CoupledSparseEstimator.state_dict``), checked for an estimator with
    ``radars`` (their sensor models' ``widths`` of bias entries) and these options: arrays as owned
    float64/int64 copies, ``aircraft`` {key: slot}, ``free`` slots, ``bias_time``. Raises :class:`~radartracker.api.InputError` naming the first fault."""
    c = StateCheck("coupled-sparse", state, FIELDS)
    c.names("radars", radars)
    m = len(radars)
    mm, nb = max(m, 1), sum(widths)
    cap = c.integer("the capacity (length of tx)", len(c.array("tx", (None,))), 0, MAX_SLOTS)
    out = {name: c.array(name, shape) for name, shape in (
        ("Yxx", (cap, 4, 4)), ("Yxb", (cap, 4, max(nb, 1))), ("ex", (cap, 4)), ("tx", (cap,)), ("Ybb", (nb, nb)),
        ("eb", (nb,)), ("S", (nb, nb)), ("sv", (nb,)), ("Pb", (nb, nb)), ("bh", (nb,)))}
    out["nk"], out["rk"], out["ctr"] = (c.array(n, shape, "i") for n, shape in (("nk", (cap,)), ("rk", (cap, mm)),
                                                                             ("ctr", (5,))))
    out["aircraft"], out["free"] = _slots(c, cap)
    _radar_lists(c, out["nk"], out["rk"], out["aircraft"], m)
    _counters(c, out["ctr"], len(out["aircraft"]), refresh_every, rebuild_factor)
    out["bias_time"] = c.number("bias_time", c.state["bias_time"], nan=True)
    _matrices(c, out, list(out["aircraft"].values()))
    return out


def _slots(c: StateCheck, cap: int) -> tuple[dict, list[int]]:
    """``aircraft`` {key: slot} and ``free`` [slot]: distinct slots in [0, cap) that together are all of them."""
    aircraft = c.mapping("aircraft")
    slots = {k: c.integer(f"slot of aircraft {k!r}", s, 0, cap - 1) for k, s in aircraft.items()}
    free = [c.integer("a free slot", s, 0, cap - 1) for s in c.sequence("free", max_len=cap)]
    used = list(slots.values()) + free
    if len(set(used)) != len(used):
        raise c.fail("a slot is given twice (to two aircraft, or to an aircraft and the free list)")
    if len(used) != cap:
        raise c.fail(f"{len(used)} slots are live or free, the capacity is {cap}")
    return slots, free


def _radar_lists(c: StateCheck, nk: np.ndarray, rk: np.ndarray, aircraft: dict, m: int) -> None:
    """nk[s] in [0, m] with rk[s, :nk[s]] distinct radar indices in [0, m) for a live slot; nk = −1 for a free one."""
    live = np.zeros(len(nk), bool)
    live[list(aircraft.values())] = True
    if np.any(nk[~live] != -1):
        raise c.fail(f"free slot {int(np.flatnonzero(~live & (nk != -1))[0])} has radars (nk must be -1)")
    for key, s in aircraft.items():
        k = c.integer(f"nk of aircraft {key!r}", nk[s], 0, m)
        seen = rk[s, :k]
        if np.any((seen < 0) | (seen >= m)) or len(np.unique(seen)) != k:
            raise c.fail(f"aircraft {key!r}: radar indices {seen.tolist()} are not distinct indices in [0, {m})")


def _counters(c: StateCheck, ctr: np.ndarray, alive: int, refresh_every: int, rebuild_factor: int) -> None:
    """[since refresh, refresh_every, since rebuild, rebuild_factor, alive] consistent with the options and
    the aircraft."""
    if ctr[C_REFRESH_EVERY] != refresh_every or ctr[C_REBUILD_FACTOR] != rebuild_factor:
        raise c.fail(f"counters refresh_every={ctr[C_REFRESH_EVERY]}, rebuild_factor={ctr[C_REBUILD_FACTOR]} are "
                     f"not this estimator's options ({refresh_every}, {rebuild_factor})")
    if ctr[C_ALIVE] != alive:
        raise c.fail(f"counter of live aircraft {ctr[C_ALIVE]} is not the {alive} aircraft listed")
    c.integer("updates since refresh", ctr[C_SINCE_REFRESH], 0, MAX_COUNT)
    c.integer("updates since rebuild", ctr[C_SINCE_REBUILD], 0, MAX_COUNT)


def _matrices(c: StateCheck, out: dict, live: list[int]) -> None:
    """Y_ii ≻ 0 for every live slot and S ≻ 0 (the kernels factor their lower triangles), Y_bb symmetric,
    P_ς exactly symmetric and ⪰ 0."""
    c.covariance("Ybb", out["Ybb"], definite=False)
    for what, M in [("an aircraft information block Y_ii", y) for y in out["Yxx"][live]] + [("S", out["S"])]:
        c.covariance(what, M, definite=True)
    if not np.array_equal(out["Pb"], out["Pb"].T):
        raise c.fail("Pb (the bias covariance) is not exactly symmetric")
    c.covariance("Pb (the bias covariance)", out["Pb"])
