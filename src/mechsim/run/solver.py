"""`simulate`: a run's settings checked before any work, its formulation chosen (a fully
driven mechanism goes to the projection method), and the run (`mechsim.run.loop.Run`) executed.

Formulations supply the ODE and the corrections; integrators supply steps and dense output;
`mechsim.run.loop` owns the loop, the output, the step bounds, the restarts and the status.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..linalg import sparse
from ..formulations import METHODS, formulation_class
from ..formulations.monitor import SingularityMonitor
from ..formulations.tangent import Tangent
from ..integrators import integrator_class
from ..options import Option, check_all, check_memory, unknown_names
from ..problem import NumericProblem
from ..problem.sensitivity import MotionSensitivities
from ..results import SimulationResult, Switch
from .loop import Run, Settings
from ..threads import run_threads
from ..tolerances import Tolerances


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
    "progress": Option.flag(False),
}


@dataclass(frozen=True)
class RunConfig:
    """A run's settings, built once from the user's keywords and checked before any work
    (`RunConfig.from_keywords`): the formulation and integrator classes, the time span, the
    tolerances (a `Tolerances`, which derives every other tolerance) and the other
    settings of `simulate` (see there), with the method's own options."""
    method: type
    integrator: type
    t_start: float
    t_end: float
    tolerances: Tolerances
    max_step: float
    output_step: float | None
    first_step: float | None
    h: float | None
    max_steps: int | None
    singular_thresholds: tuple
    work: bool
    progress: bool
    options: dict = field(default_factory=dict)
    integrator_name: str | None = None      # as given (None: the method's default)

    @classmethod
    def from_keywords(cls, n: int, t_end, method=None, integrator=None, *,
                      streamed: bool = False, **keywords) -> "RunConfig":
        """The settings of a run of a problem with `n` coordinates: `keywords` are
        `simulate`'s settings and the method's options. A ValueError names the argument
        and says what is wrong (an unknown name gets the closest valid one, or the methods
        that take it). `streamed`: the samples go to disk, only the output grid's times
        stay in memory."""
        form = formulation_class(method)
        valid = {**SETTINGS, **form.options, "t_end": None, "method": None,
                 "integrator": None, "stream": None}
        message = unknown_names(keywords, valid, f"simulate (method {form.name!r})")
        if message:
            elsewhere = {name: [m for m, c in METHODS.items() if name in c.options]
                         for name in keywords if name not in valid}
            message += "".join(f"; {name!r} is an option of method(s) {', '.join(ms)}"
                               for name, ms in elsewhere.items() if ms)
            raise ValueError(message)
        options = {k: v for k, v in keywords.items() if k not in SETTINGS}
        checked = check_all(SETTINGS, {k: v for k, v in keywords.items() if k in SETTINGS})
        for name, value in options.items():
            form.options[name].check(value, name, f"method {form.name!r}")
        t0 = checked["t_start"]
        t_end = Option.real(None).check(t_end, "t_end")
        if not t_end > t0:
            raise ValueError(f"`t_end` must be after t_start = {t0}, got {t_end!r}")
        solver_cls = integrator_class(integrator or form.default_integrator)
        if checked["h"] is None and getattr(solver_cls, "fixed_step", False):
            raise ValueError(f"method {form.name!r} steps at a fixed size: give `h`, e.g. "
                             "h=1e-3")
        if checked["output_step"] is not None:
            _check_output_size(0 if streamed else n, t_end - t0, checked["output_step"])
        h = checked["h"]
        return cls(form, solver_cls, t0, t_end, Tolerances(checked["rtol"], checked["atol"]),
                   checked["max_step"], checked["output_step"],
                   checked["first_step"] if h is None else h, h, checked["max_steps"],
                   checked["singular_thresholds"], checked["work"], checked["progress"],
                   options, integrator)

    @property
    def rtol(self) -> float:
        return self.tolerances.rtol

    @property
    def atol(self) -> float:
        return self.tolerances.atol

    def settings(self) -> dict:
        """What a result keeps of them, and `SimulationResult.extend` goes on with."""
        return dict(method=self.method.name, integrator=self.integrator_name, rtol=self.rtol,
                    atol=self.atol, max_step=self.max_step, output_step=self.output_step,
                    singular_thresholds=self.singular_thresholds, max_steps=self.max_steps,
                    h=self.h, work=self.work, **self.options)


def check_simulate_arguments(n, t_end, method=None, options=None) -> RunConfig:
    """The `RunConfig` of the keyword arguments as `Mechanism.simulate` takes them."""
    options = dict(options or {})
    integrator = options.pop("integrator", None)
    streamed = options.pop("stream", None) is not None      # checked where the run starts
    return RunConfig.from_keywords(n, t_end, method, integrator, streamed=streamed, **options)


