"""Kinematic analysis and inverse dynamics of a fully driven mechanism (0 degrees of freedom).

Where the drivers fix every degree of freedom the motion is not integrated but solved at
each output time (or at the times a driver's law reaches given values: over the driver's
range) from the constraints alone:

    Φ(q, t) = 0  (Newton),   Φ_q v = −Φ_t,   Φ_q q̈ = γ,

and the driver efforts and joint reactions follow from M q̈ + Φ_qᵀ λ = Q (`SimulationResult`
answers for them as for a simulation). Each time's Newton starts from the previous one's
Taylor prediction q + h v + h²/2 q̈ (the branch the mechanism moves on); a step whose
Newton does not converge, or corrects the prediction by more than a tenth of the motion it
predicted (it may have jumped to the other assembly branch), is taken in halves, down to
1/2¹² of the output step. Where Φ_q is singular (a driven change-point four-bar with all
its bars aligned) the drivers do not decide the branch: the analysis records the passage
(det Φ_q changing sign between two samples, or σ_min/σ_max under `SINGULAR` at one) and
says so in its message.
"""

from __future__ import annotations

import numbers

import time

import numpy as np

from ..build import sensitivity_model
from ..linalg import dense
from ..problem.sensitivity import Sensitivities
from ..linalg.newton import newton
from ..records import SingularPassage, Status
from ..threads import in_run_threads

# A Newton correction beyond this share of the predicted motion sends the step to halves.
JUMP = 0.1
# At most this many halvings of an output step.
MAX_HALVINGS = 12
# σ_min/σ_max of Φ_q below which a configuration counts as singular.
SINGULAR = 1e-6


class KinematicsError(ValueError):
    """The mechanism cannot be analysed kinematically (it has degrees of freedom left)."""


def _solve(J, b):
    """J⁺ b (exact for a square nonsingular J, least squares for redundant constraints)."""
    if J.shape[0] == J.shape[1]:
        try:
            return dense.solve(J, b)
        except np.linalg.LinAlgError:
            pass
    return np.linalg.lstsq(J, b, rcond=None)[0]


class _Kinematics:
    """The state at a time: (q, v, q̈) on the constraints."""

    def __init__(self, problem, tol):
        self.problem, self.tol = problem, tol

    def velocities(self, q, t):
        p = self.problem
        J = p.phi_q(q, t)
        v = _solve(J, -p.phi_t(q, t))
        return v, _solve(J, p.gamma(q, v, t)), J

    def positions(self, guess, t):
        p = self.problem

        def correct(q, phi, J, slow):
            return q - _solve(J, phi)

        return newton(guess, lambda q: p.position_terms(q, t), correct, self.tol, 25,
                      stall=True, extra=1)

    def advance(self, t0, state, t1, depth=0):
        """The state at t1 from the state (q, v, a) at t0, halving where needed; None where
        even the finest halves fail."""
        q, v, a = state
        h = t1 - t0
        guess = q + h * v + 0.5 * h * h * a
        done = self.positions(guess, t1)
        motion = np.max(np.abs(guess - q))
        if done.converged and np.max(np.abs(done.x - guess)) <= JUMP * motion + 1e3 * self.tol:
            v1, a1, _ = self.velocities(done.x, t1)
            return done.x, v1, a1
        if depth >= MAX_HALVINGS:
            return None
        middle = self.advance(t0, state, t0 + 0.5 * h, depth + 1)
        return None if middle is None else self.advance(t0 + 0.5 * h, middle, t1, depth + 1)


