"""Compiled kernels that own nothing: numba without its runtime's reference counts.

A filter's compiled step reads and writes arrays its caller owns (the filter's state, its scratch, the
measurement) and returns numbers. Compiled the usual way, every array argument, every view and every
call between kernels costs an atomic increment and decrement of a reference count that nothing needs
here (what that cost on the national replay: docs/performance.md, "Kernels without reference counts").

:func:`kernel` compiles without numba's runtime (``_nrt=False``). Numba itself then refuses to compile
anything that needs the runtime: an allocation (``np.empty``, an array expression making a temporary),
an array copied onto a slice ("NRT required but not enabled"), so a kernel that compiles allocates
nothing, and it refuses to return a new array or a view. What it lets through is a view inside a
returned tuple: Python would get an array with no owner. So a kernel returns only numbers (or tuples of
them) and writes arrays into its arguments.
:func:`array_returns` finds a compiled signature that breaks this rule, and
:func:`radartracker.testing.check_kernels` fails on it in a plugin's tests.

numba keeps each compiled kernel in a disk cache (beside the source, or in ``NUMBA_CACHE_DIR``): only
the first run after installing or upgrading compiles, for some seconds. :func:`in_disk_cache` tells
whether a kernel is there, and :func:`compile_notice` says so on stderr while kernels are compiled.
"""

from __future__ import annotations

import contextlib
import sys
import time
from collections.abc import Callable, Iterator
from types import ModuleType
from typing import Any, TextIO

from numba import njit, types
from numba.core import event
from numba.core.registry import CPUDispatcher

COMPILING = ("compiling the numba kernels, once after installing or upgrading (15 s to a minute; later runs load "
             "them from numba's disk cache)...")


def kernel(fn: Callable | None = None, /, **options: Any) -> Any:
    """``@kernel`` or ``@kernel(inline="always")``: ``fn`` compiled by numba (cached) without its
    runtime, for a function that allocates nothing and returns only numbers (module docstring)."""
    jit = njit(cache=True, _nrt=False, **options)
    return jit if fn is None else jit(fn)


def is_kernel(obj: object) -> bool:
    """Whether ``obj`` is a function compiled by :func:`kernel` (without numba's runtime)."""
    return isinstance(obj, CPUDispatcher) and obj.targetoptions.get("_nrt") is False


def _holds_array(tp: types.Type) -> bool:
    if isinstance(tp, types.Array):
        return True
    return isinstance(tp, types.BaseTuple) and any(_holds_array(t) for t in tp.types)


def array_returns(module: ModuleType) -> tuple[list[str], int]:
    """(each ``name(signature) -> return type`` of ``module``'s kernels that returns an array, the number
    of compiled kernel signatures looked at). Only signatures compiled so far are seen: run the
    kernels first."""
    bad, seen = [], 0
    for name, obj in vars(module).items():
        if not is_kernel(obj) or getattr(obj, "__module__", None) != module.__name__:
            continue
        for sig in obj.nopython_signatures:
            seen += 1
            if _holds_array(sig.return_type):
                bad.append(f"{name}{sig.args} -> {sig.return_type}")
    return bad, seen


def cache_is_cold(*modules: ModuleType) -> bool:
    """Whether numba's disk cache holds none of the kernels defined in ``modules`` that it caches, for their current
    source: a fresh install, an upgrade or an emptied cache. One kernel held is enough to say warm: a run
    need not use every kernel of a module, and one it never uses is never cached."""
    kernels = [obj for m in modules for obj in vars(m).values()
               if isinstance(obj, CPUDispatcher) and obj.__module__ == m.__name__ and obj.stats.cache_path is not None]
    return not any(in_disk_cache(k) for k in kernels)


def in_disk_cache(kernel: CPUDispatcher) -> bool:
    """Whether numba's disk cache holds a compiled ``kernel`` for its current source: False after installing,
    upgrading or emptying the cache, until a run has compiled it. A kernel numba does not cache counts as held
    (there is nothing to compile ahead for it)."""
    cache = getattr(kernel, "_cache", None)
    index = getattr(getattr(cache, "_cache_file", None), "_load_index", None)  # numba's own reading of its index
    return index is None or bool(index())


class _Compiling(event.Listener):
    """numba's ``numba:compile`` events (a kernel compiled, not loaded from the cache): the first one of a
    cached kernel is said on ``stream``; the seconds spent compiling are added up."""

    def __init__(self, stream: TextIO) -> None:
        self.stream, self.depth, self.started, self.seconds, self.said = stream, 0, 0.0, 0.0, False

    def on_start(self, ev: event.Event) -> None:
        if self.depth == 0:  # a kernel calling another compiles the callee inside its own compilation
            self.started = time.perf_counter()
        self.depth += 1
        if not self.said and ev.data["dispatcher"].stats.cache_path is not None:  # a cached kernel: the cache is cold
            print(f"radartracker: {COMPILING}", file=self.stream, flush=True)
            self.said = True

    def on_end(self, ev: event.Event) -> None:
        self.depth -= 1
        if self.depth == 0:
            self.seconds += time.perf_counter() - self.started


@contextlib.contextmanager
def compile_notice(stream: TextIO | None = None) -> Iterator[None]:
    """While the block runs, the first kernel that numba compiles because its disk cache lacks it is said on
    ``stream`` (stderr) in one line (:data:`COMPILING`), and at the end one more line says how long the
    compiling took. A warm cache (kernels loaded, none compiled) says nothing."""
    listener = _Compiling(stream if stream is not None else sys.stderr)
    with event.install_listener("numba:compile", listener):
        yield
    if listener.said:
        print(f"radartracker: kernels compiled in {listener.seconds:.1f} s", file=listener.stream, flush=True)