def _check_output_size(n, span, step):
    """Refuse an output grid whose samples of n coordinates (0: streamed, the grid's times
    alone) would not fit in memory."""
    samples = math.floor(span / step) + 2
    what = f"of {n} coordinates and velocities" if n else "(their times: the run streams)"
    check_memory(samples * (1 + 2 * n) * 8.0,
                 f"`output_step` = {step:g} over {span:g} s asks for {samples:.3g} samples "
                 f"{what}, which", "choose a larger output_step")


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
             progress: bool = False, stream=None, mechanism=None, events=None,
             output_grid=None, sensitivities=None, **options) -> SimulationResult:
    """Integrate the constrained equations of motion from a consistent (q0, v0) at t_start.

    Parameters
    ----------
    method : name in `mechsim.formulations.METHODS` (default "hybrid")
    rtol, atol : the accuracy asked of the motion; the integrator's local error test runs
        at `Tolerances.local()` of them (a hundredth from rtol 1e-6 up, all of it from 1e-11
        down), so that the error of the whole run, not of each step, is of the order of rtol
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
    progress : show a progress bar of simulated time (needs tqdm, the `progress` extra)
    stream : a directory (created; empty, or a stream written before): the samples go to its
        files a chunk at a time and the result reads them back as memory maps, so a run of
        any length needs memory for a chunk (and the output grid's times, 8 bytes a
        sample); `mechsim.load_result(stream)` loads it again
    mechanism : the Mechanism `problem` was built from, kept with the result (and saved
        with it: a loaded result then has its model)
    events : where the run ends early (`mechsim.engineering.impacts` passes the stops): an
        object with `values(t, q, v)` (an array, each ≥ 0 while the run may go on) and
        `describe(i)`; the result's `event` is then (t, i, q, v) of the first crossing,
        else None
    output_grid : the output times (from t_start to t_end), instead of `output_step`'s
    sensitivities : (a `MotionEquations`, ∂q0/∂k, ∂v0/∂k) to carry with the motion (`run`)
    **options : method-specific options (e.g. `alpha`, `beta` for "baumgarte")
    """
    config = RunConfig.from_keywords(
        problem.n, t_end, method, integrator, streamed=stream is not None, t_start=t_start,
        rtol=rtol, atol=atol, max_step=max_step, output_step=output_step,
        first_step=first_step, singular_thresholds=singular_thresholds,
        max_steps=max_steps, h=h, work=work, progress=progress, **options)
    return run(problem, q0, v0, config, stream=stream, mechanism=mechanism, events=events,
               output_grid=output_grid, sensitivities=sensitivities)


def run(problem: NumericProblem, q0, v0, config: RunConfig, *, stream=None, mechanism=None,
        events=None, output_grid=None, sensitivities=None) -> SimulationResult:
    """`simulate` with its settings checked already (`RunConfig`): the formulation chosen,
    the run executed, the result given its settings and continuation. `sensitivities`:
    (a `MotionEquations`, ∂q0/∂k, ∂v0/∂k) to carry the sensitivities with the motion
    (`mechsim.formulations.tangent`); the result's `sensitivities` then holds them."""
    c = config
    q0, v0 = check_initial_state(problem, q0, v0, c.t_start)
    stream = stream_directory(stream)
    problem.start_run()
    dof = problem.degrees_of_freedom(q0, c.t_start) if problem.m else problem.n
    fully_driven = problem.m >= problem.n and dof == 0
    # Constraint equations redundant at the start (Φ_q's rank n − dof below m) are taken
    # as redundant everywhere: the singularity monitor watches the rank-th singular value.
    redundant = max(problem.m - (problem.n - dof), 0)
    monitor = SingularityMonitor(problem, *c.singular_thresholds, redundant=redundant)
    local = c.tolerances.local()         # the accuracy asked, as the local error test's
    form = _formulation(c.method, problem, q0, c.t_start, local.rtol, local.atol, c.options,
                        redundant, fully_driven, monitor)
    if sensitivities is not None:
        form = Tangent(form, *sensitivities)
    grid = output_times(c.t_start, c.t_end, c.output_step) if output_grid is None else \
        np.asarray(output_grid, float)
    settings = Settings(c.t_start, c.t_end, local.rtol, local.atol, c.max_step, c.first_step,
                        c.h, c.max_steps, grid, c.work, c.progress, stream, events)
    with run_threads():
        runner = Run(problem, form, c.integrator, settings, q0, v0, method=c.method.name,
                     fully_driven=fully_driven)
        res = runner.execute()
    if sensitivities is not None:
        _keep_sensitivities(res, sensitivities[0], runner.out.extra.take())
    res.settings = c.settings()
    res.mechanism = mechanism
    res.continuation = continue_run
    if stream is not None:
        from ..results.stream import finish_stream
        finish_stream(res, stream)
    return res