@in_run_threads
def kinematic_analysis(mech, t_end: float | None = None, output_step: float | None = None,
                       t_start: float = 0.0, over=None, tol: float = 1e-12,
                       sensitivities=None):
    """Positions, velocities and accelerations of the fully driven `mech` at t_start,
    t_start + output_step, …, t_end, or over a driver's range (`over` = (driver, values):
    the times where the driver's law reaches each value, see `times_of`), as a
    `SimulationResult` (its `accelerations()`, `driver_effort`, `joint_force`,
    `cycle_figures()` answer as for a simulation). `sensitivities`: names of Parameters
    (`mech.parameters`) whose exact sensitivities at every sample the result keeps
    (`SimulationResult.sensitivity`; `mechsim.problem.sensitivity`). Raises
    KinematicsError where the mechanism has degrees of freedom left or the arguments do
    not describe the samples or name no parameter of it."""
    from ..results import SimulationResult
    from ..run.solver import output_times
    started = time.perf_counter()
    names = sensitivity_names(mech, sensitivities)
    problem = mech.problem()
    report = mech.assemble(t=t_start)
    dof = problem.degrees_of_freedom(report.q, t_start)
    if dof:
        raise KinematicsError(f"mechanism '{mech.name}' has {dof} degree(s) of freedom left: "
                              "kinematic analysis needs drivers that fix every one; "
                              "simulate it instead")
    if over is not None:
        if t_end is not None or output_step is not None:
            raise KinematicsError("kinematics: give `t_end` and `output_step`, or `over`, "
                                  "not both")
        ts = times_of(mech, *over, t_start=t_start)
    elif not (isinstance(t_end, numbers.Real) and isinstance(output_step, numbers.Real)
              and output_step > 0 and t_end > t_start):
        raise KinematicsError(f"kinematics: need t_end > t_start and output_step > 0 (or "
                              f"`over`), got t_end = {t_end!r}, output_step = {output_step!r}")
    else:
        ts = output_times(t_start, t_end, output_step)
    ts, Q, V, A, shape, status, message = _march(_Kinematics(problem, tol), problem,
                                                 report.q, t_start, ts)
    n = len(Q)
    passages = _passages(ts, np.array(shape).reshape(n, 2))
    if passages and status == Status.SUCCESS:
        message += (f"; it passed {len(passages)} singular configuration(s) (first at t = "
                    f"{passages[0].t_min:.6g}) where the drivers do not decide the branch: it "
                    "went on along the one it moved on, and reactions and efforts there are "
                    "not unique")
    result = SimulationResult(
        ts, np.array(Q).reshape(n, problem.n), np.array(V).reshape(n, problem.n),
        problem.coordinate_names, problem=problem,
        status=status, message=message, singular_passages=passages,
        stats={"method": "kinematics", "samples": n,
               "wall_time": time.perf_counter() - started})
    if names:
        result.sensitivities = Sensitivities(
            problem, sensitivity_model(mech), ts, result.q, result.v,
            np.asarray(A, float).reshape(len(ts), problem.n), names,
            lam=lambda: result.reactions.multipliers.lam,
            blind_loads=mech.parameter_blind_loads())
        if passages:
            result.message += ("; the sensitivities are not defined at the singular "
                               "configurations (Φ_q singular there: they grow without bound "
                               "near them)")
    result.mechanism = mech
    return result


def _march(kin, problem, q0, t_start, ts):
    """The states at the times `ts` from the assembled q0 at t_start (a first step from
    t_start where the first sample lies later, as over a driver's range that does not
    start at its present value): (times reached, Q, V, A, shapes, status, message)."""
    steps = np.asarray(ts, float)
    skip = int(steps[0] != t_start)
    if skip:
        steps = np.concatenate([[t_start], steps])
    state = (q0, *kin.velocities(q0, t_start)[:2])
    Q, V, A, shape = [state[0]], [state[1]], [state[2]], [_shape(problem, q0, t_start)]
    status, message = Status.SUCCESS, "reached t_end"
    for t0, t1 in zip(steps[:-1], steps[1:]):
        state = kin.advance(t0, state, t1)
        if state is None:
            status = Status.FAILED
            message = (f"no configuration followed from t = {t0:.9g} to {t1:.9g}: the "
                       "drivers move the mechanism where it cannot assemble, or too fast for "
                       "the output step")
            break
        Q.append(state[0])
        V.append(state[1])
        A.append(state[2])
        shape.append(_shape(problem, state[0], t1))
    n = len(Q)
    return (steps[skip:n], Q[skip:], V[skip:], A[skip:], shape[skip:], status, message)


def sensitivity_names(mech, sensitivities, what="kinematics",
                      error=KinematicsError) -> list[str]:
    """The Parameter names asked for, checked against `mech.parameters` before any work
    (else `error`, its message beginning with `what`)."""
    if sensitivities is None:
        return []
    if isinstance(sensitivities, str):
        sensitivities = [sensitivities]
    try:
        asked = list(sensitivities)
    except TypeError:
        raise error(f"{what}: `sensitivities` must be a list of Parameter "
                              f"names, got {sensitivities!r:.60}") from None
    known = mech.parameters
    for name in asked:
        if not isinstance(name, str) or name not in known:
            raise error(
                f"{what}: `sensitivities` names {name!r:.60}, which is no Parameter of "
                f"mechanism '{mech.name}'; its parameters: {', '.join(known) or '(none)'}")
    blind = mech.parameter_blind() if asked else []
    if blind:
        raise error(
            f"{what}: '{blind[0]}' depends on Parameters but does not carry their "
            "derivatives (sensitivities are carried through revolute and prismatic joints and "
            "drivers); give the numbers it depends on as plain numbers")
    return list(dict.fromkeys(asked))


