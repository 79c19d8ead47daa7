"""Snapshots of a TrackManager: a documented, versioned, checksummed file; no pickle.

Layout (all integers big-endian; documented in docs/reliability.md, "Snapshots")::

    offset  size  content
    0       8     magic  89 52 54 53 4E 41 50 0A  ("\\x89RTSNAP\\n")
    8       4     format version (uint32), FORMAT_VERSION
    12      8     payload length n (uint64)
    20      32    SHA-256 of the payload
    52      n     payload: a msgpack array [meta, state], state itself msgpack bytes

``meta`` holds what rebuilds the manager (radars, reference point, configuration); ``state`` the
document of what changes while it runs (:mod:`radartracker.tracking.schema` lists it field by field).
Values are msgpack natives (nil, bool, int,
float, str, bin, array) or a map ``{"t": tag, "v": value}`` — a msgpack map is never anything
else — with the tags: ``tuple``, ``set``, ``frozenset``, ``dict`` and ``counter`` (v: [key, value]
pairs, in order), ``deque`` ([maxlen, items]), ``complex`` ([re, im]), ``nd`` ([dtype, shape,
order, bytes]; numeric dtypes only), ``np`` ([dtype, bytes]: a NumPy scalar), ``count``
([next, step]: an ``itertools.count``) and ``attrs`` ([module, class, [[field, value]…]]: an attrs
class of radartracker or its plugins, already imported, built through its validating constructor).

Reading never executes anything from the file: no pickle, no import; it only builds the listed
types, and attrs classes that are already loaded, through their validating constructors. A file
that is truncated, corrupted (checksum), foreign (magic) or of a newer format version is refused
with a :class:`~radartracker.errors.SnapshotError` naming it. Writing is atomic: the file is
written under a temporary name in its folder, synced and renamed, so a failed snapshot leaves the
previous one intact. A snapshot continues a run with the same release of radartracker and its
plugins; shared references inside the state are not preserved (it is saved as a tree).
"""

from __future__ import annotations

import hashlib
import itertools
import os
import re
import struct
import sys
from collections import Counter, deque
from collections.abc import Callable
from pathlib import Path
from typing import Any

import attrs
import msgpack
import numpy as np

from radartracker.errors import SnapshotError

MAGIC = b"\x89RTSNAP\n"
FORMAT_VERSION = 2
_HEADER = struct.Struct(">8sIQ32s")
_PACKAGES = ("radartracker.", "radartracker_plugins.")
_COUNT = re.compile(r"count\((-?\d+)(?:, (-?\d+))?\)")


# --- encoding --------------------------------------------------------------------------------------

def class_name(obj: object) -> str:
    return f"{type(obj).__module__}.{type(obj).__qualname__}"


def _tag(tag: str, value: Any) -> dict:
    return {"t": tag, "v": value}


def _enc(obj: Any, where: str) -> Any:
    if obj is None or isinstance(obj, (bool, str, bytes)) or type(obj) in (int, float):
        return obj
    if isinstance(obj, list):
        return [_enc(v, f"{where}[{i}]") for i, v in enumerate(obj)]
    if isinstance(obj, tuple) and not hasattr(obj, "_fields"):
        return _tag("tuple", [_enc(v, f"{where}[{i}]") for i, v in enumerate(obj)])
    if isinstance(obj, (set, frozenset)):
        return _tag(type(obj).__name__, [_enc(v, f"{where}{{}}") for v in obj])
    if isinstance(obj, deque):
        return _tag("deque", [obj.maxlen, [_enc(v, f"{where}[{i}]") for i, v in enumerate(obj)]])
    if isinstance(obj, dict) and type(obj) in (dict, Counter):
        pairs = [[_enc(k, f"{where} key"), _enc(v, f"{where}[{k!r}]")] for k, v in obj.items()]
        return _tag("counter" if type(obj) is Counter else "dict", pairs)
    if type(obj) is complex:
        return _tag("complex", [obj.real, obj.imag])
    if isinstance(obj, np.ndarray) and obj.dtype.kind in "biufc":
        order = "F" if obj.flags.f_contiguous and not obj.flags.c_contiguous else "C"
        return _tag("nd", [obj.dtype.str, list(obj.shape), order, obj.tobytes(order=order)])
    if isinstance(obj, np.generic) and obj.dtype.kind in "biufc":
        return _tag("np", [obj.dtype.str, obj.tobytes()])
    if isinstance(obj, itertools.count):
        m = _COUNT.fullmatch(repr(obj))
        if m is None:
            raise TypeError(f"{where}: cannot save {obj!r} (integer counters only)")
        return _tag("count", [int(m[1]), int(m[2] or 1)])
    cls = type(obj)
    if attrs.has(cls) and cls.__module__.startswith(_PACKAGES):
        fields = [[f.name, _enc(getattr(obj, f.name), f"{where}.{f.name}")] for f in attrs.fields(cls)]
        return _tag("attrs", [cls.__module__, cls.__qualname__, fields])
    raise TypeError(f"{where}: cannot save a {cls.__module__}.{cls.__qualname__} (see radartracker.tracking.snapshot)")


