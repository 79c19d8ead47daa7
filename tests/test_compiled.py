"""Kernels compiled without numba's runtime (radartracker.compiled): the rule they keep, checked."""

from __future__ import annotations

import sys
import types

import numpy as np
import pytest

from radartracker.api import EstimatorConfig, kernel
from radartracker.compiled import array_returns, is_kernel
from radartracker.registry import load_motion_model, make_estimator
from radartracker.testing import CheckFailed
from radartracker.testing.common import check_kernels


def _module_with(**functions) -> types.ModuleType:
    module = types.ModuleType("kernels_under_test")
    for name, fn in functions.items():
        fn.__module__ = module.__name__
        setattr(module, name, fn)
    return module


def test_a_kernel_that_allocates_does_not_compile() -> None:
    @kernel
    def allocates(n):
        return np.zeros(n).sum()

    @kernel
    def copies(a, b):
        a[:] = b  # numba copies through a temporary, in case the two overlap

    with pytest.raises(Exception, match="returning of array passed into the function"):
        allocates(3)
    with pytest.raises(Exception, match="NRT required but not enabled"):
        copies(np.zeros(2), np.ones(2))


def test_array_returns_finds_a_kernel_returning_a_view() -> None:
    def view(a):
        return a[1:], a.shape[0]  # numba refuses a bare view; in a tuple it lets it through

    def total(a):
        s = 0.0
        for v in a:
            s += v
        return s, a.shape[0]

    module = _module_with(view=kernel(view), total=kernel(total))
    assert module.total(np.arange(4.0)) == (6.0, 4)
    assert array_returns(module) == ([], 1)  # only what has been compiled is seen
    module.view(np.arange(4.0))  # compiles; Python must not keep what it returned
    bad, seen = array_returns(module)
    assert seen == 2 and len(bad) == 1 and bad[0].startswith("view(")
    with pytest.raises(CheckFailed, match="returns an array"):
        sys.modules[module.__name__] = module
        try:
            check_kernels(type("Plugin", (), {"__module__": module.__name__}), "plugin 'x'")
        finally:
            del sys.modules[module.__name__]


def _run_built_in_kernels() -> tuple:
    """The coupled-sparse estimator through updates, reads and a removal; an IMM through screening."""
    est = make_estimator("coupled-sparse", EstimatorConfig(), ["R1", "R2"])
    for a in range(3):
        est.add_aircraft(a, 0.0, np.array([1e3 * a, 0.0, 100.0, 0.0]), np.diag([1e4, 1e4, 1e2, 1e2]))
    C, R = np.tile(np.eye(2), (6, 1, 1)), np.tile(np.eye(2) * 100.0, (6, 1, 1))
    refs = [sys.getrefcount(x) for x in (est._F, est._I, est._WF)]
    for k in range(1, 50):
        z = np.array([[1e3 * a + 400.0 * k, 0.0] for a in range(3)] * 2)
        est.update_many([4.0 * k] * 6, [0, 1, 2] * 2, ["R1"] * 3 + ["R2"] * 3, z, C, R)
        est.aircraft(1)
        est.bias("R2")
    est.remove_aircraft(2)
    f = load_motion_model("imm")()
    f.start(0.0, np.array([0.0, 0.0]), np.eye(2) * 100.0)
    for k in range(1, 20):
        f.screen(4.0 * k, np.array([400.0 * k, 0.0]), np.eye(2), np.eye(2) * 100.0, np.zeros(2), np.eye(2), 25.0)
    return est, refs


def test_built_in_kernels_return_only_numbers_and_keep_no_references() -> None:
    est, refs = _run_built_in_kernels()
    # a reference count taken and never given back would keep the buffers alive forever
    assert [sys.getrefcount(x) for x in (est._F, est._I, est._WF)] == refs
    seen = 0
    for name in ("_kernels", "_linalg", "_predict", "_refresh"):
        bad, n = array_returns(sys.modules[f"radartracker_plugins.coupled_sparse.{name}"])
        assert bad == []
        seen += n
    bad, n = array_returns(sys.modules["radartracker_plugins.motion._imm_compiled"])
    assert bad == [] and n >= 1  # screen, at least
    # the kernels Python calls are compiled (or loaded from numba's cache) in this process; the ones they
    # call are compiled into them, and seen only when compiled here, so the count depends on the cache
    kernels = sys.modules["radartracker_plugins.coupled_sparse._kernels"]
    assert all(k.nopython_signatures for k in (kernels.update_rows, kernels.read_aircraft, kernels.marginalise))
    assert seen >= 3
