"""Seeded fuzzing of every reader in child processes: inputs, tracebacks, signals and hangs per reader.

Each reader gets mutated copies of a small valid input (:mod:`tests.fuzz.mutations`: 1–4 byte edits) and
must read it (every row a domain object) or refuse it with a RadarTrackerError (:func:`works_or_refuses`).
Inputs run in batches in a child process (``multiprocessing``, fork) so that a crash is seen: a child that
dies by a signal counts one ``signal`` and the batch goes on after that input; an input that takes more
than :data:`HANG_S` seconds is a ``hang`` (the child's alarm interrupts it); any other exception is a
``traceback`` (its first lines kept). ``python scripts/fuzz_table.py`` prints the table of
docs/reliability.md.
"""

from __future__ import annotations

import multiprocessing as mp
import random
import signal
import tempfile
import traceback
from collections import Counter
from collections.abc import Callable
from pathlib import Path

HANG_S = 10.0
BATCH = 500


class _Hang(Exception):
    pass


def _alarm(signum, frame):
    raise _Hang()


def _inputs(work: Path) -> dict[str, tuple[bytes, Callable[[Path, random.Random], object], str]]:
    """reader name -> (valid bytes, read(path, rng), file name) over small valid inputs made in ``work``."""
    import numpy as np

    from radartracker.io.asterix import write_asterix
    from radartracker.io.asterix_reader import read_asterix
    from radartracker.io.limits import read_json
    from radartracker.io.recording import TrackPoints, read_new4, read_plt, write_new4, write_plt
    from radartracker.io.scenario import read_scenario, write_scenario
    from radartracker.pipeline.config import RunConfig, read_config
    from radartracker.simulation.scenarios import build_scenario
    from radartracker_plugins.triangulation import io as tio
    from tests.fuzz.mutations import scenario_items
    from tests.plugins.test_triangulation_cli import _rows, _write_bearings, _write_stations

    data = build_scenario("demo", seed=3, duration=8.0).run()
    write_scenario(work / "scen", data)
    write_scenario(work / "scenpq", data, format="parquet")
    write_asterix(work / "rec.ast", data)
    pts = TrackPoints(1.7e9 + np.arange(5.0), 56.0 + 0.01 * np.arange(5), 37.0 + 0.01 * np.arange(5),
                      np.array([1000.0, np.nan, 1020.0, 1030.0, 1040.0]))
    write_new4(work / "t.new4", pts)
    write_plt(work / "t.plt", pts)
    frame = _write_stations(work / "stations.csv")
    pos = np.array([[1000.0 + 100.0 * t, 2000.0, 3000.0] for t in range(5)])
    _write_bearings(work / "bearings.csv", _rows(frame, list(frame.stations), np.arange(5.0), pos, "M",
                                                 np.random.default_rng(2)))
    (work / "config.json").write_text(RunConfig().to_json())

    def scenario(name: str, source: str = "scen"):
        def read(path: Path, rng: random.Random):
            folder = path.parent / "s"
            if not folder.exists():
                import shutil
                shutil.copytree(work / source, folder)
            (folder / name).write_bytes(path.read_bytes())
            out = read_scenario(folder, skip_bad=rng.random() < 0.5)
            scenario_items(out)
        return read

    snap, restore = _snapshot(work)

    def asterix(path: Path, rng: random.Random):
        scenario_items(read_asterix(path, radars=work / "rec.ast.radars.csv", skip_bad=rng.random() < 0.5))

    return {
        "plots.csv": ((work / "scen" / "plots.csv").read_bytes(), scenario("plots.csv"), "plots.csv"),
        "radars.csv": ((work / "scen" / "radars.csv").read_bytes(), scenario("radars.csv"), "radars.csv"),
        "adsb.csv": ((work / "scen" / "adsb.csv").read_bytes(), scenario("adsb.csv"), "adsb.csv"),
        "scenario.json": ((work / "scen" / "scenario.json").read_bytes(), scenario("scenario.json"), "scenario.json"),
        "plots.parquet": ((work / "scenpq" / "plots.parquet").read_bytes(), scenario("plots.parquet", "scenpq"),
                          "plots.parquet"),
        "adsb.parquet": ((work / "scenpq" / "adsb.parquet").read_bytes(), scenario("adsb.parquet", "scenpq"),
                         "adsb.parquet"),
        "config.json": ((work / "config.json").read_bytes(), lambda p, r: read_config(p), "config.json"),
        "JSON (any)": ((work / "config.json").read_bytes(), lambda p, r: read_json(p), "any.json"),
        "ASTERIX (.ast)": ((work / "rec.ast").read_bytes(), asterix, "m.ast"),
        ".new4": ((work / "t.new4").read_bytes(), lambda p, r: read_new4(p), "m.new4"),
        ".plt": ((work / "t.plt").read_bytes(), lambda p, r: read_plt(p), "m.plt"),
        "stations.csv": ((work / "stations.csv").read_bytes(), lambda p, r: tio.read_stations(p), "st.csv"),
        "bearings.csv": ((work / "bearings.csv").read_bytes(),
                         lambda p, r: tio.read_bearings(p, skip_bad=r.random() < 0.5), "b.csv"),
        "snapshot": (snap, restore, "m.rtsnap"),
    }


