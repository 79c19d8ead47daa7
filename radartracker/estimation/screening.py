"""Innovation screening: a measurement must agree with its aircraft before it may touch a filter or a bias.

For measurement z of aircraft i (bias Jacobian C, noise R; C = 0 for ADS-B and other unbiased
positions), the aircraft's prediction to the measurement time (p̄, P̄_pp) and the radar's bias
estimate (ς̂, P_ς)::

    ν = z − p̄ − C ς̂,   S = P̄_pp + C P_ς Cᵀ + R,   d² = νᵀ S⁻¹ ν   (χ²₂ when the model holds)

A measurement with d² above its kind's gate is rejected and counted (``plots_outlier``,
``adsb_outlier``, ``positions_outlier``); it changes neither the track nor the estimator. The gates
(defaults in :class:`ScreeningConfig`) were chosen from the d² of clean simulated streams and the
gross errors of scripts/fault_injection.py: see docs/reliability.md, section "Gross errors".

``reinit_after`` consecutive rejections of one identified aircraft (Mode S address, ADS-B address,
labelled key) that agree with each other (:func:`extend_run`) mean the track, not the measurements,
is wrong — it started on a wild measurement or a swapped address: the track is re-initialised from
the newest measurement instead of being frozen.

A new track has a diffuse prior, so its first measurement passes trivially. A wild *first*
measurement is handled so: in the TrackManager a track reaches the bias estimator only when
confirmed, and its M-of-N hits are screened measurements — a wild start rejects the aircraft's
good measurements (the second one is judged with the start's position and the diffuse velocity
prior, i.e. an implied-speed test) and is re-initialised after ``reinit_after`` of them, its wild
measurement dropped with the tentative track before it reached the estimator. On the labelled path
(:class:`LabelledScreen`) the estimator holds the aircraft from its first measurement with a wide
prior centred on it: the wild start lands in the aircraft state, not the biases (the prior
variance, ~10⁸ m², dwarfs the bias variance, so the bias gain on the next innovation is ~P_ς/10⁸),
the following good measurements disagree with the state fitted through it and after
``reinit_after`` rejections the aircraft is started again from a good one.

ADS-B must also be plausible before it may anchor a bias (:class:`AdsbPlausibility`): NACp at or
above a floor (the report carries no NIC in this domain model), and an implied speed from the last
accepted report of the same address below ``adsb_max_speed_mps``. Its consistency with the radars
that see the aircraft is the innovation test above against the track they feed.
"""

from __future__ import annotations

import math
from collections.abc import Hashable

import attrs
import numpy as np
from numba import njit

from radartracker.estimation.base import Estimator, PlaneMeasurement

ACCEPT, REJECT, REINIT = "accept", "reject", "reinit"


@attrs.frozen
class ScreeningConfig:
    """Gates (on d², χ²₂-distributed for good measurements) and plausibility limits.

    ``gate_*`` per measurement kind — 600, about twice the largest d² of a good measurement in clean
    runs of the built-in scenarios (309: a 3°/s turn under the CV model; 28 under IMM) and a third of
    the smallest d² of a gross error (1 805: a +20 km range error); ``gate_tentative`` for a
    tentative track, χ²₂'s 99.99 % quantile: its prediction is its diffuse start (no model mismatch
    has built up yet), so the second measurement meets an implied-speed test of about
    √18.4 × ``prior_sd_velocity_mps`` (1 300 m/s with 300 m/s) and a wild one cannot confirm it;
    ``reinit_after`` consecutive, mutually consistent rejections re-initialise an identified
    aircraft's track; ``adsb_min_nacp`` is the lowest NACp that may be used; ``adsb_max_speed_mps``
    the fastest implied speed between reports of one address, allowing
    ``speed_sigmas`` standard deviations of the two positions' noise on top.
    """

    enabled: bool = True
    gate_plots: float = attrs.field(default=600.0, validator=attrs.validators.gt(0.0))
    gate_adsb: float = attrs.field(default=600.0, validator=attrs.validators.gt(0.0))
    gate_positions: float = attrs.field(default=600.0, validator=attrs.validators.gt(0.0))
    gate_tentative: float = attrs.field(default=18.42, validator=attrs.validators.gt(0.0))
    reinit_after: int = attrs.field(default=3, validator=attrs.validators.ge(1))
    adsb_min_nacp: int = attrs.field(default=5, validator=attrs.validators.in_(range(1, 12)))
    adsb_max_speed_mps: float = attrs.field(default=600.0, validator=attrs.validators.gt(0.0))
    speed_sigmas: float = attrs.field(default=5.0, validator=attrs.validators.gt(0.0))

    def gate(self, kind: str, tentative: bool = False) -> float:
        """The d² gate of a measurement of ``kind`` ("plots", "adsb", "positions") of a (tentative) track."""
        if tentative:
            return self.gate_tentative
        if kind == "plots":
            return self.gate_plots
        if kind == "adsb":
            return self.gate_adsb
        if kind == "positions":
            return self.gate_positions
        raise KeyError(kind)


