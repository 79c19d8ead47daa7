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
"""

from __future__ import annotations

from collections.abc import Callable
from types import ModuleType
from typing import Any

from numba import njit, types
from numba.core.registry import CPUDispatcher


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
