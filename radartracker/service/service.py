"""The tracker loop: queue → decoder → TrackManager → CAT062, checkpoints, summary.

CAT062 leaves on update (the tracks a frame changed, as soon as the datagram whose records closed
that frame is processed), every period (every track), or both (``ServiceConfig.publish_mode``); the
final publication at a stop is always a full one.

One thread (the caller's) owns the manager. The :class:`~radartracker.service.receiver.Receiver`
thread only fills the bounded queue; the HTTP thread only reads the views this loop replaces whole
(:attr:`Service.view`, :attr:`Service.tracks_json`, :attr:`Service.biases_json`).

Accounting (``summary.json``, the same rule as a replay: every input used or counted under a
reason): datagrams received = dropped_queue_full + dropped_at_stop + decoded + malformed (at a stop,
what is still queued after :data:`STOP_DRAIN_S` of draining is dropped and counted); CAT048 + CAT021 records =
records_to_tracker + the per-reason rejections; records_to_tracker = the sum of the manager's
accounting (used, late, duplicate, in tentative tracks, …). A checkpoint stores these counters
together with the manager, so after a restart they continue from the checkpoint; what arrived
between the last checkpoint and a crash is in neither (docs/service.md measures it).
"""

from __future__ import annotations

import itertools
import logging
import math
import os
import queue
import shutil
import signal
import threading
import time
from collections import Counter
from pathlib import Path

import attrs
import numpy as np

from radartracker.domain import Radar
from radartracker.errors import ConfigurationError
from radartracker.settings import check_number
from radartracker.registry import make_estimator
from radartracker.service.checkpoints import checkpoints, resume, write_checkpoint, write_json_atomic
from radartracker.service.decoder import DayClock, Decoder, ReceiveClock
from radartracker.service.endpoints import Endpoint, open_receiver, open_sender
from radartracker.service.metrics import ServiceMetrics
from radartracker.service.publisher import Publisher, track_rows
from radartracker.service.receiver import DatagramQueue, Receiver
from radartracker.registry import default_estimator, make_manager
from radartracker.tracking.events import ENDS, TrackEvent
from radartracker.tracking.manager import TrackManager
log = logging.getLogger(__name__)
# seconds a stop spends on what was already received before the final checkpoint: with the checkpoint
# (~15 s of wall time for 2 000 tracks, docs/service.md) well inside systemd's 60 s stop timeout
STOP_DRAIN_S = 5.0

PUBLISH_MODES = ("update", "periodic", "both")
# The tracker's reordering window and frame for live data (a replay's are 2 s and 0.5 s), chosen by
# measurement (docs/service.md, "Reorder window and frame"): twice the largest lateness measured on
# the loopback feed, and a frame short enough for p99 latency below 1 s on national traffic.
LIVE_TRACKER = {"reorder_window_s": 0.5, "frame_s": 0.25}
_CHANGED = frozenset({"confirmed", "updated", "coasting"})  # events after which a track is sent on update


def build_manager(radars: list[Radar], estimator: str | None = None, motion_model: str | None = None,
                  manager: dict | None = None) -> TrackManager:
    """A TrackManager set up as ``radartracker replay --association manager`` sets up its own
    (:func:`radartracker.pipeline.run.run`): same settings, estimator and motion-model factory, so the
    service's tracks are the replay's; the system plane is centred on the radars' mean position.
    ``manager``: overrides of :class:`ManagerConfig` settings, as ``RunConfig.manager``."""
    from radartracker.pipeline.config import RunConfig, motion_factory, resolve

    name = estimator or default_estimator()
    # with the association named, resolve() reads nothing of the scenario
    cfg = resolve(RunConfig(association="manager", estimator=name, motion_model=motion_model, manager=manager or {}),
                  None, name)
    mcfg = cfg.manager_settings()
    est = make_estimator(name, cfg.estimator_settings(), [r.id for r in radars], cfg.estimator_options)
    ref = (float(np.mean([r.lat for r in radars])), float(np.mean([r.lon for r in radars])))
    return make_manager(radars, ref, mcfg, estimator=est, filter_factory=motion_factory(cfg))