def normalised_innovation(z: np.ndarray, C: np.ndarray, R: np.ndarray, bias: np.ndarray, bias_cov: np.ndarray,
                          pos: np.ndarray, pos_cov: np.ndarray) -> float:
    """d² = νᵀ S⁻¹ ν with ν = z − p̄ − C ς̂ and S = P̄_pp + C P_ς Cᵀ + R (∞ if S is not positive definite).

    S is 2×2: its inverse is written out (d² = (S₁₁ν₀² − 2 S₀₁ν₀ν₁ + S₀₀ν₁²) / det S), compiled
    (:func:`_innovation_d2`): one call per measurement instead of a dozen small numpy operations, each
    with its own dispatch and temporary array.
    """
    return _innovation_d2(np.asarray(z, float), C, R, bias, bias_cov, pos, pos_cov)


@njit(cache=True)
def _innovation_d2(z: np.ndarray, C: np.ndarray, R: np.ndarray, bias: np.ndarray, bias_cov: np.ndarray,
                   pos: np.ndarray, pos_cov: np.ndarray) -> float:
    n0 = (z[0] - pos[0]) - (C[0, 0] * bias[0] + C[0, 1] * bias[1])
    n1 = (z[1] - pos[1]) - (C[1, 0] * bias[0] + C[1, 1] * bias[1])
    S = np.empty((2, 2))
    for i in range(2):
        m0 = C[i, 0] * bias_cov[0, 0] + C[i, 1] * bias_cov[1, 0]  # (C P_ς) row i
        m1 = C[i, 0] * bias_cov[0, 1] + C[i, 1] * bias_cov[1, 1]
        for j in range(2):
            S[i, j] = (pos_cov[i, j] + (m0 * C[j, 0] + m1 * C[j, 1])) + R[i, j]
    return _d2(n0, n1, S[0, 0], S[1, 1], 0.5 * (S[0, 1] + S[1, 0]))


@njit(cache=True)
def position_d2(z: np.ndarray, R: np.ndarray, pos: np.ndarray, pos_cov: np.ndarray) -> float:
    """d² of an unbiased (or already bias-corrected) position: :func:`normalised_innovation` with C = 0,
    the same operations (the zero terms added as 0.0, so the results are equal bit for bit)."""
    n0 = (z[0] - pos[0]) - 0.0
    n1 = (z[1] - pos[1]) - 0.0
    s01 = ((pos_cov[0, 1] + 0.0) + R[0, 1])
    s10 = ((pos_cov[1, 0] + 0.0) + R[1, 0])
    return _d2(n0, n1, (pos_cov[0, 0] + 0.0) + R[0, 0], (pos_cov[1, 1] + 0.0) + R[1, 1], 0.5 * (s01 + s10))


@njit(cache=True)
def _d2(n0: float, n1: float, s00: float, s11: float, s01: float) -> float:
    """νᵀ S⁻¹ ν for symmetric 2×2 S (∞ unless positive definite and finite)."""
    det = s00 * s11 - s01 * s01
    if not (s00 > 0.0 and det > 0.0):
        return math.inf
    d2 = (s11 * n0 * n0 - 2.0 * s01 * n0 * n1 + s00 * n1 * n1) / det
    return d2 if math.isfinite(d2) else math.inf