def _snapshot(work: Path) -> tuple[bytes, Callable[[Path, random.Random], object]]:
    """A TrackManager's snapshot (tracks confirmed, the estimator holding aircraft) and its reader: the
    mutated payload is given a valid checksum again (a file crafted, not damaged), restored, and the
    restored manager processes the next inputs of its stream — compiled code reached from a restored
    state must not crash."""
    import hashlib
    import struct

    from radartracker.pipeline.stream import scenario_stream
    from radartracker.registry import make_manager, restore_manager
    from radartracker.simulation.scenarios import build_scenario
    from radartracker.tracking.snapshot import _HEADER, FORMAT_VERSION, MAGIC

    data = build_scenario("demo", seed=3, duration=90.0).run()
    items = scenario_stream(data)
    half = len(items) // 2
    mgr = make_manager(data.radars, data.reference)
    for item in items[:half]:
        mgr.process(item)
    mgr.snapshot(work / "valid.rtsnap")
    payload = (work / "valid.rtsnap").read_bytes()[_HEADER.size:]

    def restore(path: Path, rng: random.Random):
        body = path.read_bytes()
        path.write_bytes(struct.pack(">8sIQ32s", MAGIC, FORMAT_VERSION, len(body), hashlib.sha256(body).digest())
                         + body)
        restore_manager(path).process_many(items[half:half + 200])

    return payload, restore


def _mutate(buf: bytes, rng: random.Random) -> bytes:
    """1–4 byte edits; one input in 50 is also nested deep or given a long number (the JSON bombs)."""
    from tests.fuzz.mutations import apply, random_mutations

    out = apply(buf, random_mutations(rng, len(buf)))
    if rng.random() < 0.02:
        at = rng.randrange(len(out) + 1)
        bomb = rng.choice([b"[" * rng.randint(60, 5000), b"9" * rng.randint(90, 6000), b"\n" * 3])
        out = out[:at] + bomb + out[at:]
    return out


def _child(name: str, seed: int, start: int, stop: int, conn, inputs=_inputs) -> None:
    """Run inputs start..stop-1 of ``name``; send (index, outcome, detail) for each."""
    import logging

    from radartracker.errors import RadarTrackerError

    logging.disable(logging.WARNING)  # each damaged file logs what it skipped: thousands say nothing new
    signal.signal(signal.SIGALRM, _alarm)
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        buf, read, fname = inputs(work)[name]
        for i in range(start, stop):
            rng = random.Random(f"{seed}:{name}:{i}")
            path = work / fname
            path.write_bytes(_mutate(buf, rng))
            signal.setitimer(signal.ITIMER_REAL, HANG_S)
            try:
                read(path, rng)
                outcome, detail = "read", ""
            except RadarTrackerError:
                outcome, detail = "refused", ""
            except _Hang:
                outcome, detail = "hang", ""
            except Exception:  # a bug: kept for the report
                outcome, detail = "traceback", traceback.format_exc(limit=3)[-600:]
            finally:
                signal.setitimer(signal.ITIMER_REAL, 0)
            conn.send((i, outcome, detail))
    conn.send(None)


def fuzz(name: str, n: int, seed: int = 28, inputs=_inputs) -> tuple[Counter, list[str]]:
    """Outcomes of ``n`` inputs of reader ``name`` (read, refused, traceback, signal, hang) and the first
    tracebacks or signals seen (``inputs``: the readers, :func:`_inputs` unless a test gives its own)."""
    ctx = mp.get_context("fork")
    tally: Counter = Counter()
    seen: list[str] = []
    i = 0
    while i < n:
        stop = min(i + BATCH, n)
        parent, child = ctx.Pipe(duplex=False)
        proc = ctx.Process(target=_child, args=(name, seed, i, stop, child, inputs))
        proc.start()
        child.close()
        last = i - 1
        while True:
            try:
                msg = parent.recv()
            except EOFError:
                break
            if msg is None:
                break
            last, outcome, detail = msg
            tally[outcome] += 1
            if detail and len(seen) < 5:
                seen.append(f"input {last}: {detail}")
        proc.join()
        if proc.exitcode != 0:  # died (a signal: exitcode < 0) during input last + 1
            tally["signal"] += 1
            if len(seen) < 5:
                seen.append(f"input {last + 1}: child exit code {proc.exitcode}")
            last += 1
        i = last + 1
    return tally, seen


def readers() -> list[str]:
    with tempfile.TemporaryDirectory() as tmp:
        return list(_inputs(Path(tmp)))