# --- decoding --------------------------------------------------------------------------------------

def _record_class(module: str, qualname: str) -> type:
    """An attrs class of radartracker or its plugins that is already imported (nothing is imported)."""
    mod = sys.modules.get(module) if isinstance(module, str) and module.startswith(_PACKAGES) else None
    obj: Any = mod
    for part in qualname.split(".") if isinstance(qualname, str) and mod is not None else ():
        obj = getattr(obj, part, None) if part.isidentifier() else None
    if not (isinstance(obj, type) and attrs.has(obj)):
        raise ValueError(f"class {module}.{qualname} is not a loaded radartracker attrs class")
    return obj


def _build(cls: type, fields: list) -> Any:
    values = dict(fields)
    known = {f.name: f for f in attrs.fields(cls)}
    if set(values) - set(known):
        raise ValueError(f"{cls.__qualname__}: unknown field(s) {sorted(set(values) - set(known))}")
    obj = cls(**{f.alias: values[n] for n, f in known.items() if f.init and n in values})
    for n, f in known.items():
        if not f.init and n in values:
            object.__setattr__(obj, n, values[n])
    return obj


def _array(dtype: str, shape: list, order: str, data: bytes) -> np.ndarray:
    dt = np.dtype(dtype)
    if dt.kind not in "biufc" or order not in ("C", "F") or any(not isinstance(n, int) or n < 0 for n in shape):
        raise ValueError(f"array of dtype {dtype!r}, shape {shape}, order {order!r} refused")
    return np.frombuffer(data, dt).reshape(shape, order=order).copy(order="K")


def _hook() -> Callable[[dict], Any]:
    def pairs(v: list) -> list[tuple]:
        return [(k, x) for k, x in v]

    def decode(d: dict) -> Any:
        if set(d) != {"t", "v"}:
            raise ValueError(f"map with keys {sorted(map(str, d))} is not a tagged value")
        t, v = d["t"], d["v"]
        if t == "tuple":
            return tuple(v)
        if t in ("set", "frozenset"):
            return (set if t == "set" else frozenset)(v)
        if t == "dict":
            return dict(pairs(v))
        if t == "counter":
            return Counter(dict(pairs(v)))
        if t == "deque":
            return deque(v[1], maxlen=v[0])
        if t == "complex":
            return complex(float(v[0]), float(v[1]))
        if t == "nd":
            return _array(*v)
        if t == "np":
            return _array(v[0], [], "C", v[1])[()]
        if t == "count":
            return itertools.count(int(v[0]), int(v[1]))
        if t == "attrs":
            return _build(_record_class(v[0], v[1]), v[2])
        raise ValueError(f"unknown or misplaced tag {t!r}")

    return decode


def decode(data: bytes) -> Any:
    """The value of msgpack ``data`` written by :func:`encode` (tags resolved, nothing executed)."""
    return msgpack.unpackb(data, object_hook=_hook(), raw=False, strict_map_key=False)


def encode(value: Any, where: str) -> bytes:
    """``value`` (plain values, NumPy arrays, attrs classes of radartracker) as msgpack bytes."""
    return msgpack.packb(_enc(value, where), use_bin_type=True)


# --- files ----------------------------------------------------------------------------------------

def write_snapshot_file(path: Path | str, payload: bytes) -> None:
    """Header + payload, written atomically (temporary file in the same folder, fsync, rename)."""
    path = Path(path)
    blob = _HEADER.pack(MAGIC, FORMAT_VERSION, len(payload), hashlib.sha256(payload).digest()) + payload
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        with open(tmp, "wb") as fh:
            fh.write(blob)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def read_snapshot_file(path: Path | str) -> bytes:
    """The checked payload of a snapshot file; :class:`SnapshotError` for anything else."""
    data = Path(path).read_bytes()
    name = str(path)
    if len(data) < len(MAGIC) or data[:len(MAGIC)] != MAGIC:
        raise SnapshotError(name, "not a radartracker snapshot (magic bytes differ; pickle snapshots of "
                                  "earlier releases are refused)")
    if len(data) < _HEADER.size:
        raise SnapshotError(name, f"truncated: {len(data)} bytes, the header alone has {_HEADER.size}")
    _, version, n, digest = _HEADER.unpack_from(data)
    if version > FORMAT_VERSION:
        raise SnapshotError(name, f"snapshot format version {version} is newer than this release reads "
                                  f"({FORMAT_VERSION}); restore it with the release that wrote it")
    if version < FORMAT_VERSION:
        raise SnapshotError(name, f"snapshot format version {version} was written by an earlier release (its state "
                                  f"was the manager's attributes); this release reads version {FORMAT_VERSION}")
    payload = data[_HEADER.size:]
    if len(payload) != n:
        raise SnapshotError(name, f"truncated or padded: payload of {len(payload)} bytes, header says {n}")
    if hashlib.sha256(payload).digest() != digest:
        raise SnapshotError(name, "corrupted: SHA-256 of the payload does not match the header")
    return payload
