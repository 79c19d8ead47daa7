"""Plugin state as plain values, for snapshots (docs/reliability.md, "Snapshots").

An estimator or track filter exports its state with ``state_dict()`` and takes it back with
``load_state_dict(state)`` on an instance built with the same configuration (as PyTorch modules
do): the configuration rebuilds the structure, the state dict fills in the numbers. The defaults
here walk the instance's attributes and keep those of *plain* types — ``None``, bool, int, float,
complex, str, bytes, numeric NumPy arrays and scalars, and lists, tuples, dicts, sets and deques of
plain values; attributes holding another object with ``state_dict`` are nested. Anything else
(configuration objects, compiled kernels, scratch buffers) is left to the constructor. A plugin
whose state lives elsewhere overrides both methods.

A state dict comes from a file and is untrusted: the default loader takes a value only in place of
an attribute of the same kind (a number for a number, an array of the same dimensions and kind of
dtype, a container of the same type), and :class:`StateCheck` gives a plugin's own loader the checks
of shapes, dtypes, indices and covariances it needs *before* it builds anything from the state.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Hashable, Iterable
from numbers import Number
from typing import Any

import numpy as np

from radartracker.errors import InputError

_SCALARS = (type(None), bool, int, float, complex, str, bytes)
_NESTED = "__state_dict__"  # key marking a nested object's state dict
_FIELD: Any = object()  # StateCheck: "the field of that name", as opposed to a value given


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
        elif name in own and not _same_kind(own[name], value):
            raise InputError(f"{type(obj).__name__}: state of {name!r} is a {_kind(value)} where the "
                             f"attribute holds a {_kind(own[name])}")
        else:
            setattr(obj, name, value)


def _kind(value: Any) -> str:
    if isinstance(value, np.ndarray):
        return f"{value.ndim}-d {value.dtype} array"
    return type(value).__name__


def _same_kind(current: Any, value: Any) -> bool:
    """Whether ``value`` may replace ``current``: None for anything (and anything for None), a number for
    a number, an array of the same dimensions and kind of dtype, else the same type."""
    if current is None or value is None:
        return True
    if isinstance(current, np.ndarray):
        return (isinstance(value, np.ndarray) and value.ndim == current.ndim
                and _dtype_class(value.dtype) == _dtype_class(current.dtype))
    if isinstance(current, (Number, np.generic)) and not isinstance(current, (str, bytes)):
        return isinstance(value, (Number, np.generic)) and not isinstance(value, (str, bytes, np.ndarray))
    return type(value) is type(current)


def _dtype_class(dtype: np.dtype) -> str:
    """'b' booleans, 'i' integers (signed or not), 'f' floats, 'c' complex."""
    return "i" if dtype.kind == "u" else dtype.kind


class StateCheck:
    """Checks of an untrusted state dict, for a plugin's ``load_state_dict``: each method returns the
    checked value (arrays as owned float64/int64 copies) or raises :class:`InputError` naming ``owner``,
    the field and what is wrong. Build everything only after every check has passed."""

    def __init__(self, owner: str, state: Any, fields: Iterable[str]) -> None:
        self.owner = owner
        fields = tuple(fields)
        if not isinstance(state, dict):
            raise self.fail(f"the state is a {type(state).__name__}, not a dict")
        if set(state) != set(fields):
            extra, missing = sorted(map(str, set(state) - set(fields))), sorted(set(fields) - set(state))
            raise self.fail(f"state fields {sorted(map(str, state))} are not {sorted(fields)} "
                            f"(unknown: {extra}, missing: {missing})")
        self.state = state

    def fail(self, message: str) -> InputError:
        """The error to raise: ``owner``'s state and ``message``."""
        return InputError(f"{self.owner} state: {message}")

    def array(self, name: str, shape: tuple[int | None, ...], kind: str = "f", value: Any = _FIELD) -> np.ndarray:
        """Field ``name`` (or ``value``, named ``name``) as an array of ``shape`` (None: any length) and dtype
        kind ``kind`` ('f': finite float64, 'i': int64), copied."""
        v = self.state[name] if value is _FIELD else value
        if not isinstance(v, np.ndarray):
            raise self.fail(f"{name} is a {type(v).__name__}, not an array")
        ok_kinds = "fiu" if kind == "f" else "iu"
        if v.dtype.kind not in ok_kinds:
            raise self.fail(f"{name} has dtype {v.dtype}, expected {'float' if kind == 'f' else 'integer'}")
        if v.ndim != len(shape) or any(n is not None and n != d for n, d in zip(shape, v.shape)):
            want = "(" + ", ".join("any" if n is None else str(n) for n in shape) + ")"
            raise self.fail(f"{name} has shape {v.shape}, expected {want}")
        if kind == "f":
            out = v.astype(np.float64)
            if not np.isfinite(out).all():
                raise self.fail(f"{name} has non-finite values")
            return out
        if v.size and (v.min() < np.iinfo(np.int64).min or v.max() > np.iinfo(np.int64).max):
            raise self.fail(f"{name} has values beyond 64-bit integers")
        return v.astype(np.int64)

    def integer(self, what: str, value: Any, lo: int, hi: int) -> int:
        """``value`` as an int in [lo, hi] (an index, a size or a count; refused before anything is sized by it)."""
        if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
            raise self.fail(f"{what} is a {type(value).__name__}, not an integer")
        if not lo <= value <= hi:
            raise self.fail(f"{what} = {value} is outside [{lo}, {hi}]")
        return int(value)

    def number(self, what: str, value: Any, *, nan: bool = False, none: bool = False) -> float | None:
        """``value`` as a finite float (NaN too if ``nan``; None kept if ``none``)."""
        if value is None and none:
            return None
        if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer, np.floating)):
            raise self.fail(f"{what} is a {type(value).__name__}, not a number")
        x = float(value)
        if not (np.isfinite(x) or (nan and np.isnan(x))):
            raise self.fail(f"{what} = {x} is not finite")
        return x

    def mapping(self, name: str, value: Any = _FIELD) -> dict:
        """Field ``name`` (or ``value``) as a dict whose keys are plain hashable values."""
        v = self.state[name] if value is _FIELD else value
        if not isinstance(v, dict):
            raise self.fail(f"{name} is a {type(v).__name__}, not a dict")
        for k in v:
            if not (isinstance(k, Hashable) and is_plain(k)):
                raise self.fail(f"{name} has a key of type {type(k).__name__}")
        return v

    def sequence(self, name: str, value: Any = _FIELD, max_len: int | None = None, length: int | None = None) -> list:
        """Field ``name`` (or ``value``) as a list (from a list or tuple), at most ``max_len`` or exactly
        ``length`` long."""
        v = self.state[name] if value is _FIELD else value
        if not isinstance(v, (list, tuple)):
            raise self.fail(f"{name} is a {type(v).__name__}, not a list")
        if (max_len is not None and len(v) > max_len) or (length is not None and len(v) != length):
            raise self.fail(f"{name} has {len(v)} entries, expected {length if length is not None else f'≤ {max_len}'}")
        return list(v)

    def names(self, name: str, expected: list[str], value: Any = _FIELD) -> list[str]:
        """Field ``name`` (or ``value``, a list or the keys of a dict): the radar ids ``expected`` (the
        estimator's own, in its order)."""
        v = self.sequence(name, list(value) if isinstance(value, dict) else value)
        if v != list(expected):
            raise self.fail(f"{name} {v[:10]!r} are not the radars this estimator was built with {expected[:10]!r}")
        return v

    def gaussian(self, what: str, mean: Any, cov: Any, n: int) -> tuple[np.ndarray, np.ndarray]:
        """(mean, cov) as a finite n-vector and a symmetric positive semi-definite n×n covariance."""
        mean, cov = self.array(f"{what} mean", (n,), value=mean), self.array(f"{what} covariance", (n, n), value=cov)
        self.covariance(f"{what} covariance", cov)
        return mean, cov

    def covariance(self, what: str, P: np.ndarray, *, definite: bool | None = None, rtol: float = 1e-9) -> None:
        """``P`` (finite, square) symmetric to ``rtol`` of its largest diagonal entry and, by ``definite``,
        positive semi-definite (None: a Cholesky factor of P + rtol·max|diag|·I exists), positive definite
        (True: a Cholesky factor of P exists) or either (False)."""
        if P.size == 0:
            return
        scale = max(float(np.max(np.abs(np.diag(P)))), np.finfo(float).tiny)
        if np.max(np.abs(P - P.T)) > rtol * scale:
            raise self.fail(f"{what} is not symmetric")
        if definite is False:
            return
        try:
            np.linalg.cholesky(0.5 * (P + P.T) + (0.0 if definite else rtol * scale) * np.eye(len(P)))
        except np.linalg.LinAlgError:
            raise self.fail(f"{what} is not positive {'definite' if definite else 'semi-definite'}") from None
