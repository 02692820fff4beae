"""The solver manager: owns the integration loop, output sampling, restarts, the singularity
monitor and the status.

Formulations supply the ODE and the corrections; integrators supply steps and dense output.
A failure mid-run (an exception in the model, a singular matrix, an integrator giving up, the
user pressing Ctrl-C) ends the loop and returns everything computed so far, with a `status`
and a `message` (diffrax's RESULTS): no work is lost.
"""

from __future__ import annotations

import collections
import math
import os
import time

import numpy as np

from .formulations import METHODS, formulation_class
from .formulations.bridge import SPAN
from .formulations.full import settle_samples
from .formulations.monitor import SingularityMonitor
from .integrators import AdamsPECE, integrator_class
from .integrators.adapters import correct_in_place, proposed_step, shift_in_place
from .options import Option, check_all, unknown_names
from .problem import NumericProblem
from .results import SimulationResult, Switch
from .results.result import WorkRecord
from .results.work import WorkIntegral


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


# A run stops as stuck when this many steps together advance less than this fraction of
# its span (LU alone at the flexible four-bar's passage: 2000 steps of 2e-12–7e-12 s).
STALL_STEPS = 2000
STALL_SPAN = 1e-7
# A step that left the assembly branch (`Formulation.keeps_branch`) is taken again at a
# quarter of its length, up to this many times in a row, by the methods that resolve
# passages; then it stands, and the run says so.
BRANCH_RETRIES = 6
# What a formulation raises when a run cannot go on: the run stops with its partial result.
FAILURES = (ArithmeticError, ValueError, np.linalg.LinAlgError, RuntimeError)


class NonFiniteState(RuntimeError):
    """The motion became infinite or NaN: the run stops there with its partial result."""


def check_finite(problem, t, q, v) -> None:
    """NonFiniteState where q or v holds an infinite or NaN value, naming the coordinate
    and, where one is the cause, the driver whose prescribed motion is not finite there."""
    for name, x in (("position", q), ("velocity", v)):
        bad = np.flatnonzero(~np.isfinite(x))
        if bad.size:
            break
    else:
        return
    raise NonFiniteState(f"the motion became non-finite at t = {t:.9g} ({name} of "
                         f"'{problem.coordinate_names[bad[0]]}' = {x[bad[0]]})"
                         f"{troubled_drivers(problem, (t,))}")


# A driver moving faster than this (rad/s or m/s) is named where a run fails.
DRIVER_RATE_LIMIT = 1e8


def troubled_drivers(problem, times) -> str:
    """"; driver 'd' …" for each driver whose law at one of `times` is undefined, not finite
    (or beyond 1e100) or changing faster than `DRIVER_RATE_LIMIT`: the likely cause of a
    failed run; "" where there is none."""
    out = []
    for driver, law in problem.driver_laws:
        for t in times:
            dt = 1e-9 * max(1.0, abs(t))
            try:
                value, ahead = law.value(t=t), law.value(t=t + dt)
            except (ArithmeticError, ValueError) as exc:
                out.append(f"driver '{driver}' prescribes {law.text}, undefined at "
                           f"t ≈ {t:.9g} ({exc})")
                break
            if not (abs(value) < 1e100 and abs(ahead) < 1e100):
                out.append(f"driver '{driver}' prescribes {law.text} = {value:.3g} at "
                           f"t = {t:.9g}")
                break
            if abs(ahead - value) > DRIVER_RATE_LIMIT * dt:
                out.append(f"driver '{driver}' prescribes {law.text}, changing at "
                           f"{(ahead - value) / dt:.3g}/s at t = {t:.9g}")
                break
    return "".join(f"; {o}" for o in out)


def _warm_start(solver, old, form, past, order=None, step=None) -> int:
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


