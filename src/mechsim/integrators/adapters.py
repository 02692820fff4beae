"""Everything mechsim does with the private state of scipy's integrators, in one place.

scipy's `OdeSolver` has no public way to replace the state of a running solver. After a
projection onto the constraints mechsim puts the projected state into the running solver
where that is sound, keeping its history (a projected multistep method) instead of
restarting it at order one after every step. That writes attributes scipy does not
document: `y` and `f` of the Runge–Kutta methods and Radau, the backward differences `D`
of BDF, ODEPACK's work array of LSODA (whose layout ODEPACK does document). Each adapter
checks the layout it relies on and declines (the manager then restarts the solver) where
it does not find it, so a scipy release that changes them costs speed, not correctness.
The same holds for a constant shift of the state (`shift_in_place`: a partition whose
reference moved), and a fresh Adams solver takes the history of the one it replaces
(`warm_start`).
`tests/test_adapters.py` runs `mechsim.integrators.adapter_check` against the oldest and
the newest scipy that pyproject allows.
"""

from __future__ import annotations

import numpy as np
from scipy.integrate import BDF, DOP853, LSODA, RK23, RK45, Radau

from .adams import AdamsPECE

# scipy's undocumented names this module relies on, each checked where it is used: LSODA's
# wrapped `scipy.integrate.ode` and, on that, the state it passes to ODEPACK and its
# integrator (whose `rwork` is ODEPACK's documented work array).
LSODA_ODE, ODE_STATE, ODE_INTEGRATOR = "_lsoda_solver", "_y", "_integrator"


def correct_in_place(solver, y) -> bool:
    """Put a projected state into a running integrator without restarting it, where that is
    sound: the one-step methods (RK, Radau) need only y and f(t, y), Radau's previous
    collocation polynomial serving as before for its Newton start; the multistep methods
    (Adams, BDF, LSODA) keep their history with the newest point replaced (a projected
    multistep method)."""
    if isinstance(solver, AdamsPECE):
        solver.correct(y)
        return True
    y = np.array(y, float)
    if isinstance(solver, BDF):
        # Its history is the backward differences ∇ᵏyₙ (rows 0 … order + 1 of D), each of
        # which holds yₙ with coefficient 1: replacing yₙ shifts them all by the correction
        # and keeps the older points (a projected multistep method, as for Adams). Row 0
        # is yₙ itself (to round-off): the layout is checked by that.
        D = getattr(solver, "D", None)
        order = getattr(solver, "order", None)
        if not isinstance(D, np.ndarray) or not isinstance(order, (int, np.integer)) or \
                D.ndim != 2 or D.shape[0] < order + 2 or \
                not np.allclose(D[0], solver.y, rtol=1e-12, atol=1e-300):
            return False
        D[:order + 2] += y - solver.y
        solver.y = y
        return True
    if isinstance(solver, LSODA):
        # ODEPACK's documented workspace: the Nordsieck array YH starts at RWORK(21), its
        # first column the current y (checked); replacing it keeps the history (as for BDF).
        rwork = lsoda_workspace(solver)
        ode = getattr(solver, LSODA_ODE, None)
        n = solver.y.size
        if rwork is None or rwork.size < 20 + n or not hasattr(ode, ODE_STATE) or \
                not np.allclose(rwork[20:20 + n], solver.y, rtol=1e-15, atol=0.0):
            return False
        rwork[20:20 + n] = y
        solver.y = y
        setattr(ode, ODE_STATE, y.copy())
        return True
    if isinstance(solver, (RK23, RK45, DOP853, Radau)):
        f = getattr(solver, "f", None)
        if not isinstance(f, np.ndarray) or f.shape != y.shape:
            return False
        solver.y = y
        solver.f = solver.fun(solver.t, y)
        return True
    return False


def shift_in_place(solver, delta) -> bool:
    """Move a running integrator's state by the constant `delta` (the same motion in
    coordinates measured from another origin) without restarting it: its derivatives and
    history of derivatives stand; of the history of states only what holds y itself moves
    (BDF's D[0], the Nordsieck array's first column). Radau's Newton start is a polynomial
    in the old coordinates: False there (the caller restarts), as for anything unknown."""
    delta = np.asarray(delta, float)
    y = solver.y + delta
    if isinstance(solver, AdamsPECE):
        solver.correct(y)
        return True
    if isinstance(solver, BDF):
        D = getattr(solver, "D", None)
        if not isinstance(D, np.ndarray) or D.ndim != 2 or \
                not np.allclose(D[0], solver.y, rtol=1e-12, atol=1e-300):
            return False
        D[0] += delta
        solver.y = y
        return True
    if isinstance(solver, LSODA):
        return correct_in_place(solver, y)       # replaces y in the Nordsieck array only
    if isinstance(solver, (RK23, RK45, DOP853)):
        if getattr(solver, "f", None) is None or solver.y.shape != delta.shape:
            return False
        solver.y = y
        return True
    return False


def bound_read_at_start(solver_cls) -> bool:
    """Whether the integrator reads `max_step` only when it starts (LSODA passes it to
    ODEPACK once): a new bound then needs a restart."""
    return issubclass(solver_cls, LSODA)


def lsoda_workspace(solver):
    """LSODA's RWORK array (ODEPACK's documented layout), or None."""
    ode = getattr(solver, LSODA_ODE, None)
    return getattr(getattr(ode, ODE_INTEGRATOR, None), "rwork", None)


def retune(solver, rtol, atol) -> bool:
    """Give a running integrator new tolerances for its next steps without restarting it,
    where its steps read them afresh: scipy's explicit Runge–Kutta methods and mechsim's
    Adams (`rtol`, `atol`; the compiled DOP853 keeps its own copy of atol, renewed by its
    `tolerances_changed`). False elsewhere (BDF and Radau derive Newton's tolerance from
    rtol once, LSODA keeps them in ODEPACK's arrays): the caller restarts the solver."""
    if not isinstance(solver, (RK23, RK45, DOP853, AdamsPECE)) or \
            not (hasattr(solver, "rtol") and hasattr(solver, "atol")):
        return False
    solver.rtol, solver.atol = float(rtol), float(atol)
    changed = getattr(solver, "tolerances_changed", None)
    if changed is not None:
        changed()
    return True


def proposed_step(solver):
    """The step size the integrator proposes next (scipy's RK, BDF, Radau: h_abs; Adams: h;
    LSODA: HCUR, RWORK(12))."""
    h = getattr(solver, "h_abs", None) or getattr(solver, "h", None)
    if h is None and isinstance(solver, LSODA):
        rwork = lsoda_workspace(solver)
        h = float(rwork[11]) if rwork is not None and rwork.size > 11 else None
    return h or solver.step_size


def warm_start(solver, old, form, past, order=None, step=None) -> int:
    """After a change of coordinates at solver.t, give a fresh Adams solver the history the
    old one had, re-expressed in the new coordinates: y' at the last accepted states
    `past` ((t, q, v), oldest first, the present one excluded) from `form.derivative`, up
    to the old order (or `order`), going on with the old solver's next step (or `step`).
    Returns the right-hand sides spent (0 where not possible: then the solver starts from
    order 1 as usual)."""
    if not past:
        return 0
    order = old.order if order is None else min(order, old.order)
    recent = list(past)[-order:]
    try:
        fs = [form.derivative(t, q, v) for t, q, v in recent]
    except NotImplementedError:
        return 0
    if not all(np.all(np.isfinite(f)) for f in fs):
        return len(fs)
    solver.seed_history([t for t, _, _ in recent], fs, order,
                        proposed_step(old) if step is None else step)
    return len(fs)