def times_of(mech, driver, values, t_start=0.0, horizon=1e6) -> np.ndarray:
    """The times from t_start at which `driver`'s law f(t) (the change of its joint's
    coordinate) takes each of `values` in turn: f is sampled forward (doubling the span
    up to `horizon` s) until it covers them, must be monotonic there, and is inverted by
    Brent's method. KinematicsError where it is not monotonic or does not reach them."""
    from scipy.optimize import brentq
    try:
        driver = mech.driver(driver)
    except KeyError:
        raise KinematicsError(f"kinematics: `over` names no driver of mechanism "
                              f"'{mech.name}'; drivers: "
                              f"{', '.join(d.name for d in mech.drivers) or '(none)'}") from None
    values = np.asarray(values, float).ravel()
    if values.size < 2 or not np.all(np.isfinite(values)) or \
            not (np.all(np.diff(values) > 0) or np.all(np.diff(values) < 0)):
        raise KinematicsError("kinematics: `over` needs at least two finite values, "
                              "strictly increasing or decreasing")
    span = 1.0
    while True:
        grid = t_start + np.linspace(0.0, span, 4097)
        law = driver.values_at(grid)
        rising = np.diff(law)
        if not (np.all(rising >= 0) or np.all(rising <= 0)):
            raise KinematicsError(f"kinematics: driver '{driver.name}' ({driver.expression}) "
                                  "is not monotonic where it would have to reach `over`")
        if law.min() <= values.min() and law.max() >= values.max():
            break
        span *= 2.0
        if span > horizon:
            raise KinematicsError(f"kinematics: driver '{driver.name}' ({driver.expression}) "
                                  f"does not reach {values.min():g} … {values.max():g}")
    out, sign = [], 1.0 if law[-1] >= law[0] else -1.0
    for target in values:
        k = int(np.clip(np.searchsorted(sign * law, sign * target), 1, len(grid) - 1))
        # The bracket in `value`'s own arithmetic (the grid's values may differ from it in
        # the last bit): the neighbouring interval where that puts the target there.
        fa, fb = driver.value(grid[k - 1]) - target, driver.value(grid[k]) - target
        while sign * fa > 0.0 and k > 1:
            k -= 1
            fa, fb = driver.value(grid[k - 1]) - target, fa
        while sign * fb < 0.0 and k < len(grid) - 1:
            k += 1
            fa, fb = fb, driver.value(grid[k]) - target
        a, b = grid[k - 1], grid[k]
        if sign * fa >= 0.0:          # at a (or, by round-off, just before the grid's start)
            out.append(a)
        elif sign * fb <= 0.0:        # at b (or just after the grid's end)
            out.append(b)
        else:
            out.append(brentq(lambda x: driver.value(x) - target, a, b, xtol=1e-14,
                              rtol=1e-15))
    return np.array(out)


def _shape(problem, q, t):
    """(σ_min/σ_max of Φ_q, sign of det Φ_q (0 where it is not square)) at (q, t)."""
    J = problem.phi_q(q, t)
    s = np.linalg.svd(J, compute_uv=False)
    sign = float(np.linalg.slogdet(J)[0]) if J.shape[0] == J.shape[1] else 0.0
    return (float(s[-1] / s[0]) if s.size and s[0] > 0 else 0.0), sign


def _passages(ts, shape):
    """SingularPassage records where det Φ_q changes sign between two samples or runs of
    samples have σ_min/σ_max under `SINGULAR` (shape: (N, 2) of `_shape`)."""
    ratios, signs = shape[:, 0], shape[:, 1]
    low = ratios < SINGULAR
    crossed = np.zeros(len(ts), dtype=bool)
    crossed[:-1] = (signs[:-1] * signs[1:]) < 0
    out, k = [], 0
    while k < len(ts):
        if not (low[k] or crossed[k]):
            k += 1
            continue
        j = k + 1 if crossed[k] and not low[k] else k
        while j + 1 < len(ts) and (low[j + 1] or crossed[j]):
            j += 1
        i = k + int(np.argmin(ratios[k:j + 1]))
        out.append(SingularPassage(float(ts[k]), float(ts[j]), float(ratios[i]),
                                   t_min=float(ts[i])))
        k = j + 1
    return out
