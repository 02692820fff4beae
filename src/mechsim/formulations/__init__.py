"""Formulations: the constrained DAE turned into an ODE an integrator can step.

`METHODS` maps a method name to its class; `mechanism.simulate(method=...)` looks names up
here, and an unknown name lists the valid ones.
"""

import difflib

from .base import Formulation
from .basis import ConstraintSolveError
from .baumgarte import Baumgarte
from .hybrid import Hybrid
from .partitioned import Partitioned, QRPartitioned, SSNewmark, SVDPartitioned
from .projection import Projection

METHODS: dict[str, type[Formulation]] = {
    cls.name: cls for cls in (Partitioned, QRPartitioned, SVDPartitioned, Projection, Hybrid,
                              Baumgarte, SSNewmark)
}

DEFAULT_METHOD = "hybrid"


def formulation_class(name: str | None) -> type[Formulation]:
    name = DEFAULT_METHOD if name is None else name
    try:
        return METHODS[name]
    except (KeyError, TypeError):
        close = difflib.get_close_matches(str(name), list(METHODS), n=1)
        hint = f" (did you mean {close[0]!r}?)" if close else ""
        raise ValueError(f"unknown method {name!r}{hint}; valid methods: "
                         f"{', '.join(sorted(METHODS))}") from None


__all__ = ["DEFAULT_METHOD", "METHODS", "ConstraintSolveError", "Formulation",
           "formulation_class"]