def _keep_sensitivities(res, equations, rows) -> None:
    """The sensitivities the run carried, as the result's table (and what its message
    says of them at singular passages)."""
    res.sensitivities = MotionSensitivities(
        equations, res.t, res.q, res.v, rows, lam=lambda: res.reactions.multipliers.lam,
        accelerations=res.accelerations)
    if res.singular_passages:
        res.message += ("; the sensitivities were carried through the singular passages "
                        "along the branch the motion followed (one-sided there)")


def continue_run(result, t_end: float, overrides: dict):
    """`SimulationResult.extend` of a run made by `simulate`: the run goes on from the
    result's last sample with its settings (and `overrides` of them), joined to it; the
    sensitivities the run carried go on from their values there."""
    from ..results.join import join
    table = result.sensitivities
    carried = None if not isinstance(table, MotionSensitivities) else \
        (table.equations, table.q[-1], table.v[-1])
    rest = simulate(result.problem, result.q[-1], result.v[-1], t_start=float(result.t[-1]),
                    t_end=t_end, sensitivities=carried, **{**result.settings, **overrides})
    return join(result, rest)


def _formulation(cls, problem, q0, t_start, rtol, atol, options, redundant, fully_driven,
                 monitor):
    """The formulation of the method `cls` for this run, or a ValueError saying why the
    mechanism cannot be run (locked where it starts, beyond the method's resolution)."""
    if redundant:
        why = locked(problem, q0, t_start)
        if why:
            raise ValueError(why)
    if cls.needs_freedom and fully_driven:
        # A fully driven mechanism: no independent coordinate to integrate. Its motion is
        # the drivers' kinematics, which the projection method follows on its branch with
        # the integrator's error control (a partitioned run took one step for the whole
        # run and landed on the mirror branch).
        form = METHODS["projection"](problem, rtol, atol, monitor=monitor)
        form.switches.append(Switch(t_start, cls.name, form.name, "0 degrees of freedom: the "
                                    "drivers' motion, followed by the projection method"))
        return form
    why = cls.cannot_resolve(problem, q0, t_start, rtol, redundant)
    if why:
        raise ValueError(why)
    return cls(problem, rtol, atol, monitor=monitor, **options)


def locked(problem, q, t) -> str:
    """Why a mechanism whose Φ_q loses rank at (q, t) cannot move ("" where it can): each
    instantaneous motion Φ_q allows (its null space) is tried as a finite one, a step of
    1e-4 of the coordinates' size projected back onto the constraints. A mechanism held
    straight between fixed pivots (a toggle at its dead point) has instantaneous motions
    but no finite one: every projection comes back to where it began. (Its runs ground
    at a second a step to no end.) A mechanism with no instantaneous motion left and
    drivers (fully driven, with redundant rows) is not locked: its drivers move it."""
    J = sparse.dense(problem.phi_q(q, t))
    U, _, Vt = np.linalg.svd(J)
    rank = problem.rank(J)
    if rank == len(Vt) and problem.rheonomic_rows:
        return ""
    eps = 1e-4 * max(1.0, float(np.max(np.abs(q), initial=0.0)))
    for direction in Vt[rank:]:
        for sign in (1.0, -1.0):
            moved, _, err = problem.project_positions(q + sign * eps * direction, t)
            if err <= 1e-10 and np.linalg.norm(moved - q) > 0.1 * eps:
                return ""
    left = U[:, rank:]
    joints = list(dict.fromkeys(problem.constraint_owners[i]
                                for i in np.flatnonzero(np.linalg.norm(left, axis=1) > 1e-8)))
    return (f"mechanism '{problem.title}' is locked where it starts: its constraints "
            f"(joints {', '.join(joints)}) allow {len(Vt) - rank} instantaneous motion(s) "
            "but no finite one, as a chain held straight between fixed pivots; move a joint "
            "off that configuration")


def stream_directory(stream):
    """The `mechsim.files.OutputDirectory` a run streams to (created), or None; a
    ValueError where it is not a directory, is a symbolic link, or holds files other than
    an earlier stream's. An earlier stream's meta.json goes at once (a run killed before
    writing its own must not load as the earlier run)."""
    if stream is None:
        return None
    from pathlib import Path
    from ..files import STAGING, OutputDirectory, UnsafePathError
    from ..results.stream import STREAM_FILES
    try:
        path = Path(stream)
    except TypeError:
        raise ValueError(f"`stream` must be a directory path, got {stream!r:.60}") from None
    if path.exists() and not path.is_dir() and not path.is_symlink():
        raise ValueError(f"`stream` must be a directory, got the file {str(path)!r}")
    try:
        directory = OutputDirectory(path)
    except (UnsafePathError, OSError) as exc:
        raise ValueError(f"`stream`: {exc}") from None
    others = [p for p in directory.names() if p not in STREAM_FILES and not p.startswith(STAGING)]
    if others:
        raise ValueError(f"`stream` directory {str(path)!r} holds other files "
                         f"({', '.join(others[:3])}…); give an empty one")
    directory.remove("meta.json")
    return directory
