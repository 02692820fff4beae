"""Argument checks shared by the model classes.

Every message names the model object and the argument, and says what was expected and what was
given (scipy's style: "`axis` of prismatic 'P1' must have length 2, got 3").
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from .parameters import Dual, is_exact, values


class ModelError(ValueError):
    """A mechanism was described inconsistently; the message names the object at fault."""


class LoadError(ModelError):
    """A user's load function failed or gave an unusable value during a run; the message
    names the load, and the user's own exception is its `__cause__` (with its traceback)."""


def call_user(function, args, owner: str):
    """`function(*args)`, any exception it raises turned into a LoadError naming `owner`."""
    try:
        return function(*args)
    except Exception as exc:
        raise LoadError(f"{owner}: its function raised {type(exc).__name__}: {exc} "
                        f"(at t = {args[0]:.9g})") from exc


def _no_parameter(value, what: str, owner: str):
    """A ModelError where an argument that does not take parameters is given one."""
    if is_exact(value):
        raise ModelError(f"{owner}: `{what}` cannot depend on a Parameter (sensitivities are "
                         "carried through bodies' position, angle, mass, inertia and initial "
                         "velocities and through revolute and prismatic joints' geometry); "
                         "give a number")


def scalar(value, what: str, owner: str, *, positive: bool = False,
           nonnegative: bool = False) -> float:
    """Return `value` as a finite float, or raise naming `owner` and `what` (a string or a
    boolean is not a number here, even where float() would read it; nor is a Parameter,
    see `scalar_exact`)."""
    _no_parameter(value, what, owner)
    if isinstance(value, (str, bytes, bool, np.bool_)):
        raise ModelError(f"{owner}: `{what}` must be a number, got {value!r:.60}")
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ModelError(f"{owner}: `{what}` must be a number, got {value!r:.60}") from None
    if not math.isfinite(x):
        raise ModelError(f"{owner}: `{what}` must be finite, got {x}")
    if positive and not x > 0.0:
        raise ModelError(f"{owner}: `{what}` must be positive, got {x}")
    if nonnegative and x < 0.0:
        raise ModelError(f"{owner}: `{what}` must be non-negative, got {x}")
    return x


def number_array(value, owner: str, expected: str) -> np.ndarray:
    """`value` as an array of floats, or a ModelError naming `owner` and what it expected."""
    try:
        return np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise ModelError(f"{owner}: expected {expected}, got {value!r:.80}") from None


def name_or_default(name, default: str, what: str) -> str:
    """A model object's name: `name` if given (a non-empty string), else `default`."""
    if name is None:
        return default
    if not isinstance(name, str) or not name.strip():
        raise ModelError(f"{what} {default!r}: `name` must be a non-empty string, got "
                         f"{name!r:.60}")
    return name


def scalar_exact(value, what: str, owner: str, **checks):
    """(`value` as a checked float as `scalar` gives it, `value` itself where it is a
    Parameter or a number computed from them, else that float): for an argument that
    takes parameters (`mechsim.model.parameters`)."""
    if isinstance(value, Dual):
        return scalar(value.value, what, owner, **checks), value
    x = scalar(value, what, owner, **checks)
    return x, x


def vector2_exact(value, what: str, owner: str):
    """(`value` as `vector2` gives it, its two entries as given where either is a
    Dual, else the same array): for an argument that takes parameters."""
    if not is_exact(value):
        a = vector2(value, what, owner)
        return a, a
    entries = list(np.asarray(value, dtype=object).ravel()) \
        if np.ndim(np.asarray(value, dtype=object)) == 1 else None
    if entries is None or len(entries) != 2:
        raise ModelError(f"{owner}: `{what}` must be a 2-vector of numbers, got {value!r:.60}")
    return vector2(values(entries), what, owner), np.array(entries, dtype=object)


def vector2(value, what: str, owner: str) -> np.ndarray:
    """Return `value` as a finite float array of shape (2,), or raise naming `owner` (a
    Parameter is refused here: see `vector2_exact`)."""
    _no_parameter(value, what, owner)
    if isinstance(value, (str, bytes)) or (isinstance(value, (list, tuple)) and any(
            isinstance(x, (str, bytes, bool)) for x in value)):
        raise ModelError(f"{owner}: `{what}` must be a 2-vector of numbers, got {value!r:.60}")
    try:
        a = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ModelError(f"{owner}: `{what}` must be a 2-vector of numbers, got "
                         f"{value!r:.60}") from None
    if a.shape != (2,):
        raise ModelError(f"{owner}: `{what}` must have length 2, got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ModelError(f"{owner}: `{what}` must be finite, got {a.tolist()}")
    return a


def scalar_or_function(value, what: str, owner: str) -> float | Callable[[float], float]:
    """A constant (checked now) or a callable of time (checked when first evaluated)."""
    if callable(value):
        return value
    return scalar(value, what, owner)


def rotation(angle: float) -> np.ndarray:
    """Planar rotation matrix A(θ) = [[cos θ, −sin θ], [sin θ, cos θ]]."""
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s], [s, c]])
