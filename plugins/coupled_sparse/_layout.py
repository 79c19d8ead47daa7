"""Storage layout of the sparse information-form coupled filter (see the package docstring).

Radar j's bias block ς_j (its sensor model's m_j = 2 to 4 components) is entries ``rt[j, 0]`` …
``rt[j, 0] + rt[j, 1] − 1`` of the bias vector; ``rt[j, 2]`` and ``rt[j, 3]`` are the positions of its range
gain and time offset in the block (−1: none). For aircraft slot ``s`` with ``nk[s]`` observing radars
``rk[s, :nk[s]]`` (``nk[s] = −1``: a free slot): ``Yxx[s]`` = Y_ii (4×4), ``Yxb[s]`` = Y_ib, the blocks of
those radars side by side in that order (radar c's m columns after the m's of radars 0 … c−1; the bias
positions of the columns are :func:`~._linalg.bias_index`), ``ex[s]`` = η_i and ``tx[s]`` the aircraft's
epoch. Global: ``Ybb``, ``eb`` (bias information, including what removed aircraft taught), the Schur
complement ``S`` = Y_bb − Σ_i Y_bi Y_ii⁻¹ Y_ib and ``sv`` = η_b − Σ_i Y_bi Y_ii⁻¹ η_i kept incrementally, and
the bias marginal ``Pb`` = S⁻¹, ``bh`` = S⁻¹ sv kept by rank-2 updates and reset from S every
``refresh_every`` updates.

Every array is a view into one float buffer ``F`` and one int buffer ``I`` whose first three entries are
the dimensions (capacity, radar columns, bias entries), so the compiled update takes a few arguments;
:func:`carve` is the one layout. The kernels' scratch is carved the same way from ``WF``
(:func:`carve_work`).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from radartracker.api import SensorModel

OK = 0
ERR_NONFINITE = 1  # z, C, R or dt not finite
ERR_R = 2  # R not positive definite (the information form needs R⁻¹)
ERR_YII = 3  # an aircraft's information block Y_ii not positive definite
ERR_LAMBDA = 4  # innovation covariance Λ not positive definite
ERR_S = 5  # bias Schur complement S not positive definite
ERR_REBUILD = 6  # recomputing S from the blocks met an aircraft whose Y_ii is not positive definite

# ctr: [updates since refresh, refresh_every, updates since rebuild, rebuild_factor, n alive]
C_SINCE_REFRESH, C_REFRESH_EVERY, C_SINCE_REBUILD, C_REBUILD_FACTOR, C_ALIVE = range(5)

# the estimator's arrays in the order carve() returns them (before its scratch ``idx``)
STORE = ("Yxx", "Yxb", "ex", "tx", "Ybb", "eb", "S", "sv", "Pb", "bh", "nk", "rk", "ctr")


def storage_sizes(cap: int, mm: int, nb: int) -> tuple[int, int]:
    """Lengths of the float and int buffers for ``cap`` aircraft slots, ``mm`` radar columns, ``nb`` biases."""
    nbx = max(nb, 1)
    return cap * (16 + 4 * nbx + 4 + 1) + 3 * nb * nb + 3 * nb, 3 + cap * (1 + mm) + 5 + 4 * mm + nbx


@njit(cache=True)
def carve(F, I):
    """(Yxx, Yxb, ex, tx, Ybb, eb, S, sv, Pb, bh, nk, rk, ctr, rt, idx) as views into F and I, whose I[:3]
    holds (cap, mm, nb); rt the radars' blocks (module docstring), idx the kernels' scratch of bias positions."""
    cap, mm, nb = I[0], I[1], I[2]
    nbx = max(nb, 1)
    o = 0
    Yxx = F[o:o + cap * 16].reshape((cap, 4, 4))
    o += cap * 16
    Yxb = F[o:o + cap * 4 * nbx].reshape((cap, 4, nbx))
    o += cap * 4 * nbx
    ex = F[o:o + cap * 4].reshape((cap, 4))
    o += cap * 4
    tx = F[o:o + cap]
    o += cap
    Ybb = F[o:o + nb * nb].reshape((nb, nb))
    o += nb * nb
    eb = F[o:o + nb]
    o += nb
    S = F[o:o + nb * nb].reshape((nb, nb))
    o += nb * nb
    sv = F[o:o + nb]
    o += nb
    Pb = F[o:o + nb * nb].reshape((nb, nb))
    o += nb * nb
    bh = F[o:o + nb]
    o = 3
    nk = I[o:o + cap]
    o += cap
    rk = I[o:o + cap * mm].reshape((cap, mm))
    o += cap * mm
    ctr = I[o:o + 5]
    o += 5
    rt = I[o:o + 4 * mm].reshape((mm, 4))
    o += 4 * mm
    idx = I[o:o + nbx]
    return Yxx, Yxb, ex, tx, Ybb, eb, S, sv, Pb, bh, nk, rk, ctr, rt, idx


def work_size(nbw: int) -> int:
    """Length of the scratch buffer for ``nbw`` bias entries (:func:`carve_work`)."""
    return 16 * 16 + 3 * 4 * nbw + 24 + 2 * nbw + 2 * nbw * nbw + 8


@njit(cache=True)
def carve_work(WF, nbw):
    """Scratch (f4, V, G, W, v4, Kb, LS, LSi, io) as views into WF; io = [ν (2), Λ (4), NIS, q] of
    :func:`~._kernels.update_packed`."""
    f4 = WF[0:256].reshape((16, 4, 4))  # 4×4 scratch: [0:7] predict, [3:16] update_one
    o = 256
    V = WF[o:o + 4 * nbw].reshape((4, nbw))
    o += 4 * nbw
    G = WF[o:o + 4 * nbw].reshape((4, nbw))
    o += 4 * nbw
    W = WF[o:o + 4 * nbw].reshape((4, nbw))
    o += 4 * nbw
    v4 = WF[o:o + 24].reshape((6, 4, 1))
    o += 24
    Kb = WF[o:o + 2 * nbw].reshape((2, nbw))  # rows: the two columns of K_b, each contiguous
    o += 2 * nbw
    LS = WF[o:o + nbw * nbw].reshape((nbw, nbw))
    o += nbw * nbw
    LSi = WF[o:o + nbw * nbw].reshape((nbw, nbw))
    o += nbw * nbw
    io = WF[o:o + 8]
    return f4, V, G, W, v4, Kb, LS, LSi, io


def radar_table(models: list[SensorModel]) -> np.ndarray:
    """``rt`` (module docstring) of radars with these sensor models, in their order in the bias vector."""
    rt = np.full((max(len(models), 1), 4), -1, np.int64)
    offset = 0
    for j, model in enumerate(models):
        rt[j, :2] = offset, model.size
        for col, name in ((2, "range_gain"), (3, "time_offset")):
            if name in model.names:
                rt[j, col] = model.index(name)
        offset += model.size
    return rt


def allocate(cap: int, models: list[SensorModel], q: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Zeroed buffers (F, I, WF) for ``cap`` aircraft slots and radars with these sensor ``models`` (every
    slot free, ``rt`` filled), and the process-noise density ``q`` stored in the scratch's ``io``."""
    mm, nb = max(len(models), 1), sum(model.size for model in models)
    nf, ni = storage_sizes(cap, mm, nb)
    F, I = np.zeros(nf), np.zeros(ni, np.int64)
    I[:3] = cap, mm, nb
    st = carve(F, I)
    st[10][:] = -1
    st[13][:] = radar_table(models)
    WF = np.zeros(work_size(max(nb, 1)))
    carve_work(WF, max(nb, 1))[8][7] = q
    return F, I, WF