def _bridge_passage(form, bridge, monitor, solver, t, q, v, max_step, t_end):
    """Approach and cross a singular passage ahead with the formulation's bridge
    (`mechsim.formulations.bridge`): its `Crossing` when crossed, else None,
    with the next step limited to the landing point while approaching. A crossing that
    would end after t_end is not taken: the formulation steps to the end on its own."""
    s, rate = monitor.last * monitor.peak, monitor.rate * monitor.peak
    h_free = proposed_step(solver)
    if not h_free:                   # a restarted integrator that has not stepped yet
        return None
    h_next = min(h_free, max_step)
    plan = bridge.plan(s, rate, t, h_next, max_step_bound=h_free >= max_step)
    if plan is not None and plan[0] == "cross":
        if t + SPAN * (plan[1] - t) >= t_end:
            bridge.stand_down()
            return None
        crossed = bridge.cross(t, q, v, plan[1], lambda qk, tk: monitor.measure(qk, tk)[0],
                               t_floor=monitor.clear_since)
        if crossed is not None and crossed.t_b >= t_end:
            bridge.stand_down()
            return None
        if crossed is not None:
            return crossed
        plan = bridge.plan(s, rate, t, h_next, h_free >= max_step)   # land closer, or stand down
    if plan is not None and plan[0] == "land":
        solver.max_step = min(solver.max_step, plan[1])
    return None


# What `simulate` takes besides `t_end`, `method` and the method's own options (each
# formulation's `options`), checked before any work (`mechsim.options`).
SETTINGS = {
    "t_start": Option.real(0.0),
    "rtol": Option.positive(1e-6, high=0.1),
    "atol": Option.positive(1e-8),
    "max_step": Option.positive(math.inf, infinite=True),
    "output_step": Option.positive(None, optional=True),
    "first_step": Option.positive(None, optional=True),
    "singular_thresholds": Option((0.07, 0.14), "pair"),
    "max_steps": Option.integer(None, low=1, optional=True),
    "h": Option.positive(None, optional=True),
    "work": Option.flag(True),
}
# An output grid is refused where its arrays would take more than this share of the
# machine's memory.
OUTPUT_MEMORY_SHARE = 0.5


def check_settings(n, t_end, method, integrator, settings: dict, options: dict):
    """The formulation class, the integrator class and every setting of a run of a problem
    with `n` coordinates checked, before any work: a ValueError names the argument and
    says what is wrong (an unknown name gets the closest valid one, or the methods that
    take it). Returns (formulation class, integrator class, t_end, settings)."""
    cls = formulation_class(method)
    valid = {**SETTINGS, **cls.options, "t_end": None, "method": None, "integrator": None}
    message = unknown_names(options, valid, f"simulate (method {cls.name!r})")
    if message:
        elsewhere = {name: [m for m, c in METHODS.items() if name in c.options]
                     for name in options if name not in valid}
        message += "".join(f"; {name!r} is an option of method(s) {', '.join(ms)}"
                           for name, ms in elsewhere.items() if ms)
        raise ValueError(message)
    checked = check_all(SETTINGS, settings)
    for name, value in options.items():
        cls.options[name].check(value, name, f"method {cls.name!r}")
    t0 = checked["t_start"]
    t_end = Option.real(None).check(t_end, "t_end")
    if not t_end > t0:
        raise ValueError(f"`t_end` must be after t_start = {t0}, got {t_end!r}")
    solver_cls = integrator_class(integrator or cls.default_integrator)
    if checked["h"] is None and solver_cls.__name__ == "Trapezoidal":
        raise ValueError(f"method {cls.name!r} steps at a fixed size: give `h`, e.g. h=1e-3")
    if checked["output_step"] is not None:
        _check_output_size(n, t_end - t0, checked["output_step"])
    return cls, solver_cls, t_end, checked


def check_simulate_arguments(n, t_end, method=None, options=None):
    """`check_settings` for the keyword arguments as `Mechanism.simulate` takes them."""
    options = dict(options or {})
    integrator = options.pop("integrator", None)
    settings = {k: options.pop(k) for k in list(options) if k in SETTINGS}
    return check_settings(n, t_end, method, integrator, settings, options)


