"""A check of `mechsim.integrators.adapters` against the scipy it runs with.

For each of scipy's integrators, y'' = −y is integrated to t = 1; after the step that
passes t = 0.4 the state is moved by δ = 1e-3 through `correct_in_place` and the run goes
on. The end state must match the exact solution through the moved state, within a few
hundred times the tolerance: an adapter that left the state or the history alone would
miss it by about δ. Run as `python -m mechsim.integrators.adapter_check`; it prints one line
per integrator and exits 1 if any fails.
"""

from __future__ import annotations

import sys

import numpy as np
from scipy.integrate import BDF, DOP853, LSODA, RK23, RK45, Radau

from .adapters import correct_in_place

RTOL, ATOL = 1e-9, 1e-12
SHIFT = np.array([1e-3, -1e-3])


def _exact(t, t0, y0):
    c, s = np.cos(t - t0), np.sin(t - t0)
    return np.array([c * y0[0] + s * y0[1], -s * y0[0] + c * y0[1]])


def check_one(cls) -> tuple[bool, str]:
    """(passed, what happened) for one scipy integrator class."""
    solver = cls(lambda t, y: np.array([y[1], -y[0]]), 0.0, np.array([1.0, 0.0]), 1.0,
                 rtol=RTOL, atol=ATOL)
    moved_at, steps_after = None, 0
    while solver.status == "running":
        solver.step()
        if moved_at is None and solver.t > 0.4 and solver.status == "running":
            if not correct_in_place(solver, solver.y + SHIFT):
                return False, "declined (the solver's layout is not the one expected)"
            moved_at, moved = solver.t, solver.y.copy()
        elif moved_at is not None:
            steps_after += 1
    if moved_at is None or solver.status != "finished":
        return False, f"did not finish ({solver.status})"
    err = float(np.max(np.abs(solver.y - _exact(1.0, moved_at, moved))))
    ok = err < 300 * (RTOL + ATOL) and steps_after >= 1
    return ok, f"moved at t = {moved_at:.3f}, {steps_after} steps after, end error {err:.2e}"


def main() -> int:
    import scipy
    failed = 0
    for cls in (RK23, RK45, DOP853, Radau, BDF, LSODA):
        ok, what = check_one(cls)
        failed += not ok
        print(f"scipy {scipy.__version__} {cls.__name__:7s} {'ok  ' if ok else 'FAIL'} {what}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
