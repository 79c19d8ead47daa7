"""Plugin state as plain values, for snapshots (docs/reliability.md, "Snapshots").

An estimator or track filter exports its state with ``state_dict()`` and takes it back with
``load_state_dict(state)`` on an instance built with the same configuration (as PyTorch modules
do): the configuration rebuilds the structure, the state dict fills in the numbers. The defaults
here walk the instance's attributes and keep those of *plain* types — ``None``, bool, int, float,
complex, str, bytes, numeric NumPy arrays and scalars, and lists, tuples, dicts, sets and deques of
plain values; attributes holding another object with ``state_dict`` are nested. Anything else
(configuration objects, compiled kernels, scratch buffers) is left to the constructor. A plugin
whose state lives elsewhere overrides both methods.
"""

from __future__ import annotations

from collections import deque
from typing import Any

import numpy as np

from radartracker.errors import InputError

_SCALARS = (type(None), bool, int, float, complex, str, bytes)
_NESTED = "__state_dict__"  # key marking a nested object's state dict


def is_plain(value: Any) -> bool:
    """Whether ``value`` is built only of the plain types listed in the module docstring."""
    if isinstance(value, _SCALARS):
        return True
    if isinstance(value, (np.ndarray, np.generic)):
        return value.dtype.kind in "biufc"
    if isinstance(value, (list, tuple, set, frozenset, deque)):
        return all(is_plain(v) for v in value)
    if isinstance(value, dict):
        return all(is_plain(k) and is_plain(v) for k, v in value.items())
    return False


def default_state_dict(obj: object) -> dict[str, Any]:
    """The plain attributes of ``obj`` (nested objects with ``state_dict`` under their own key)."""
    out: dict[str, Any] = {}
    for name, value in vars(obj).items():
        if is_plain(value):
            out[name] = value
        elif callable(getattr(value, "state_dict", None)):
            out[name] = {_NESTED: value.state_dict()}
    return out


def default_load_state_dict(obj: object, state: dict[str, Any]) -> None:
    """Set the attributes of ``obj`` from ``state`` (as :func:`default_state_dict` made it).

    Only instance attributes may be set: a key naming a method or property of the class, or a
    dunder, is refused, so a state dict can change numbers but not behaviour.
    """
    for name, value in state.items():
        own = vars(obj)
        if (not isinstance(name, str) or not name.isidentifier() or name.startswith("__")
                or (name not in own and hasattr(type(obj), name))):
            raise InputError(f"{type(obj).__name__}: state key {name!r} is not an attribute it can take")
        if isinstance(value, dict) and set(value) == {_NESTED}:
            target = own.get(name)
            if not callable(getattr(target, "load_state_dict", None)):
                raise InputError(f"{type(obj).__name__}: attribute {name!r} cannot take a nested state")
            target.load_state_dict(value[_NESTED])
        elif not is_plain(value):
            raise InputError(f"{type(obj).__name__}: state of {name!r} is not made of plain values")
        else:
            setattr(obj, name, value)