def _check_output_size(n, span, step):
    """Refuse an output grid whose samples of n coordinates would not fit in memory."""
    samples = math.floor(span / step) + 2
    size = samples * (1 + 2 * n) * 8.0
    try:
        memory = os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        memory = 16 * 2.0 ** 30
    if size > OUTPUT_MEMORY_SHARE * memory:
        raise ValueError(f"`output_step` = {step:g} over {span:g} s asks for {samples:.3g} "
                         f"samples of {n} coordinates and velocities, "
                         f"{size / 2**30:.3g} GiB, more than {OUTPUT_MEMORY_SHARE:.0%} of this "
                         f"machine's {memory / 2**30:.3g} GiB; choose a larger output_step")


def check_initial_state(problem, q0, v0, t0):
    """(q0, v0) as float arrays of the problem's size, finite and consistent with the
    constraints (positions to 1e-6, velocities to 1e-6 of their scale), or a ValueError
    saying which and how to fix it."""
    n = problem.n
    out = []
    for name, x in (("q0", q0), ("v0", v0)):
        try:
            a = np.array(x, dtype=float).reshape(-1)
        except (TypeError, ValueError):
            raise ValueError(f"`{name}` must be {n} numbers, got {x!r:.80}") from None
        if a.size != n:
            raise ValueError(f"`{name}` must have {n} entries (the coordinates "
                             f"{', '.join(problem.coordinate_names[:6])}…), got {a.size}")
        bad = np.flatnonzero(~np.isfinite(a))
        if bad.size:
            raise ValueError(f"`{name}` must be finite, got {a[bad[0]]} for "
                             f"'{problem.coordinate_names[bad[0]]}'")
        out.append(a)
    q0, v0 = out
    if problem.m:
        phi = problem.phi(q0, t0)
        if np.max(np.abs(phi)) > 1e-6 * max(1.0, np.max(np.abs(q0))):
            raise ValueError(f"`q0` does not satisfy the constraints: residual "
                             f"{problem.worst_constraint(phi)}; start from an assembled "
                             "state (Mechanism.assemble)")
        r = problem.phi_q(q0, t0) @ v0 + problem.phi_t(q0, t0)
        if np.max(np.abs(r)) > 1e-6 * max(1.0, np.max(np.abs(v0))):
            raise ValueError(f"`v0` does not satisfy the velocity constraints: residual "
                             f"{problem.worst_constraint(r)}; start from an assembled "
                             "state (Mechanism.assemble)")
    return q0, v0