@njit(cache=True)
def bias_corrected(z: np.ndarray, C: np.ndarray, R: np.ndarray, bias: np.ndarray,
                   bias_cov: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(z − C ς̂, R + C P_ς Cᵀ): a radar measurement corrected by its radar's bias estimate (compiled)."""
    zc = np.empty(2)
    Rc = np.empty((2, 2))
    bias_correct_into(z, C, R, bias, bias_cov, zc, Rc)
    return zc, Rc


@njit(cache=True)
def bias_correct_into(z: np.ndarray, C: np.ndarray, R: np.ndarray, bias: np.ndarray, bias_cov: np.ndarray,
                      zc: np.ndarray, Rc: np.ndarray) -> None:
    """:func:`bias_corrected` written into ``zc`` and ``Rc``."""
    for i in range(2):
        zc[i] = z[i] - (C[i, 0] * bias[0] + C[i, 1] * bias[1])
        m0 = C[i, 0] * bias_cov[0, 0] + C[i, 1] * bias_cov[1, 0]
        m1 = C[i, 0] * bias_cov[0, 1] + C[i, 1] * bias_cov[1, 1]
        for j in range(2):
            Rc[i, j] = R[i, j] + (m0 * C[j, 0] + m1 * C[j, 1])


Rejected = list[tuple[float, np.ndarray, float]]  # (time, position, σ) of consecutive rejected measurements


def judge(config: ScreeningConfig, kind: str, d2: float, run: Rejected, identified: bool, tentative: bool,
          time: float, z: np.ndarray, R: np.ndarray) -> tuple[str, Rejected]:
    """(verdict, the aircraft's run of rejections after it) for a measurement (z, R at ``time``).

    ACCEPT when d² ≤ the gate (``gate_tentative`` for a tentative track), which ends the run; else
    the measurement joins the run (:func:`extend_run`), and REINIT when that makes
    ``reinit_after`` consecutive, mutually consistent rejections of an identified aircraft (the run
    ends), else REJECT.
    """
    if d2 <= config.gate(kind, tentative):
        return ACCEPT, []
    run = extend_run(config, run, time, z, R)
    if identified and len(run) >= config.reinit_after:
        return REINIT, []
    return REJECT, run


def extend_run(config: ScreeningConfig, run: Rejected, time: float, z: np.ndarray, R: np.ndarray) -> Rejected:
    """The run of consecutive rejections with this measurement added — restarted at it when it
    disagrees with the previous one (:func:`speed_consistent`, σ = √ of R's largest eigenvalue).

    Only a run of measurements that agree with each other says the *track* is wrong; scattered
    gross errors between good measurements never make such a run, so they never re-initialise it.
    """
    half_trace, det = 0.5 * float(R[0, 0] + R[1, 1]), float(R[0, 0] * R[1, 1] - R[0, 1] * R[1, 0])
    sd = math.sqrt(max(half_trace + math.sqrt(max(half_trace * half_trace - det, 0.0)), 0.0))
    if run and not speed_consistent(config, time - run[-1][0], run[-1][1], run[-1][2], z, sd):
        run = []
    keep = config.reinit_after - 1  # the run never needs more than reinit_after entries
    return [*run[len(run) - keep:], (time, np.asarray(z, float), sd)] if keep else [(time, np.asarray(z, float), sd)]


def speed_consistent(config: ScreeningConfig, dt: float, a: np.ndarray, sd_a: float, b: np.ndarray,
                     sd_b: float) -> bool:
    """Two positions of one aircraft ``dt`` s apart agree: ‖b − a‖ ≤ v_max·|dt| + k·√(σ_a² + σ_b²)."""
    allowance = config.adsb_max_speed_mps * abs(dt) + config.speed_sigmas * math.hypot(sd_a, sd_b)
    (ax, ay), (bx, by) = a, b
    dx, dy = float(bx) - float(ax), float(by) - float(ay)
    d = math.hypot(dx, dy)  # within an ulp or two of numpy's (C library) hypot, which decides near the limit
    if abs(d - allowance) <= 1e-15 * d:
        d = float(np.hypot(dx, dy))
    return d <= allowance


_ADDRESSES_KEPT = 20_000  # AdsbPlausibility forgets addresses silent for an hour when it holds more


class AdsbPlausibility:
    """NACp floor and implied speed from the last accepted report of the same address.

    A report failing the speed test is counted and not used, and the reference stays the last
    accepted report — so a single wild report costs only itself. If ``reinit_after`` reports in a
    row fail but agree with each other (:func:`extend_run`), the reference was the wild one: the
    newest report becomes the reference and is used.
    """

    def __init__(self, config: ScreeningConfig) -> None:
        self.config = config
        self._last: dict[str, tuple[float, float, float, float]] = {}  # (time, x, y, σ) by address
        self._fails: dict[str, Rejected] = {}
        self._limits = config.adsb_min_nacp, config.adsb_max_speed_mps, config.speed_sigmas  # per call, unpacked

    def check(self, icao24: str, time: float, xy: np.ndarray, sd: float, nacp: int) -> str | None:
        """``None`` if the report may be used, else the counter it is rejected under."""
        min_nacp, v_max, sigmas = self._limits
        if nacp < min_nacp:
            return "adsb_low_nacp"
        x, y = xy.tolist() if type(xy) is np.ndarray else (float(xy[0]), float(xy[1]))
        last = self._last.get(icao24)
        if last is not None:  # speed_consistent(config, time - t0, (x0, y0), sd0, (x, y), sd) written out
            t0, x0, y0, sd0 = last
            allowance = v_max * abs(time - t0) + sigmas * math.hypot(sd0, sd)
            d = math.hypot(x - x0, y - y0)
            if abs(d - allowance) <= 1e-15 * d:
                d = float(np.hypot(x - x0, y - y0))
            if not d <= allowance:
                run = extend_run(self.config, self._fails.get(icao24, []), time, xy, np.eye(2) * sd * sd)
                if len(run) < self.config.reinit_after:
                    self._fails[icao24] = run
                    return "adsb_implausible_speed"
        if self._fails:
            self._fails.pop(icao24, None)
        self._last[icao24] = (time, x, y, sd)
        if len(self._last) > _ADDRESSES_KEPT:  # forget addresses silent for an hour
            self._last = {k: v for k, v in self._last.items() if time - v[0] < 3600.0}
            self._fails = {k: v for k, v in self._fails.items() if k in self._last}
        return None

    def state_dict(self) -> dict:
        """The state as plain values (for TrackManager snapshots)."""
        def plain(entry: tuple) -> list:
            return [entry[0], [float(v) for v in entry[1]], entry[2]]

        return {"last": {k: [t, [float(x), float(y)], sd] for k, (t, x, y, sd) in self._last.items()},
                "fails": {k: [plain(e) for e in run] for k, run in self._fails.items()}}

    def load_state_dict(self, state: dict) -> None:
        def typed(entry: list) -> tuple[float, np.ndarray, float]:
            return float(entry[0]), np.array(entry[1], float), float(entry[2])

        self._last = {k: (float(v[0]), float(v[1][0]), float(v[1][1]), float(v[2])) for k, v in state["last"].items()}
        self._fails = {k: [typed(e) for e in run] for k, run in state["fails"].items()}


class LabelledScreen:
    """Screening for the labelled replay, where the estimator is the only model of each aircraft.

    A measurement of a known aircraft is tested against the estimator's own prediction
    (:meth:`Estimator.predict`) and the radar's bias (S as in the module docstring), with
    ``reinit_after`` consecutive rejections asking for the aircraft to be started again.
    """

    def __init__(self, config: ScreeningConfig) -> None:
        self.config = config
        self.adsb = AdsbPlausibility(config)
        self._runs: dict[Hashable, Rejected] = {}

    def screen(self, est: Estimator, m: PlaneMeasurement, kind: str) -> str:
        """ACCEPT, REJECT or REINIT for measurement ``m`` of aircraft ``m.aircraft`` (known to ``est``)."""
        pred = est.predict(m.aircraft, m.time)
        if m.radar is not None:
            b = est.bias(m.radar)
            bias, bias_cov = b.bias, b.cov
        else:
            bias, bias_cov = np.zeros(2), np.zeros((2, 2))
        d2 = normalised_innovation(m.z, m.C, m.R, bias, bias_cov, pred.state[:2], pred.cov[:2, :2])
        verdict, run = judge(self.config, kind, d2, self._runs.pop(m.aircraft, []), True, False, m.time,
                             m.z - m.C @ bias, m.R)
        if run:
            self._runs[m.aircraft] = run
        return verdict

    def forget(self, key: Hashable) -> None:
        """Aircraft ``key`` left the estimator."""
        self._runs.pop(key, None)


