"""The solver manager: owns the integration loop, output sampling, restarts and status.

Formulations supply the ODE and the corrections; integrators supply steps and dense output.
A failure mid-run (an exception in the model, a singular matrix, an integrator giving up, the
user pressing Ctrl-C) ends the loop and returns everything computed so far, with a `status`
and a `message` (diffrax's RESULTS): no work is lost.
"""

from __future__ import annotations

import math
import time

import numpy as np

from .formulations import formulation_class
from .integrators import integrator_class
from .problem import NumericProblem
from .results import SimulationResult


def output_times(t0: float, t_end: float, output_step: float | None) -> np.ndarray | None:
    """Regular output grid t0, t0 + h, …, ending exactly at t_end (None: every step)."""
    if output_step is None:
        return None
    k = math.floor((t_end - t0) / output_step + 1e-9)
    ts = t0 + output_step * np.arange(k + 1)
    if t_end - ts[-1] > 1e-9 * output_step:
        ts = np.append(ts, t_end)
    else:
        ts[-1] = t_end
    return ts


def _positive(value, what):
    x = float(value)
    if not (x > 0 and math.isfinite(x)):
        raise ValueError(f"`{what}` must be a positive number, got {value!r}")
    return x


def simulate(problem: NumericProblem, q0, v0, *, t_end: float, method: str | None = None,
             t_start: float = 0.0, rtol: float = 1e-6, atol: float = 1e-8,
             max_step: float = math.inf, output_step: float | None = None,
             integrator: str | None = None, first_step: float | None = None,
             **options) -> SimulationResult:
    """Integrate the constrained equations of motion from a consistent (q0, v0) at t_start.

    Parameters
    ----------
    method : name in `mechsim.formulations.METHODS` (default: the registry's default)
    rtol, atol : integrator tolerances
    max_step : largest step the integrator may take
    output_step : spacing of output samples (None: one sample per accepted step)
    integrator : name in `mechsim.integrators.INTEGRATORS` (default: the method's choice)
    **options : method-specific options (e.g. `alpha`, `beta` for "baumgarte")
    """
    cls = formulation_class(method)
    t_end = float(t_end)
    if not (math.isfinite(t_end) and t_end > t_start):
        raise ValueError(f"`t_end` must be a finite time after t_start = {t_start}, got {t_end!r}")
    rtol, atol = _positive(rtol, "rtol"), _positive(atol, "atol")
    max_step = _positive(max_step, "max_step") if max_step != math.inf else math.inf
    if output_step is not None:
        output_step = _positive(output_step, "output_step")
    solver_cls = integrator_class(integrator or cls.default_integrator)
    form = cls(problem, rtol, atol, **options)

    projections_before = problem.counters.projections
    start = time.perf_counter()
    ts = output_times(t_start, t_end, output_step)
    out_t, out_y = [], []
    y = form.initial_state(t_start, np.asarray(q0, float), np.asarray(v0, float))

    def make(t, y, h):
        kw = {"first_step": min(h, t_end - t)} if h else {}
        return solver_cls(form.rhs, t, y, t_end, rtol=rtol, atol=atol, max_step=max_step, **kw)

    status, message = "success", "reached t_end"
    steps = restarts = 0
    nfev_done = njev_done = nlu_done = 0
    next_out = 0
    if ts is None:
        out_t.append(t_start)
        out_y.append(y.copy())
    solver = None
    try:
        solver = make(t_start, y, first_step)
        while solver.status == "running":
            t_old, y_old = solver.t, solver.y.copy()
            msg = solver.step()
            if solver.status == "failed":
                status, message = "failed", f"integrator stopped at t = {solver.t:.9g}: {msg}"
                break
            steps += 1
            t_new, y_new = solver.t, solver.y
            corrected = form.after_step(t_new, y_new)
            y_here = y_new if corrected is None else corrected
            if ts is None:
                out_t.append(t_new)
                out_y.append(y_here.copy())
            else:
                dense = None
                while next_out < len(ts) and ts[next_out] <= t_new:
                    tk = ts[next_out]
                    if tk == t_new or tk == t_old:
                        yk = y_here if tk == t_new else y_old
                    else:
                        dense = dense or solver.dense_output()
                        yk = dense(tk)
                    out_t.append(tk)
                    out_y.append(np.array(yk, float))
                    next_out += 1
            if corrected is not None and solver.status == "running":
                nfev_done += solver.nfev
                njev_done += int(getattr(solver, "njev", 0))
                nlu_done += int(getattr(solver, "nlu", 0))
                restarts += 1
                solver = make(t_new, corrected, solver.step_size)
    except KeyboardInterrupt:
        status, message = "interrupted", "interrupted by the user"
    except (ArithmeticError, ValueError, np.linalg.LinAlgError, RuntimeError) as exc:
        t_fail = out_t[-1] if out_t else t_start
        status, message = "failed", f"{type(exc).__name__} after t = {t_fail:.9g}: {exc}"

    wall = time.perf_counter() - start
    c = problem.counters
    stats = {
        "method": cls.name,
        "integrator": solver_cls.__name__,
        "steps": steps,
        "rejected_steps": None,    # scipy's OdeSolver does not expose its rejections
        "rhs_evaluations": nfev_done + (solver.nfev if solver is not None else 0),
        "jacobian_evaluations": njev_done + int(getattr(solver, "njev", 0)),
        "lu_decompositions": nlu_done + int(getattr(solver, "nlu", 0)),
        "restarts": restarts,
        "projections": c.projections - projections_before,
        "partitions": 0,
        "wall_time": wall,
    }
    n_out = len(out_t)
    ys = np.array(out_y).reshape(n_out, -1)
    qs = np.empty((n_out, problem.n))
    vs = np.empty((n_out, problem.n))
    for i in range(n_out):
        qs[i], vs[i] = form.state(out_t[i], ys[i])
    return SimulationResult(np.array(out_t), qs, vs, problem.coordinate_names,
                            problem=problem, status=status, message=message, stats=stats,
                            singular_passages=form.singular_passages, switches=form.switches)
