"""Typed keyword options: one declaration gives the default, checks a value and words its error.

`simulate`'s settings and each method's options (`Formulation.options`) are tables of
`Option`s. The same tables check keyword arguments in Python and the `[simulation]` table of
a scene, so a value is refused the same way wherever it comes from, before any work:

    >>> Option.integer(12, low=1).check(1.5, "max_newton", "method 'lu'")
    Traceback (most recent call last):
    ...
    ValueError: `max_newton` of method 'lu' must be a whole number, got 1.5

An unknown name is refused with the valid ones and the closest match (`unknown_names`).
"""

from __future__ import annotations

import difflib
import math
import numbers

import numpy as np


class Option:
    """A keyword option: `default`, and what a value must be.

    kind: "real" (a finite number in [low, high]; `open_low` excludes low), "integer" (a
    whole number ≥ low), "flag" (True or False), "choice" (one of `choices`), "pair" (two
    reals in (0, 1), increasing). `optional`: None is accepted (the default is then worked
    out from other settings). `infinite`: +inf is accepted for a "real" (no bound)."""

    __slots__ = ("default", "kind", "low", "high", "open_low", "choices", "optional",
                 "infinite", "doc")

    def __init__(self, default, kind, *, low=None, high=None, open_low=False, choices=(),
                 optional=False, infinite=False, doc=""):
        self.default, self.kind, self.low, self.high = default, kind, low, high
        self.open_low, self.choices, self.optional = open_low, tuple(choices), optional
        self.infinite, self.doc = infinite, doc

    @classmethod
    def positive(cls, default, **kw):
        """A finite real number > 0."""
        return cls(default, "real", low=0.0, open_low=True, **kw)

    @classmethod
    def real(cls, default, **kw):
        return cls(default, "real", **kw)

    @classmethod
    def integer(cls, default, low=0, **kw):
        return cls(default, "integer", low=low, **kw)

    @classmethod
    def flag(cls, default, **kw):
        return cls(default, "flag", **kw)

    @classmethod
    def choice(cls, default, choices, **kw):
        return cls(default, "choice", choices=choices, **kw)

    def check(self, value, name: str, owner: str = ""):
        """`value` converted (float, int, bool or the choice), or ValueError naming
        `name` (and `owner`) and saying what was expected and what was given."""
        who = f"`{name}`" + (f" of {owner}" if owner else "")
        if value is None and self.optional:
            return None
        kind = self.kind
        if kind == "flag":
            if isinstance(value, (bool, np.bool_)):
                return bool(value)
            raise ValueError(f"{who} must be true or false, got {_show(value)}")
        if kind == "choice":
            if isinstance(value, str) and value in self.choices:
                return value
            close = difflib.get_close_matches(str(value), self.choices, n=1)
            hint = f" (did you mean {close[0]!r}?)" if close else ""
            raise ValueError(f"{who} must be one of {', '.join(map(repr, self.choices))}, "
                             f"got {_show(value)}{hint}")
        if kind == "pair":
            try:
                a, b = (float(x) for x in value)
            except (TypeError, ValueError):
                raise ValueError(f"{who} must be two numbers, got {_show(value)}") from None
            if not (0.0 < a < b < 1.0):
                raise ValueError(f"{who} must be two numbers with 0 < first < second < 1, "
                                 f"got {_show(value)}")
            return (a, b)
        if isinstance(value, bool) or not isinstance(value, numbers.Real):
            what = "a whole number" if kind == "integer" else "a number"
            raise ValueError(f"{who} must be {what}, got {_show(value)}")
        x = float(value)
        if math.isnan(x) or (math.isinf(x) and not (self.infinite and x > 0)):
            raise ValueError(f"{who} must be finite, got {x}")
        if kind == "integer":
            if x != math.floor(x):
                raise ValueError(f"{who} must be a whole number, got {value!r}")
            x = int(x)
        if self.low is not None and (x < self.low or (self.open_low and x == self.low)):
            if self.open_low and self.low == 0:
                raise ValueError(f"{who} must be positive, got {value!r}")
            raise ValueError(f"{who} must be {'>' if self.open_low else '≥'} {self.low:g}, "
                             f"got {value!r}")
        if self.high is not None and x > self.high:
            raise ValueError(f"{who} must be ≤ {self.high:g}, got {value!r}")
        return x


def _show(value) -> str:
    text = repr(value)
    return text if len(text) <= 80 else text[:77] + "..."


def check_all(table: dict, values: dict, owner: str = "") -> dict:
    """Every option of `table` checked: `values` where given, else the defaults."""
    return {name: opt.check(values[name], name, owner) if name in values else opt.default
            for name, opt in table.items()}


def unknown_names(given, valid, what: str) -> str | None:
    """None if every name in `given` is in `valid`; else a message naming the unknown ones,
    the closest valid name of each (difflib) and all the valid ones."""
    unknown = [g for g in given if g not in valid]
    if not unknown:
        return None
    parts = []
    for name in unknown:
        close = difflib.get_close_matches(name, list(valid), n=1, cutoff=0.6)
        parts.append(f"{name!r}" + (f" (did you mean {close[0]!r}?)" if close else ""))
    return (f"{what} does not take {', '.join(parts)}; valid names: "
            f"{', '.join(sorted(valid))}")


# The share of the machine's memory one request may ask for before it is refused.
MEMORY_SHARE = 0.5


def machine_memory() -> float:
    """The machine's physical memory in bytes (16 GiB where it cannot be read)."""
    import os
    try:
        return float(os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"))
    except (ValueError, OSError, AttributeError):
        return 16 * 2.0 ** 30


def check_memory(size: float, what: str, advice: str) -> None:
    """ValueError where `size` bytes (asked for by `what`) exceed `MEMORY_SHARE` of the
    machine's memory, saying how much and what to do (`advice`): refused before any work,
    not a MemoryError after it."""
    memory = machine_memory()
    if size > MEMORY_SHARE * memory:
        raise ValueError(f"{what} needs {size / 2**30:.3g} GiB, more than {MEMORY_SHARE:.0%} "
                         f"of this machine's {memory / 2**30:.3g} GiB; {advice}")
