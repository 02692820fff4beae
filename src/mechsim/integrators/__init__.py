"""Integrators: scipy's `OdeSolver` classes by name (more join this registry).

Every entry follows scipy's `OdeSolver` interface (`step()`, `dense_output()`, `t`, `y`,
`status`, `nfev`), so the solver manager drives all of them the same way.
"""

from __future__ import annotations

import difflib

from scipy.integrate import BDF, LSODA, RK23, RK45, Radau

from .adams import AdamsPECE
from .compiled import CompiledDOP853
from .trapezoidal import Trapezoidal

INTEGRATORS = {"adams": AdamsPECE, "RK45": RK45, "RK23": RK23, "DOP853": CompiledDOP853,
               "Radau": Radau, "BDF": BDF, "LSODA": LSODA, "trapezoidal": Trapezoidal}


def integrator_name(cls) -> str:
    """The registry's name of the integrator class `cls` (its class name if unlisted)."""
    return next((key for key, known in INTEGRATORS.items() if known is cls), cls.__name__)


def integrator_class(name: str):
    """The integrator called `name`, in any letter case ("radau" is scipy's Radau)."""
    if isinstance(name, str):
        for key, cls in INTEGRATORS.items():
            if key.lower() == name.lower():
                return cls
    close = difflib.get_close_matches(str(name).lower(), [k.lower() for k in INTEGRATORS], n=1)
    hint = "".join(f" (did you mean {k!r}?)" for k in INTEGRATORS if close and k.lower() == close[0])
    raise ValueError(f"unknown integrator {name!r}{hint}; valid integrators: "
                     f"{', '.join(INTEGRATORS)}")


__all__ = ["INTEGRATORS", "AdamsPECE", "CompiledDOP853", "Trapezoidal", "integrator_class",
           "integrator_name"]