def simulate(problem: NumericProblem, q0, v0, *, t_end: float, method: str | None = None,
             t_start: float = 0.0, rtol: float = 1e-6, atol: float = 1e-8,
             max_step: float = math.inf, output_step: float | None = None,
             integrator: str | None = None, first_step: float | None = None,
             singular_thresholds: tuple[float, float] = (0.07, 0.14),
             max_steps: int | None = None, h: float | None = None, work: bool = True,
             **options) -> SimulationResult:
    """Integrate the constrained equations of motion from a consistent (q0, v0) at t_start.

    Parameters
    ----------
    method : name in `mechsim.formulations.METHODS` (default "hybrid")
    rtol, atol : integrator tolerances
    max_step : largest step the integrator may take
    output_step : spacing of output samples (None: one sample per accepted step)
    integrator : name in `mechsim.integrators.INTEGRATORS` (default: the method's choice)
    singular_thresholds : (enter, leave) for σ_min/σ_max of Φ_q M^{-1/2} relative to its
        peak in the run: a singular passage is recorded while the ratio is below `enter`
        until it rises above `leave` (see `mechsim.formulations.monitor`)
    max_steps : stop (status "failed", partial result kept) after this many steps
    h : fixed step for the fixed-step methods ("ss-newmark"); required by them
    work : integrate the work of each damper, load, damped beam and driver along every step
        (`mechsim.results.work`), so the energy balance measures the solver, not the output
        spacing; it costs 9 evaluations of the powers per step, and only mechanisms with such
        forces pay it. False: the balance integrates the power over the output samples
    **options : method-specific options (e.g. `alpha`, `beta` for "baumgarte")
    """
    cls, solver_cls, t_end, checked = check_settings(
        problem.n, t_end, method, integrator,
        dict(t_start=t_start, rtol=rtol, atol=atol, max_step=max_step, output_step=output_step,
             first_step=first_step, singular_thresholds=singular_thresholds,
             max_steps=max_steps, h=h, work=work), options)
    t_start, rtol, atol = checked["t_start"], checked["rtol"], checked["atol"]
    max_step, output_step, h = checked["max_step"], checked["output_step"], checked["h"]
    max_steps, singular_thresholds = checked["max_steps"], checked["singular_thresholds"]
    first_step = checked["first_step"] if h is None else h
    q0, v0 = check_initial_state(problem, q0, v0, t_start)
    problem.start_run()
    fully_driven = problem.m >= problem.n and problem.degrees_of_freedom(q0, t_start) == 0
    if cls.needs_freedom and fully_driven:
        # A fully driven mechanism: no independent coordinate to integrate. Its motion is
        # the drivers' kinematics, which the projection method follows on its branch with
        # the integrator's error control (a partitioned run took one step for the whole
        # run and landed on the mirror branch).
        form = METHODS["projection"](problem, rtol, atol)
        form.switches.append(Switch(t_start, cls.name, form.name, "0 degrees of freedom: the "
                                    "drivers' motion, followed by the projection method"))
    else:
        form = cls(problem, rtol, atol, **options)
    monitor = form.monitor = SingularityMonitor(problem, *singular_thresholds)

    counters = problem.counters
    before = {k: getattr(counters, k) for k in ("projections", "partitions", "switches",
                                                 "factorizations", "constraint_terms")}
    start = time.perf_counter()
    ts = output_times(t_start, t_end, output_step)
    out_t, out_q, out_v = [], [], []
    # The work of each non-conservative channel at the output samples, integrated along the
    # steps (rows: out_t's first len(work_at) samples).
    channels = problem.work_channels if checked["work"] else []
    work = None
    if channels:
        energy = (problem.kinetic_energy(q0, v0) + abs(problem.potential_energy(q0))
                  + problem.strain_energy(q0))
        work = WorkIntegral(channels, problem.work_rates, rtol, float(energy), t_end - t_start)
    work_at = []

    def bridge_samples(tk, Y):
        """A bridge's output samples, onto the constraints as the steps' are."""
        Q, V = _split(np.array(Y), problem.n)
        settle_samples(problem, tk, Q, V, max(10.0 * rtol, 100.0 * atol))
        return Q, V

    def add_work(a, b, states, times):
        if work is not None:
            W = work.add(a, b, states, times)
            if W is not None:
                work_at.extend(W)
    y = form.initial_state(t_start, q0, v0)
    monitor.observe(t_start, q0, v0)

    def make(t, y, step, bound=max_step):
        step = first_step if h is not None else step      # a fixed step stays fixed
        kw = {"first_step": min(step, t_end - t, bound)} if step else {}
        solver = solver_cls(form.integrand, t, y, t_end, rtol=rtol, atol=atol, max_step=bound, **kw)
        if isinstance(solver, AdamsPECE):
            # Project inside the step, before its last evaluation: after_step then finds
            # the state on the constraints and the projection costs no extra evaluation.
            solver.project = getattr(form, "project_now", None)
        return solver

    # scipy's RK, Radau and BDF and the Adams method read `max_step` at every step, so the
    # step bounds of a formulation (the hybrid ahead of a singularity) and of the passage
    # bridge's landing apply at once; LSODA takes its bound only when it starts, so a new
    # bound restarts it.
    bound_at_start = max_step if solver_cls.__name__ == "LSODA" else None

    def record(t, q, v):
        check_finite(problem, t, q, v)
        out_t.append(t)
        out_q.append(np.array(q, float))
        out_v.append(np.array(v, float))

    def record_within(t_lo, t_hi, through, values, states):
        """Record the output samples in (t_lo, t_hi), or (t_lo, t_hi] with `through`, from
        one call of the interpolant `values(times)` and one of `states(times, Y) -> (Q, V)`
        (rows: the samples)."""
        nonlocal next_out
        first = next_out
        while next_out < len(ts) and (ts[next_out] < t_hi or through and ts[next_out] == t_hi):
            next_out += 1
        inside = np.array([tk for tk in ts[first:next_out] if tk > t_lo])
        if not inside.size:
            return
        Y = np.atleast_2d(values(inside).T)
        try:
            Q, V = states(inside, Y)
        except FAILURES:
            # One by one: the samples before the one that fails are kept (a run that
            # cannot go on returns them).
            for k in range(inside.size):
                q, v = states(inside[k:k + 1], Y[k:k + 1])
                record(inside[k], q[0], v[0])
            return
        for tk, q, v in zip(inside, Q, V):
            record(tk, q, v)

    status, message, exception = "success", "reached t_end", None
    steps = restarts = rejected = corrections = retries = 0
    nfev_done = njev_done = nlu_done = 0
    next_out = 0
    if ts is None or ts[0] == t_start:
        record(t_start, q0, v0)
        next_out = 1
        work_at.append(np.zeros(len(channels)))
    solver = None
    t_reached = t_start
    # Stuck (at a singular configuration the formulation cannot pass): stop there with the
    # partial result instead of grinding on.
    recent = collections.deque([t_start], maxlen=STALL_STEPS + 1)
    stalled = STALL_SPAN * (t_end - t_start)
    # The last accepted states (t, q, v), for a warm Adams restart after a change of
    # coordinates (after a bridge: the states the bridge was built on).
    keep_past = issubclass(solver_cls, AdamsPECE)
    past = collections.deque(maxlen=AdamsPECE.max_order_limit + 1)
    bridge = getattr(form, "bridge", None)
    bridges = 0
    bridge_evals_before = bridge.evaluations if bridge is not None else 0
    bridge_over_before = bridge.over_tolerance if bridge is not None else 0

    def retire(old):
        nonlocal nfev_done, njev_done, nlu_done, rejected
        nfev_done += old.nfev
        njev_done += int(getattr(old, "njev", 0))
        nlu_done += int(getattr(old, "nlu", 0))
        rejected += int(getattr(old, "n_rejected", 0))

    try:
        solver = make(t_start, y, first_step)
        while solver.status == "running":
            if bound_at_start is not None:
                # Restart only where the bound decides the next step: a tighter one below
                # the step LSODA would take, or a looser one where the old bound held it.
                want = getattr(solver, "max_step", bound_at_start)
                h_next = proposed_step(solver) or 0.0
                if (want < bound_at_start and h_next > want) or \
                        (want > bound_at_start and h_next >= 0.9 * bound_at_start):
                    bound_at_start = want
                    retire(solver)
                    restarts += 1
                    solver = make(solver.t, solver.y, min(h_next, want) or None, want)
            t_old, y_old = solver.t, solver.y.copy()
            msg = solver.step()
            if solver.status == "failed":
                status, message = "failed", f"integrator stopped at t = {solver.t:.9g}: {msg}"
                break
            kept = form.keeps_branch(solver.t, solver.y)
            if not kept and form.resolves_passages and h is None and \
                    retries < BRANCH_RETRIES:
                # Left the branch within the step (or crossed a singular configuration
                # unseen): take it again, shorter, from its start. A method that does not
                # resolve passages crosses them so, and says so instead.
                retries += 1
                retire(solver)
                rejected += 1
                restarts += 1
                short = 0.25 * (solver.t - t_old)
                solver = make(t_old, y_old, short, min(max_step, short))
                continue
            retries = 0
            steps += 1
            if max_steps is not None and steps > max_steps:
                status, message = "failed", (f"step limit max_steps = {max_steps} reached at "
                                             f"t = {solver.t:.9g}")
                break
            recent.append(solver.t)
            if len(recent) == recent.maxlen and solver.t - recent[0] < stalled:
                status, message = "failed", (
                    f"the steps collapsed: {recent.maxlen - 1} steps advanced only "
                    f"{solver.t - recent[0]:.2g} s up to t = {solver.t:.9g}")
                break
            t_new, y_new = solver.t, solver.y
            # The step's interpolant, built at most once (scipy's RK methods spend extra
            # right-hand sides on each `dense_output()` call) and shared by the output
            # samples and the monitor's search for a minimum inside the step.
            interpolant = []

            def dense(tk):
                if not interpolant:
                    interpolant.append(solver.dense_output())
                return interpolant[0](tk)

            recorded = len(out_t)
            if ts is not None:
                record_within(t_old, t_new, False, dense, form.states)
            records_end = ts is None or (next_out < len(ts) and ts[next_out] == t_new)
            add_work(t_old, t_new, lambda tk: form.states(tk, np.atleast_2d(dense(tk).T)),
                     out_t[recorded:] + [t_new] * bool(records_end))
            q_new, v_new = form.state(t_new, y_new)
            check_finite(problem, t_new, q_new, v_new)
            monitor.observe(t_new, q_new, v_new, lambda tk: form.state(tk, dense(tk)),
                            t_old=t_old)
            form.last_step = t_new - t_old
            form.layout_changed = False
            corrected = form.after_step(t_new, y_new)
            # A formulation may bound the next step (hybrid ahead of a singularity).
            solver.max_step = max_step if form.step_limit is None else min(max_step, form.step_limit)
            y_here = y_new if corrected is None else corrected
            t_reached = t_new
            if keep_past:
                past.append((t_new, np.array(q_new), np.array(v_new)))
            if records_end:
                record(t_new, *form.state(t_new, y_here))
                next_out += 1
            if corrected is not None and solver.status == "running":
                if form.shifted and shift_in_place(solver, corrected - y_new):
                    corrections += 1
                elif not form.layout_changed and not form.shifted and \
                        correct_in_place(solver, corrected):
                    corrections += 1
                else:
                    retire(solver)
                    restarts += 1
                    old, solver = solver, make(t_new, corrected, solver.step_size)
                    if keep_past:
                        nfev_done += _warm_start(solver, old, form, list(past)[:-1])
            if bridge is None or solver.status != "running":
                continue
            if not form.bridging:
                h_free = proposed_step(solver)
                if h_free:
                    bridge.note_step(min(h_free, max_step), h_free >= max_step)
                continue
            crossed = _bridge_passage(form, bridge, monitor, solver, t_new,
                                      *form.state(t_new, y_here), max_step, t_end)
            if crossed is None:
                continue
            t_b, q_b, v_b, interp, t_star, history = crossed[:6]
            bridges += 1
            recorded = len(out_t)
            if ts is not None:
                record_within(t_new, t_b, True, interp, bridge_samples)
            else:
                record(t_b, q_b, v_b)
            add_work(t_new, t_b, lambda tk: _split(interp(tk).T, problem.n), out_t[recorded:])
            monitor.crossed(t_new, t_b, t_star, interp(t_star)[:problem.n])
            monitor.observe(t_b, q_b, v_b)
            y_b = form.resume(t_b, q_b, v_b)
            form.last_step = t_b - t_new
            after = form.after_step(t_b, y_b)
            y_b = y_b if after is None else after
            t_reached = t_b
            retire(solver)
            restarts += 1
            old, solver = solver, make(t_b, y_b, proposed_step(solver))
            if keep_past:
                # The history goes on from the states the bridge was built on, all outside
                # the passage's band, with the bridge's own step and the order its error
                # estimate found still gaining there (near the passage the accelerations
                # carry round-off amplified by 1/σ_min²).
                past.clear()
                past.extend(history)
                nfev_done += _warm_start(solver, old, form, past, crossed.order, crossed.step)
                past.append((t_b, np.array(q_b), np.array(v_b)))
    except KeyboardInterrupt:
        status, message = "interrupted", "interrupted by the user"
    except FAILURES as exc:
        t_reached = max(t_reached, out_t[-1] if out_t else t_start)
        status, message = "failed", f"{type(exc).__name__} after t = {t_reached:.9g}: {exc}"
        exception = exc
    if status == "failed":
        if form.failure and form.failure not in message:
            message += f"; last trouble: {form.failure}"
        if "driver '" not in message and problem.driver_laws:
            h = proposed_step(solver) if solver is not None else None
            trial = min(t_end, t_reached + (h if h else t_end - t_reached))
            message += troubled_drivers(problem, (t_reached, trial))
        if monitor.inside or monitor.last < monitor.enter:   # (relative to the peak)
            s, _, u = monitor.measure(out_q[-1], out_t[-1])
            message += (f"; Φ_q is nearly singular there (σ_min/σ_max = {s:.3g}, joints "
                        f"{', '.join(monitor.joints_of(u))})")
    monitor.close(t_reached)
    if monitor.passages and not form.resolves_passages and status == "success":
        message += (f"; the run passed {len(monitor.passages)} singular configuration(s) "
                    f"(first at t = {monitor.passages[0].t_min or monitor.passages[0].t_start:.6g}) "
                    f"that method {form.name!r} does not resolve: its motion may have left "
                    "its branch there (see singular_passages and passage_drift(); methods "
                    "'hybrid' and 'projection' follow the branch)")

    if fully_driven and monitor.passages and status == "success":
        first = monitor.passages[0]
        message += (f"; the drivers carried the mechanism through {len(monitor.passages)} "
                    f"singular configuration(s) (first at t = {first.t_min or first.t_start:.6g},"
                    f" joints {', '.join(first.joints)}), following the branch it moved on: "
                    "there Φ_q loses rank, so the drivers alone do not decide which branch "
                    "follows, and the joint reactions and driver efforts are not unique")
    jumps = [(a, b) for a, b in form.sign_changes
             if not any(p.t_start <= b and a <= p.t_end for p in monitor.passages)]
    if jumps:
        message += (f"; the motion may have left its assembly branch in {len(jumps)} step(s) "
                    f"(first [{jumps[0][0]:.6g}, {jumps[0][1]:.6g}] s): the partition's "
                    "det(Φ_q D) changed sign within one step where no singular configuration "
                    "was found; check the result with a smaller rtol or max_step")

    wall = time.perf_counter() - start
    bridge_evals = bridge.evaluations - bridge_evals_before if bridge is not None else 0
    stats = {
        "method": cls.name,
        "integrator": solver_cls.__name__,
        "steps": steps,
        "rejected_steps": (rejected + int(solver.n_rejected)
                           if solver is not None and hasattr(solver, "n_rejected") else None),
        "rhs_evaluations": nfev_done + (solver.nfev if solver is not None else 0) + bridge_evals,
        "jacobian_evaluations": njev_done + int(getattr(solver, "njev", 0)),
        "lu_decompositions": nlu_done + int(getattr(solver, "nlu", 0)),
        "restarts": restarts,
        "corrections_in_place": corrections,
        "projections": counters.projections - before["projections"],
        "partitions": counters.partitions - before["partitions"],
        "factorizations": counters.factorizations - before["factorizations"],
        "constraint_evaluations": counters.constraint_terms - before["constraint_terms"],
        "switches": counters.switches - before["switches"],
        "bridges": bridges,
        "bridge_evaluations": bridge_evals,
        "bridges_over_tolerance": (bridge.over_tolerance - bridge_over_before
                                   if bridge is not None else 0),
        "work_evaluations": work.evaluations if work is not None else 0,
        "wall_time": wall,
    }
    return SimulationResult(np.array(out_t), np.array(out_q).reshape(len(out_t), -1),
                            np.array(out_v).reshape(len(out_t), -1), problem.coordinate_names,
                            problem=problem, status=status, message=message, stats=stats,
                            singular_passages=monitor.passages, switches=form.switches,
                            exception=exception,
                            work=_work_record(work, work_at) if work is not None else None)


def _split(Y, n):
    """(Q, V) from rows [q, v]."""
    Y = np.atleast_2d(Y)
    return Y[:, :n], Y[:, n:]


def _work_record(work, work_at) -> "WorkRecord":
    """What the result keeps of the work integral: the channels, W at the first samples, and
    what limits it (a failure, pieces not resolved)."""
    notes = [work.failure] if work.failure else []
    if work.unresolved:
        notes.append(f"{work.unresolved} piece(s) of steps not resolved to the quadrature's "
                     "tolerance")
    return WorkRecord(tuple(work.channels), np.array(work_at).reshape(-1, len(work.channels)),
                      "; ".join(notes))
