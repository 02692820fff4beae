"""A check of `mechsim.integrators.adapters` against the scipy it runs with.

For each of scipy's integrators, y'' = −y is integrated to t = 1; after the step that
passes t = 0.4 the state is moved by δ = 1e-3 through `correct_in_place` and the run goes
on. The end state must match the exact solution through the moved state, within a few
hundred times the tolerance: an adapter that left the state or the history alone would
miss it by about δ. Likewise `shift_in_place`: a pendulum θ'' = −sin θ moved by 2π in θ
mid-run (the same motion) must end 2π from a run left alone (Radau declines, restarting).
Run as `python -m mechsim.integrators.adapter_check`; it prints one line per integrator and
check, and exits 1 if any fails.
"""

from __future__ import annotations

import sys

import numpy as np
from scipy.integrate import BDF, DOP853, LSODA, RK23, RK45, Radau

from .adapters import correct_in_place, shift_in_place

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


def _pendulum(cls, shift_at=None, rtol=RTOL, atol=ATOL):
    """θ'' = −sin θ from (1, 0) to t = 2 by `cls`; with `shift_at`, θ moved by 2π in place
    after the step passing that time. Returns (solver, whether the shift was taken)."""
    solver = cls(lambda t, y: np.array([y[1], -np.sin(y[0])]), 0.0, np.array([1.0, 0.0]),
                 2.0, rtol=rtol, atol=atol)
    taken = None
    while solver.status == "running":
        solver.step()
        if shift_at is not None and taken is None and solver.t > shift_at and \
                solver.status == "running":
            taken = shift_in_place(solver, np.array([2.0 * np.pi, 0.0]))
            if not taken:
                break
    return solver, taken


def check_shift(cls) -> tuple[bool, str]:
    """(passed, what happened) of `shift_in_place` for one scipy integrator class."""
    solver, taken = _pendulum(cls, shift_at=0.7)
    if not taken:
        return cls is Radau, "declined (a restart follows)"
    if solver.status != "finished":
        return False, f"did not finish ({solver.status})"
    reference, _ = _pendulum(DOP853, rtol=1e-13, atol=1e-15)
    err = float(np.max(np.abs(solver.y - reference.y - [2.0 * np.pi, 0.0])))
    return err < 300 * (RTOL + ATOL) * 2 * np.pi, f"shifted by 2π, end error {err:.2e}"


def main() -> int:
    import scipy
    failed = 0
    for cls in (RK23, RK45, DOP853, Radau, BDF, LSODA):
        for name, check in (("moved", check_one), ("shifted", check_shift)):
            ok, what = check(cls)
            failed += not ok
            print(f"scipy {scipy.__version__} {cls.__name__:7s} {name:7s} "
                  f"{'ok  ' if ok else 'FAIL'} {what}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
