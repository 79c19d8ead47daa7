"""The manager's track: an aircraft's estimate (its own filter), identity, status and detection history."""

from __future__ import annotations

import math
import struct
from collections import deque
from typing import NamedTuple

import attrs
import numpy as np

from radartracker.domain import Aircraft, AdsbReport, Plot
from radartracker.estimation.base import PlaneMeasurement
from radartracker.tracking.association import ADSB_ALTITUDE_VAR, MODE_C_VAR, AltitudeTrack
from radartracker.tracking.filters import TrackFilter
from radartracker.tracking.height import HeightFilter

TRACK_STATUSES = ("tentative", "confirmed", "coasting", "deleted")
NO_COVARIANCE = np.full(16, np.nan).tobytes()  # the bytes of an unknown 4×4 covariance: 16 NaNs
MODE_C_SD, ADSB_ALTITUDE_SD = math.sqrt(MODE_C_VAR), math.sqrt(ADSB_ALTITUDE_VAR)  # a reported altitude's σ (m)
_ROW = struct.Struct("=5d")  # (t, x, y, vx, vy) as 5 native float64


class Pending(NamedTuple):
    """A tentative track's measurement, held for the bias estimator until the track is confirmed."""

    measurement: PlaneMeasurement
    kind: str  # "plots", "adsb" or "positions"


@attrs.define(eq=False, on_setattr=attrs.setters.NO_OP)  # checked when made; set on every measurement after
class Track:
    """One track of the TrackManager.

    ``filter`` (a motion-model plugin) holds the kinematic estimate χ = [x, y, vx, vy] and P; the track
    adds what the manager decides with: ``status`` (one of ``TRACK_STATUSES``), the identity its
    measurements carried (Mode S address, Mode 3/A code, truth label ``target`` in simulations), its altitude
    ``altitude_m`` (the last reported, Mode C or ADS-B, with the Mode C vertical filter for gating; or, for a
    track whose plots carry none, its ``height`` filter's estimate once observable:
    :mod:`radartracker.tracking.height`) and ``altitude_sd_m`` its σ (a reported altitude's quantisation, 100 ft
    Mode C or 25 ft ADS-B, as a uniform error: step/√12; an estimated height's filter σ_h), ``detections`` (hit or miss of the last N
    opportunities, for M-of-N confirmation), ``pending`` measurements of a tentative track, and the run of
    consecutive screening rejections ``rejected`` (:func:`radartracker.estimation.screening.judge`).
    """

    id: int
    filter: TrackFilter
    status: str = attrs.field(validator=attrs.validators.in_(TRACK_STATUSES))
    created: float
    last_update: float
    mode_s: str | None = None
    mode_3a: str | None = None
    target: object = None
    altitude_m: float | None = None
    altitude_sd_m: float | None = None
    detections: deque = attrs.field(factory=deque)
    pending: list[Pending] = attrs.field(factory=list)
    n_plots: int = 0
    n_adsb: int = 0
    rejected: list = attrs.field(factory=list)
    vertical: AltitudeTrack | None = None
    height: HeightFilter | None = None
    _estimate: tuple | None = attrs.field(default=None, repr=False)

    @property
    def aircraft(self) -> Aircraft | None:
        """The aircraft identity the track carries (known by its Mode S address), else None."""
        return None if self.mode_s is None else Aircraft(self.mode_s, mode_3a=self.mode_3a)

    @property
    def reported_altitude_m(self) -> float | None:
        """The last altitude the track's measurements reported (None: none, or only an estimated height)."""
        return self.altitude_m if self.height is None else None

    @property
    def live(self) -> bool:
        return self.status in ("confirmed", "coasting")

    def estimate(self) -> tuple[float, np.ndarray, np.ndarray]:
        """The filter's (time, χ, P): float arrays χ (4,) and P (4×4) (the motion-model contract), read
        once after each change of the filter."""
        return (self._estimate or self._read())[:3]

    def _read(self) -> tuple:
        """(t, χ, P, (t, x, y, vx, vy), the bytes of that row) of the filter, kept until :meth:`changed`."""
        t, x, P = self.filter.estimate()
        row = (t, *x.tolist())
        e = self._estimate = (t, x, P, row, _ROW.pack(*row))
        return e

    @property
    def epoch(self) -> float:
        """The time of the estimate."""
        return (self._estimate or self._read())[0]

    def estimate_bytes(self) -> bytes:
        """(t, x, y, vx, vy) of the estimate as the bytes of five float64 (a frame joins every track's into one
        array)."""
        return (self._estimate or self._read())[4]

    def changed(self) -> None:
        """The filter changed: :meth:`estimate` reads it again."""
        self._estimate = None

    def covariance_bytes(self, time: float) -> bytes:
        """The bytes of the estimate's covariance P (16 float64) if the estimate is at ``time``, else 16 NaNs."""
        t, _, P, _, _ = self._estimate or self._read()
        return P.tobytes() if t == time else NO_COVARIANCE

    def state_at(self, time: float) -> tuple[float, float, float, float]:
        """[x, y, vx, vy] at ``time``, extrapolated in a straight line from the estimate (never backwards)."""
        t0, x0, y0, vx, vy = (self._estimate or self._read())[3]
        if not time > t0:
            return x0, y0, vx, vy
        dt = time - t0
        return x0 + vx * dt, y0 + vy * dt, vx, vy

    def took(self, src: Plot | AdsbReport | PlaneMeasurement, kind: str) -> None:
        """The track used measurement ``src`` of ``kind``: its last update, counts, Mode 3/A code, altitude
        with its vertical filter, and a detection in its history."""
        self.last_update = src.time
        if kind == "plots":
            self.n_plots += 1
            self.mode_3a = src.mode_3a or self.mode_3a
            h = src.altitude_m
            if h is not None:
                self.altitude_m, self.altitude_sd_m = h, MODE_C_SD
                if self.vertical is None:
                    self.vertical = AltitudeTrack.start(src.time, h)
                else:
                    self.vertical.update(src.time, h)
        elif kind == "adsb":
            self.n_adsb += 1
            if src.altitude_m is not None:
                self.altitude_m, self.altitude_sd_m = src.altitude_m, ADSB_ALTITUDE_SD
        self.detections.append(True)

    def take_over(self, new: Track) -> None:
        """This track lost its aircraft and ``new``, a younger track, found it: this track number goes on
        with ``new``'s filter, detections, held measurements, vertical and height filters (identity kept,
        completed by ``new``'s)."""
        reported = self.reported_altitude_m
        self.filter, self.detections, self.vertical, self.pending = new.filter, new.detections, new.vertical, new.pending
        self.last_update, self.rejected, self.height = new.last_update, [], new.height
        if new.altitude_m is not None or new.height is not None:
            self.altitude_m, self.altitude_sd_m = new.altitude_m, new.altitude_sd_m
        elif reported is None:
            self.altitude_m = self.altitude_sd_m = None
        self.mode_s, self.mode_3a = self.mode_s or new.mode_s, new.mode_3a or self.mode_3a
        self.n_plots += new.n_plots
        self.n_adsb += new.n_adsb
        new.pending = []
        self.changed()

    def missed(self) -> None:
        """An antenna swept the track without a plot for it."""
        self.detections.append(False)

    def hopeless(self, confirm_m: int, confirm_n: int) -> bool:
        """A tentative track that can no longer make ``confirm_m`` hits out of ``confirm_n``."""
        misses = len(self.detections) - sum(self.detections)
        return self.status == "tentative" and misses > confirm_n - confirm_m