def _within(lo: float, hi: float, integer: bool = False):
    """An attrs validator: a finite number (an integer if ``integer``) in [lo, hi], by
    :func:`~radartracker.pipeline.config.check_number`; a text or a bool is not a number here."""
    def check(inst: object, attr: attrs.Attribute, value: object) -> None:
        if isinstance(value, bool) or not isinstance(value, int if integer else (int, float)):
            raise ValueError(f"{attr.name}: {value!r} is not {'an integer' if integer else 'a number'}")
        check_number(attr.name, value, lo=lo, hi=hi, integer=integer)
    return check


def _http(inst: object, attr: attrs.Attribute, value: tuple[str, int] | None) -> None:
    if value is not None and not (len(value) == 2 and isinstance(value[1], int) and 0 <= value[1] <= 65_535):
        raise ValueError(f"http: a (host, port) with a port in [0, 65535], not {value!r}")


def _addresses(inst: object, attr: attrs.Attribute, value: tuple) -> None:
    import ipaddress

    for a in value:
        try:
            ipaddress.IPv4Address(a)
        except ValueError:
            raise ValueError(f"{attr.name}: {a!r} is not an IPv4 address") from None


@attrs.frozen
class ServiceConfig:
    """Where the service listens and publishes, and its periods (s). Every number has bounds an
    operator's typo cannot pass: a CAT062 SAC or SIC is one byte, a port two, and the periods and the
    queue's length are those of a service that can keep up (issue 33: ``--queue 10000000000`` and
    ``--checkpoint-s 1e-9`` were accepted, ``--sac 999`` failed at the first publication)."""

    listen: tuple[Endpoint, ...]
    publish: Endpoint
    state_dir: Path
    http: tuple[str, int] | None = attrs.field(default=None, validator=_http)
    period_s: float = attrs.field(default=4.0, validator=_within(0.05, 3_600.0))
    checkpoint_s: float = attrs.field(default=60.0, validator=_within(0.1, 86_400.0))
    queue_size: int = attrs.field(default=50_000, validator=_within(1, 1_000_000, integer=True))
    queue_bytes: int = attrs.field(default=256 << 20, validator=_within(1 << 16, 8 << 30, integer=True))
    day_start: float | None = None  # None: the receive clock gives the day (live data)
    sac: int = attrs.field(default=0, validator=_within(0, 255, integer=True))
    sic: int = attrs.field(default=100, validator=_within(0, 255, integer=True))
    interface: str = "0.0.0.0"  # joins the listened multicast groups and sends the published one
    # chosen by measurement: docs/service.md, "Reorder window and frame (what chose the defaults)"
    publish_mode: str = attrs.field(default="both", validator=attrs.validators.in_(PUBLISH_MODES))
    # the IPv4 addresses datagrams may come from (empty: any); others are counted datagrams_refused_sender
    allow_from: tuple[str, ...] = attrs.field(default=(), converter=tuple, validator=_addresses)


