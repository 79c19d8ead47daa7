"""Names of a package imported when first used (PEP 562), so that importing the package costs nothing.

The command line imports every module that registers a sub-command to build its parser
(``radartracker --help``): a package that re-exports its contents at import (``from .engine import
run_many``) would pull numpy, scipy, numba and the rest in with it, for a help text. A package
whose ``__init__`` declares its names with :func:`lazy_exports` instead imports the module behind a
name only when the name is first read (``from package import name``, ``package.name``, ``import *``).
"""

from __future__ import annotations

import importlib
import sys
from collections.abc import Callable, Mapping
from typing import Any


def lazy_exports(package: str, exports: Mapping[str, tuple[str, ...]]) -> tuple[Callable[[str], Any],
                                                                               Callable[[], list[str]]]:
    """``__getattr__`` and ``__dir__`` for the module named ``package``, whose names ``exports`` lists by
    the module defining them (absolute, or relative to ``package``): ``{".engine": ("run_many",)}``.

    A name is imported from its module on first use and then kept in the package (later reads do not
    come here again); a name not listed is an ``AttributeError``, as for any module, so that
    ``from package import submodule`` still finds a submodule. Use::

        __getattr__, __dir__ = lazy_exports(__name__, {".engine": ("run_many",)})
    """
    where = {name: module for module, names in exports.items() for name in names}

    def __getattr__(name: str) -> Any:
        try:
            module = where[name]
        except KeyError:
            raise AttributeError(f"module {package!r} has no attribute {name!r}") from None
        value = getattr(importlib.import_module(module, package), name)
        setattr(sys.modules[package], name, value)
        return value

    def __dir__() -> list[str]:
        return sorted(set(vars(sys.modules[package])) | set(where))

    return __getattr__, __dir__
