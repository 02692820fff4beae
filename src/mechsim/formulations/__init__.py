"""Formulations: the constrained DAE turned into an ODE an integrator can step.

`METHODS` maps a method name to its class; `mechanism.simulate(method=...)` looks names up
here, and an unknown name lists the valid ones.
"""

from .base import Formulation
from .baumgarte import Baumgarte

METHODS: dict[str, type[Formulation]] = {
    Baumgarte.name: Baumgarte,
}

DEFAULT_METHOD = "baumgarte"


def formulation_class(name: str | None) -> type[Formulation]:
    name = DEFAULT_METHOD if name is None else name
    try:
        return METHODS[name]
    except (KeyError, TypeError):
        raise ValueError(f"unknown method {name!r}; valid methods: "
                         f"{', '.join(sorted(METHODS))}") from None


__all__ = ["DEFAULT_METHOD", "METHODS", "Formulation", "formulation_class"]