class Service:
    """A running surveillance service (see the module notes); :meth:`run` until ``stop`` is set.

    ``manager``: :class:`ManagerConfig` settings over :data:`LIVE_TRACKER` and the replay's own; on
    resume the checkpoint's hold, and naming different ones is refused."""

    def __init__(self, config: ServiceConfig, radars: list[Radar], sites: dict[tuple[int, int], str], *,
                 estimator: str | None = None, motion_model: str | None = None, manager: dict | None = None) -> None:
        self.config = config
        config.state_dir.mkdir(parents=True, exist_ok=True)
        self.base: Counter[str] = Counter()  # counters carried over from the checkpoint resumed
        self.resumed_from = None
        found, self.skipped_checkpoints = resume(config.state_dir)
        for line in self.skipped_checkpoints:
            log.error("checkpoint skipped, damaged: %s", line)
        # new checkpoints are numbered after every one there, the damaged ones included
        self.checkpoint_seq = max((n for n, _ in checkpoints(config.state_dir)), default=0)
        if found:
            _, folder, self.manager, state = found
            self._check_resume(folder, radars, estimator, motion_model, manager or {})
            self.base.update(state["counts"])
            self.resumed_from = folder.name
        else:
            self.manager = build_manager(radars, estimator, motion_model, LIVE_TRACKER | (manager or {}))
        if self.skipped_checkpoints:
            self.base["checkpoints_skipped_damaged"] += len(self.skipped_checkpoints)
        from radartracker.pipeline.config import RunConfig
        from radartracker.pipeline.warmup import warm_up

        # kernels compiled or loaded before listening: the first datagrams are not held up by them
        mc = self.manager.config
        warm_up(RunConfig(association="manager", estimator=mc.estimator, motion_model=mc.motion_model,
                          manager=LIVE_TRACKER | (manager or {})))
        self.queue: queue.Queue = DatagramQueue(config.queue_size, config.queue_bytes)
        clock = ReceiveClock() if config.day_start is None else DayClock(config.day_start)
        self.decoder = Decoder(sites, clock)
        self.sockets = {ep: open_receiver(ep, config.interface) for ep in config.listen}
        self.receiver = Receiver(self.sockets, self.queue, frozenset(config.allow_from))
        self.publisher = Publisher(open_sender(config.publish, interface=config.interface), config.sac, config.sic)
        self.publisher.remember(self.manager)
        self.checkpoints_written = 0
        self._child: int | None = None  # pid of the process writing a checkpoint, and when it started
        self._child_started = 0.0
        self.started = time.time()
        self.last_datagram: float | None = None
        self._ended: list[TrackEvent] = []  # deletions not yet published
        self._changed: set[int] = set()  # tracks changed since they were last published
        self._newest = -math.inf  # the newest record time decoded (for the lateness histogram)
        self.tracks_json: dict = {"tracks": []}
        self.biases_json: dict = {}
        self.degraded: str | None = None  # why the state folder is not being written (a full disk), if so
        self.refusing: str | None = None  # why most recent input is refused (its time stamps), if so
        self._judged = (0, 0)  # (records to the tracker, of them refused by time) at the last view
        self.view: dict = {}
        self._refresh_view()
        self.metrics = ServiceMetrics(self)
        self.http = None
        if config.http is not None:
            from radartracker.service.http import serve_http

            self.http = serve_http(self, *config.http)

    def _check_resume(self, folder: Path, radars: list[Radar], estimator: str | None, motion_model: str | None,
                      manager: dict) -> None:
        mc = self.manager.config
        differ = sorted(k for k, v in manager.items() if getattr(mc, k, None) != v)
        if differ:
            raise ConfigurationError(f"{folder}: the checkpoint's tracker settings differ in {', '.join(differ)}; "
                                     "omit them to resume, or use a new state folder")
        if {r.id: r for r in radars} != self.manager.radars:
            raise ConfigurationError(f"{folder}: the checkpoint's radars differ from --radars; "
                                     "use the same radars file or a new state folder")
        for name, given, saved in (("estimator", estimator, mc.estimator), ("motion model", motion_model, mc.motion_model)):
            if given is not None and given != saved:
                raise ConfigurationError(f"{folder}: the checkpoint was made with {name} {saved!r}, not {given!r}; "
                                         "omit the option to resume, or use a new state folder")

    # --- the loop ----------------------------------------------------------------------------------
    def run(self, stop: threading.Event) -> dict:
        """Receive, track and publish until ``stop`` is set; then drain, flush, checkpoint and
        write ``summary.json``, which is returned."""
        cfg = self.config
        self.receiver.start()
        now = time.monotonic()
        next_pub, next_ckpt, next_view = now + cfg.period_s, now + cfg.checkpoint_s, now + 0.5
        try:
            while not stop.is_set():
                self._take(block=True)
                now = time.monotonic()
                if now >= next_pub:
                    self._publish(send=cfg.publish_mode != "update")
                    next_pub = max(next_pub + cfg.period_s, now + 0.1 * cfg.period_s)
                if now >= next_ckpt:
                    self._checkpoint()
                    next_ckpt = now + cfg.checkpoint_s
                if now >= next_view:
                    self._reap()
                    self._refresh_view()
                    next_view = now + 0.5
        finally:
            self.receiver.stop()
            self.receiver.join()
            unread = self.receiver.discard_unread()  # in the sockets' buffers at the stop: counted, not lost
            if unread:
                self.base["datagrams_dropped_at_stop"] += unread
            for sock in self.sockets.values():
                sock.close()
        phases = [time.monotonic()]
        self._drain(phases[0] + STOP_DRAIN_S)
        phases.append(time.monotonic())
        # what the stream has reached; an input alone far ahead stays waiting, in the checkpoint
        self._collect(self.manager.flush(end=False))
        self._publish()  # a full publication at the stop, whatever the mode
        phases.append(time.monotonic())
        self._reap(supersede=True)
        self._checkpoint(wait=True)
        phases.append(time.monotonic())
        summary = self.summary() | {"stop_s": dict(zip(("drain", "flush_and_publish", "final_checkpoint"),
                                                        (round(b - a, 3) for a, b in itertools.pairwise(phases))))}
        self._write_state("summary.json", summary)
        if self.http is not None:
            self.http.shutdown()
            self.http.server_close()
        self.publisher.sock.close()
        return summary

    def _drain(self, deadline: float) -> None:
        """At the stop: process what was received until ``deadline`` (monotonic), then count what is
        still queued as ``datagrams_dropped_at_stop``: a flood's backlog would otherwise keep the final
        checkpoint waiting past systemd's stop timeout (issue 33: 273 s after a 40 s flood)."""
        while time.monotonic() < deadline and self._take(block=False, batch=1):  # the deadline after each datagram
            pass
        dropped = 0
        try:
            while True:
                self.queue.get_nowait()
                dropped += 1
        except queue.Empty:
            pass
        if dropped:
            self.base["datagrams_dropped_at_stop"] += dropped
            log.warning("stop: %d datagrams still queued after %.0f s of draining, dropped and counted",
                        dropped, STOP_DRAIN_S)

    def _take(self, block: bool, batch: int = 64) -> int:
        """Process up to ``batch`` queued datagrams (waiting up to 50 ms for the first if ``block``)."""
        n = 0
        try:
            entry = self.queue.get(timeout=0.05) if block else self.queue.get_nowait()
            while True:
                self._handle(*entry)
                n += 1
                if n >= batch:
                    break
                entry = self.queue.get_nowait()
        except queue.Empty:
            pass
        return n

    def _handle(self, received: float, received_mono: float, ep: Endpoint, payload: bytes) -> None:
        process, lateness = self.manager.process, self.metrics.lateness.observe
        newest = self._newest
        for item in self.decoder.decode(payload, received):
            lateness(max(0.0, newest - item.time))
            newest = max(newest, item.time)
            self._collect(process(item))
        self._newest = newest
        self.last_datagram = received
        self.metrics.latency.observe(time.monotonic() - received_mono)
        if (self._changed or self._ended) and self.config.publish_mode != "periodic":
            self._publish_changed()

    def _collect(self, events: list[TrackEvent]) -> None:
        for e in events:
            if e.kind in ENDS:
                self._ended.append(e)
                self._changed.discard(e.track)
            elif e.kind in _CHANGED:
                self._changed.add(e.track)

    # --- outputs -----------------------------------------------------------------------------------
    def _publish_changed(self) -> None:
        """On update: the tracks changed since the last publication, and the ends of published tracks."""
        self.publisher.publish(track_rows(self.manager, self._changed), self._ended, self.manager.plane, full=False)
        self._changed, self._ended = set(), []

    def _publish(self, send: bool = True) -> None:
        """Every track: sent as CAT062 if ``send`` (else only the JSON views and biases.json are renewed)."""
        rows = track_rows(self.manager)
        if send:
            self.publisher.publish(rows, self._ended, self.manager.plane)
            self._changed, self._ended = set(), []
        self.tracks_json = {"published": time.time(), "tracks": rows}
        self.biases_json = self._biases()
        self._write_state("biases.json", self.biases_json)
        self._refresh_view()

    def _write_state(self, name: str, obj: dict) -> bool:
        """Write ``obj`` as ``DIR/name``; a failure (a full disk) degrades the service instead of stopping
        it: counted (``state_writes_failed``), logged, and named on ``/health`` until a write succeeds."""
        try:
            write_json_atomic(self.config.state_dir / name, obj)
        except OSError as exc:
            self._write_failed("state_writes_failed", name, exc)
            return False
        self.degraded = None
        return True

    def _write_failed(self, counter: str, what: str, exc: OSError) -> None:
        """A write to the state folder failed: counted under ``counter``, logged once while it lasts, and
        named on ``/health`` (degraded); tracking and CAT062 go on, the next write retries."""
        self.base[counter] += 1
        if self.degraded is None:
            log.error("%s not written (%s): tracking and CAT062 go on; retried at the next write", what, exc)
        self.degraded = f"{what} not written: {exc}"

    def _biases(self) -> dict:
        mgr = self.manager
        obs = mgr.coupling.report()
        radars = {}
        for rid in mgr.estimator.radars:
            b = mgr.bias(rid)
            o = obs["radars"].get(rid, {})
            radars[rid] = {"range_bias_m": b.range_m, "sd_range_m": b.sd_range_m,
                           "azimuth_bias_deg": math.degrees(b.azimuth_rad),
                           "sd_azimuth_deg": math.degrees(b.sd_azimuth_rad), "unobservable": list(b.unobservable),
                           "observability": o.get("status"), "adsb_reference": o.get("adsb_reference"),
                           "shares_aircraft_with": o.get("shares_aircraft_with"),
                           "aircraft_now": o.get("aircraft_now")}
        return {"published": time.time(), "estimator": mgr.config.estimator, "radars": radars,
                "components": obs.get("components")}

    def _checkpoint(self, wait: bool = False) -> None:
        """Write the next checkpoint. The periodic ones are written by a forked child: it holds a
        copy-on-write image of the manager as it is now, so the loop goes on while the snapshot (seconds
        for thousands of tracks) is written; one is skipped (counted) while the previous is still being
        written. ``wait``: in this process, after the previous one (the final checkpoint)."""
        if self._reap(block=wait):
            self.checkpoint_seq += 1
            state = {"counts": dict(self._counts(False)), "written": time.time()}
            if wait or not hasattr(os, "fork"):
                try:
                    write_checkpoint(self.config.state_dir, self.checkpoint_seq, self.manager, state)
                    self.checkpoints_written += 1
                except OSError as exc:  # a full disk: the previous checkpoint stands
                    self._write_failed("checkpoints_failed", f"checkpoint {self.checkpoint_seq}", exc)
                    self.checkpoint_seq -= 1
                return
            pid = os.fork()
            if pid == 0:  # the child: write, and leave without running the parent's cleanup
                code = 1
                try:
                    write_checkpoint(self.config.state_dir, self.checkpoint_seq, self.manager, state)
                    code = 0
                finally:
                    os._exit(code)
            self._child, self._child_started = pid, time.monotonic()
        else:
            self.base["checkpoints_skipped_busy"] += 1

    def _reap(self, block: bool = False, supersede: bool = False) -> bool:
        """Collect a finished checkpoint child; True when none is running. A hung one (e.g. a lock copied by
        fork) is ended: the previous checkpoint stands. ``supersede`` (at the stop): one still being written is
        ended too rather than waited for, its ``.partial`` folder removed and counted ``checkpoints_superseded`` —
        the final checkpoint supersedes it, and under load the wait could outlast systemd's stop timeout."""
        if self._child is None:
            return True
        pid, status = os.waitpid(self._child, 0 if block else os.WNOHANG)
        hung = pid == 0 and time.monotonic() - self._child_started > max(300.0, 5 * self.config.checkpoint_s)
        superseded = pid == 0 and supersede and not hung
        if pid == 0 and (hung or supersede):
            os.kill(self._child, signal.SIGKILL)
            pid, status = os.waitpid(self._child, 0)
        if pid == 0:
            return False
        self._child = None
        if os.waitstatus_to_exitcode(status) == 0:  # a complete checkpoint (finished before any signal)
            self.checkpoints_written += 1
        elif superseded:
            self.base["checkpoints_superseded"] += 1
            shutil.rmtree(self.config.state_dir / f".checkpoint-{self.checkpoint_seq:06d}.partial", ignore_errors=True)
            log.info("stop: checkpoint %d, still being written, superseded by the final one", self.checkpoint_seq)
        else:
            self.base["checkpoints_failed"] += 1
            log.error("checkpoint %d failed (exit status %s); the previous one stands", self.checkpoint_seq, status)
        return True

    def _counts(self, live: bool) -> Counter[str]:
        """All service counters (carried-over base + this run). Not ``live``: datagrams received are
        those already processed or dropped, so the counters match the manager's state exactly."""
        c = self.base + self.decoder.counts + self.publisher.counts
        r = self.receiver.counts
        c["datagrams_dropped_queue_full"] += r["datagrams_dropped_queue_full"]
        c["datagrams_dropped_kernel"] += r["datagrams_dropped_kernel"]
        c["datagrams_refused_sender"] += r["datagrams_refused_sender"]
        if live:
            c["datagrams_received"] += r["datagrams_received"]
        else:
            c["datagrams_received"] = (c["datagrams_decoded"] + c["datagrams_malformed"] + c["datagrams_refused_sender"]
                                       + c["datagrams_dropped_queue_full"] + c["datagrams_dropped_at_stop"])
        return c

    def _judge_input(self) -> None:
        """Set :attr:`refusing` when more than half the records the tracker judged since the last view were
        refused for their time stamps (ahead of the stream clock, or behind the reordering horizon): a feed
        the tracker cannot follow shows on ``/health`` while it lasts, not only in the counters."""
        seen = self.decoder.counts["records_to_tracker"]
        refused = sum(v for k, v in self.manager.counts.items() if k.endswith(("_time_jump", "_late")))
        n, r = seen - self._judged[0], refused - self._judged[1]
        self._judged = (seen, refused)
        if n > 0:
            self.refusing = (f"input refused: {r} of the last {n} records had time stamps ahead of the stream "
                             "clock or behind the reordering horizon") if 2 * r > n else None

    def _refresh_view(self) -> None:
        self._judge_input()
        c = self._counts(True)
        groups: dict[str, dict] = {"datagrams": {}, "blocks": {}, "records": {}, "published": {},
                                   "checkpoints": {"written": self.checkpoints_written}}
        for k, v in c.items():
            if k.startswith("checkpoints_"):
                groups["checkpoints"][k.removeprefix("checkpoints_")] = v
            elif k.startswith("datagrams_"):
                groups["datagrams"][k.removeprefix("datagrams_")] = v
            elif k.startswith("blocks_"):
                groups["blocks"][k.removeprefix("blocks_")] = v
            elif k.startswith(("cat062_", "publications")):
                groups["published"][k.removeprefix("cat062_")] = v
            else:
                groups["records"][k] = v
        statuses = Counter(t.status for t in self.manager.tracks.values())
        self.view = groups | {"tracker": self.manager.accounting(),
                              "tracks_by_status": {s: statuses.get(s, 0) for s in ("tentative", "confirmed", "coasting")}}

    def health(self) -> dict:
        """``/health``: alive, how long since the last datagram, queue depth, tracks."""
        now = time.time()
        reasons = [r for r in (self.degraded, self.refusing) if r]
        degraded = {"status": "degraded", "reason": "; ".join(reasons)} if reasons else {"status": "ok"}
        return degraded | {"uptime_s": now - self.started,
                           "last_datagram_age_s": None if self.last_datagram is None else now - self.last_datagram,
                           "queue_depth": self.queue.qsize(), "datagrams": self.view["datagrams"],
                           "tracks": self.view["tracks_by_status"],
                           "checkpoints_written": self.checkpoints_written, "resumed_from": self.resumed_from}

    def summary(self) -> dict:
        """The run's accounting (module notes), estimator, final biases and checkpoints."""
        self._refresh_view()
        mc = self.manager.config
        return self.view | {"track_counts": self.manager.track_counts(),
                            "estimator": mc.estimator, "motion_model": mc.motion_model,
                            "tracker_settings": {"reorder_window_s": mc.reorder_window_s, "frame_s": mc.frame_s},
                            "started": self.started, "stopped": time.time(), "resumed_from": self.resumed_from,
                            "last_checkpoint": f"checkpoint-{self.checkpoint_seq:06d}",
                            "last_publication_records": self.publisher.last_records, "biases": self.biases_json}
