"""One run of the integration loop, made of named parts.

`Run.execute` is the algorithm: take a step with the integrator; if the formulation says the
step left its assembly branch, take it again shorter; record the output samples inside it and
integrate the work along it; let the singularity monitor look at it; let the formulation
correct the state (in place where the integrator allows, else a restart); cross a singular
passage ahead with the passage bridge. Its parts:

- `Recorder` (`mechsim.run.samples`): the output samples (one array grown in place, handed to
  the result without a copy) with the work of each channel at each sample;
- `StepBound`: the one bound on the next step (the run's `max_step`, the formulation's
  `step_limit`, the bridge's landing), and LSODA's restart when it changes;
- `Statistics`: the counts of what the run spent;
- the integrator adapters (`mechsim.integrators.adapters`) for everything private to scipy;
- the passage bridge (`mechsim.formulations.bridge`, `bridge_passage`), and the
  sensitivities of the passages' instants (`mechsim.run.passage_times`).

A failure mid-run (an exception in the model, a singular matrix, an integrator giving up, the
user pressing Ctrl-C) ends the loop and returns everything computed so far, with a `status`
and a `message` (diffrax's RESULTS): no work is lost.
"""

from __future__ import annotations

import collections
import time
from dataclasses import dataclass

import numpy as np

from ..formulations.bridge import bridge_passage
from ..formulations.full import settle_samples
from ..integrators import AdamsPECE, CompiledDOP853, integrator_name
from ..integrators.adapters import (bound_read_at_start, correct_in_place, proposed_step, retune,
                                    shift_in_place, warm_start)
from ..results import SimulationResult
from ..records import Status, WorkRecord
from ..results.stream import begin_stream
from ..results.work import WorkIntegral
from .bounds import Statistics, StepBound
from ..progress import Progress
from .events import EVENT_SLACK, crossing
from .passage_times import PassageTimes
from .runaway import Runaway
from .segment import Segment
from ..tolerances import Tolerances
from ..formulations.basis import ConstraintSolveError
from ..model.checks import LoadError
from .samples import (FAILURES, NonFiniteState, Recorder, check_finite, fastest_motion,
                      split_rows, troubled_drivers)

# A run stops as stuck when this many steps together advance less than this fraction of
# its span (LU alone at the flexible four-bar's passage: 2000 steps of 2e-12–7e-12 s).
STALL_STEPS = 2000
STALL_SPAN = 1e-7
# A step that left the assembly branch (`Formulation.keeps_branch`) is taken again at a
# quarter of its length, up to this many times in a row, by the methods that resolve
# passages; then it stands, and the run says so.
BRANCH_RETRIES = 6


@dataclass(frozen=True)
class Settings:
    """What the loop reads of a run's settings (`mechsim.run.solver.RunConfig`), with the
    output grid, the stream's directory and the events resolved."""
    t_start: float
    t_end: float
    rtol: float
    atol: float
    max_step: float
    first_step: float | None
    h: float | None                 # a fixed step (fixed-step methods), else None
    max_steps: int | None
    ts: np.ndarray | None           # the output grid (None: every step)
    work: bool
    progress: bool = False          # a progress bar (tqdm) over [t_start, t_end]
    stream: object = None           # a directory the samples are streamed to, or None
    events: object = None           # where the run ends early (`Events`), or None


class Run:
    """One integration of `form` (a formulation with its monitor set) by `solver_cls` from
    the consistent state (q0, v0): `execute()` returns the `SimulationResult`. `method`:
    the method asked for (the formulation may stand in for it); `fully_driven`: the
    mechanism has no degree of freedom (its passages get a word on what the drivers do
    there)."""

    def __init__(self, problem, form, solver_cls, settings: Settings, q0, v0, method="",
                 fully_driven=False):
        self.problem, self.form, self.solver_cls = problem, form, solver_cls
        self.method = method or form.name
        self.s, self.fully_driven = settings, fully_driven
        self.monitor = form.monitor
        self.start = time.perf_counter()
        self.counters_before = {k: getattr(problem.counters, k) for k in (
            "projections", "partitions", "switches", "factorizations", "constraint_terms")}
        channels = problem.work_channels if settings.work else []
        self.work = None
        if channels:
            energy = (problem.kinetic_energy(q0, v0) + abs(problem.potential_energy(q0))
                      + problem.strain_energy(q0))
            self.work = WorkIntegral(channels, problem.work_rates_many, form.tol.work,
                                     float(energy), settings.t_end - settings.t_start)
        self.out = Recorder(problem, settings.ts, channels, settings.stream, form.extras,
                            form.width)
        if settings.stream is not None:
            begin_stream(settings.stream, problem.coordinate_names, channels)
        self.bound = StepBound(settings.max_step, bound_read_at_start(solver_cls))
        # The integrator's tolerances: the run's local ones, or looser through a passage's
        # band where no bridge crosses it (`_tolerances_for_passages`).
        self.local = Tolerances(settings.rtol, settings.atol)
        self.through_passage = self.local.through_passage()
        self.tolerances = self.local
        self.stats = Statistics()
        self.bridge = form.bridge
        self._bridge_start = ((self.bridge.evaluations, self.bridge.over_tolerance,
                               len(self.bridge.beyond))
                              if self.bridge is not None else (0, 0, 0))
        # The last accepted states (t, q, v), for a warm Adams restart after a change of
        # coordinates (after a bridge: the states the bridge was built on).
        self.keep_past = issubclass(solver_cls, AdamsPECE)
        self.past = collections.deque(maxlen=AdamsPECE.max_order_limit + 1)
        # Stuck (at a singular configuration the formulation cannot pass): stop there with
        # the partial result instead of grinding on.
        self.recent = collections.deque([settings.t_start], maxlen=STALL_STEPS + 1)
        self.runaway = Runaway()
        self.event = None                # (t, index, q, v) where an event ended the run
        self._g_last = None if settings.events is None else \
            np.asarray(settings.events.values(settings.t_start, q0, v0), float)
        self.status, self.message, self.exception = Status.SUCCESS, "reached t_end", None
        self.stream_failed = False       # the message says so already
        self.t_reached = settings.t_start
        self.solver = None
        self.segment = None              # plain steps in the engine (`Segment`), where it applies
        self.y0 = form.initial_state(settings.t_start, q0, v0)
        self.passage_times = PassageTimes(form, self.monitor)
        self.monitor.observe(settings.t_start, q0, v0)
        if settings.ts is None or settings.ts[0] == settings.t_start:
            self.out.record_due(settings.t_start, q0, v0, self.y0)
            self.out.work.append(np.zeros(len(channels)))

    # --- the loop ------------------------------------------------------------------------------
    def execute(self) -> SimulationResult:
        progress = Progress(self.s.t_start, self.s.t_end, self.problem.title) \
            if self.s.progress else None
        try:
            self.solver = self.make(self.s.t_start, self.y0, self.s.first_step)
            self.segment = Segment.for_run(self, STALL_SPAN * (self.s.t_end - self.s.t_start))
            while self.solver.status == "running" and self._advance():
                if progress is not None:
                    progress.update(self.solver.t)
        except KeyboardInterrupt:
            self.status, self.message = Status.INTERRUPTED, "interrupted by the user"
        except FAILURES as exc:
            t = max(self.t_reached, self.out.t[-1] if self.out.count else self.s.t_start)
            self.t_reached = t
            self.status = Status.FAILED
            self.message = f"{type(exc).__name__} after t = {t:.9g}: {exc}"
            self.exception = exc
        finally:
            if progress is not None:
                progress.close()
        self._explain()
        return self._result()

    def _advance(self) -> bool:
        """One accepted step (or a step retaken, or an LSODA restart for a new bound);
        False where the run stops."""
        if self.segment is not None and self.segment.advance():
            # Plain steps taken in the engine, up to one the loop decides on (`Segment`),
            # the last of them perhaps pending: the loop finishes it.
            if self.segment.pending is not None:
                return self._finish_pending(self.segment.pending)
            why = self.runaway.verdict(self.stats.steps, self.solver.t, self.s.t_end)
            if why:
                return self._stop(why + fastest_motion(self.problem, self.solver.t, self.form.state(
                    self.solver.t, self.solver.y)[1]))
            return True
        restart = self.bound.restart_for(self.solver)
        if restart is not None:
            self._replace(self.solver.t, self.solver.y, *restart)
        solver, form = self.solver, self.form
        t_old, y_old = solver.t, solver.y.copy()
        msg = solver.step()
        if solver.status == "failed":
            return self._stop(f"integrator stopped at t = {solver.t:.9g}: {msg}")
        if not form.keeps_branch(solver.t, solver.y) and form.resolves_passages and \
                self.s.h is None and self.stats.retries < BRANCH_RETRIES:
            # Left the branch within the step (or crossed a singular configuration unseen):
            # take it again, shorter, from its start. A method that does not resolve
            # passages crosses them so, and says so instead.
            self.stats.retries += 1
            self.stats.rejected += 1
            short = 0.25 * (solver.t - t_old)
            self._replace(t_old, y_old, short, min(self.s.max_step, short))
            return True
        self.stats.retries = 0
        self.stats.steps += 1
        if self.s.max_steps is not None and self.stats.steps > self.s.max_steps:
            return self._stop(f"step limit max_steps = {self.s.max_steps} reached at "
                              f"t = {solver.t:.9g}")
        self.recent.append(solver.t)
        if len(self.recent) == self.recent.maxlen and \
                solver.t - self.recent[0] < STALL_SPAN * (self.s.t_end - self.s.t_start):
            return self._stop(f"the steps collapsed: {self.recent.maxlen - 1} steps advanced "
                              f"only {solver.t - self.recent[0]:.2g} s up to "
                              f"t = {solver.t:.9g}")
        if self.s.events is not None and self._event(t_old, solver.t, solver.y):
            return False
        return self._after_accept(solver.t, self._accept(t_old, solver.t, solver.y))

    def _after_accept(self, t, y_here) -> bool:
        """What follows an accepted step that ended at t and goes on from y_here: the
        runaway rule, the tolerances through a passage, the passage bridge, the stream;
        False where the run stops."""
        why = self.runaway.verdict(self.stats.steps, t, self.s.t_end)
        if why:
            return self._stop(why + fastest_motion(self.problem, t,
                                                    self.form.state(t, y_here)[1]))
        if self.solver.status == "running":
            self._tolerances_for_passages()
        if self.bridge is not None and self.solver.status == "running":
            self._bridge(self.solver.t, y_here)
        self.out.flush()
        if self.out.failure is not None:
            self.stream_failed = True
            return self._stop(f"writing the stream failed at t = {self.solver.t:.9g} "
                              f"({self.out.failure}); the samples after it are in memory")
        return True

    def _event(self, t_old, t_new, y_new) -> bool:
        """Whether one of `Settings.events`' values turned negative within the step just
        taken: then the step is accepted only up to the first such time, found on the
        step's dense output to `EVENT_XTOL`, a sample recorded there, and the run ends
        with `event` = (t, index, q, v)."""
        events, form = self.s.events, self.form
        q_new, v_new = form.state(t_new, y_new)
        g_new = np.asarray(events.values(t_new, q_new, v_new), float)
        g_old = self._g_last
        self._g_last = g_new
        crossed = np.flatnonzero(g_new < -EVENT_SLACK)
        if not crossed.size:
            return False
        interpolant = self.solver.dense_output()

        def value(t, i):
            q, v = form.state(t, interpolant(t))
            return float(events.values(t, q, v)[i])
        first, t_event = None, t_new
        for i in crossed:
            if g_old is None:
                continue
            t_i = crossing(lambda t, i=i: value(t, i), t_old, t_new, g_old[i])
            if first is None or t_i < t_event:
                first, t_event = int(i), t_i
        if first is None:
            return False
        ts = self.out.ts
        if ts is not None and not np.any(ts == t_event):
            self.out.ts = np.insert(ts, int(np.searchsorted(ts, t_event)), t_event)
        y_event = interpolant(t_event)
        y_here = self._accept(t_old, t_event, y_event)
        q, v = form.state(t_event, y_here)
        self.event = (t_event, first, np.array(q), np.array(v))
        self.t_reached = t_event
        self.message = f"stopped at t = {t_event:.9g}: {events.describe(first)}"
        return True

    def _accept(self, t_old, t_new, y_new):
        """Samples, work, monitor and the formulation's correction for the step just
        accepted; returns the state the run goes on from."""
        form, out, solver = self.form, self.out, self.solver
        # The step's interpolant, built at most once (scipy's RK methods spend extra right-
        # hand sides on each `dense_output()` call), shared by the samples, work and monitor.
        interpolant = []

        def step_output():
            if not interpolant:
                interpolant.append(solver.dense_output())
            return interpolant[0]

        def dense(tk):
            return step_output()(tk)

        recorded = out.count
        if out.ts is not None:
            out.within(t_old, t_new, False, dense, form.states)
        due = out.due(t_new)
        self._add_work(t_old, t_new, lambda tk: form.states(tk, np.atleast_2d(dense(tk).T)),
                       recorded, [t_new] if due else [])
        q_new, v_new = form.state(t_new, y_new)
        check_finite(self.problem, t_new, q_new, v_new)
        self.runaway.note(self.stats.steps, t_new - t_old, v_new)
        self._observe(t_old, t_new, q_new, v_new, step_output)
        return self._after_step(t_old, t_new, y_new, q_new, v_new, due)

    def _observe(self, t_old, t_new, q_new, v_new, step_output) -> None:
        """The monitor's observation of the step from t_old accepted at t_new (q_new,
        v_new there; `step_output()` its dense output) and the passage times' note."""
        form = self.form

        def dense(tk):
            return step_output()(tk)
        self.monitor.observe(t_new, q_new, v_new, lambda tk: form.state(tk, dense(tk)),
                             t_old=t_old, positions_at=lambda ts: form.positions(
                                 ts, np.atleast_2d(dense(ts).T)),
                             on_step=lambda: form.compiled_step(step_output))
        self.passage_times.note(t_old, t_new, lambda tk: form.split(tk, dense(tk)))

    def _finish_pending(self, pending) -> bool:
        """Finish a segment's pending step (`mechsim.run.segment.Pending`), taken in the
        engine with its samples (and its observation, unless `pending.observe`): what
        `_accept` and `_advance` do after that."""
        t_old, t_new, y_new = pending.t_old, pending.t_new, pending.y_new
        form = self.form
        form.keeps_branch(t_new, y_new)              # its end as the loop had it
        q_new, v_new = form.state(t_new, y_new)
        if pending.observe:
            formed = [pending.interpolant] if pending.interpolant is not None else []

            def step_output():
                if not formed:
                    formed.append(self.solver.dense_output())
                return formed[0]
            self._observe(t_old, t_new, q_new, v_new, step_output)
        y_here = self._after_step(t_old, t_new, y_new, q_new, v_new, self.out.due(t_new))
        return self._after_accept(t_new, y_here)

    def _after_step(self, t_old, t_new, y_new, q_new, v_new, due):
        """The formulation's correction of the step from t_old accepted at (t_new, y_new)
        (q_new, v_new there), its bound on the next step and the sample at its end where
        `due`; returns the state the run goes on from."""
        form, out, solver = self.form, self.out, self.solver
        correction = form.after_step(t_new, y_new, t_new - t_old)
        self.bound.after_step(solver, correction.step_limit)
        corrected = correction.y
        y_here = y_new if corrected is None else corrected
        self.t_reached = t_new
        if self.keep_past:
            self.past.append((t_new, np.array(q_new), np.array(v_new)))
        if due:
            out.record_due(t_new, *form.state(t_new, y_here), y_here)
        if corrected is not None and solver.status == "running":
            self._correct(t_new, y_new, correction)
        return y_here

    def _correct(self, t, y, correction) -> None:
        """Put the formulation's correction into the integrator: in place where it can
        take it (a projection, a constant shift), else by a restart there."""
        form, solver, corrected = self.form, self.solver, correction.y
        if correction.shifted and shift_in_place(solver, corrected - y):
            self.stats.corrections += 1
        elif not correction.layout_changed and not correction.shifted and \
                correct_in_place(solver, corrected):
            self.stats.corrections += 1
        else:
            old = self._replace(t, corrected, solver.step_size)
            if self.keep_past:
                self.stats.nfev += warm_start(self.solver, old, form, list(self.past)[:-1])

    def passage_tolerances(self):
        """The tolerances a step inside a singular passage's band takes: no tighter than
        `Tolerances.through_passage` of the local ones where the formulation steps through
        it (no bridge, or the bridge stood down), else the local ones."""
        bridged = self.form.bridges_passages and not (self.bridge is not None and
                                                      self.bridge.standing_down)
        return self.local if bridged else self.through_passage

    def _tolerances_for_passages(self) -> None:
        """Step through a singular passage's band with `passage_tolerances`, out of it with
        the local ones: the integrator takes them in place, or is restarted with them."""
        if self.s.h is not None:
            return
        wanted = self.passage_tolerances() if self.monitor.inside else self.local
        if wanted == self.tolerances:
            return
        self.tolerances = wanted
        if not retune(self.solver, wanted.rtol, wanted.atol):
            self._replace(self.solver.t, self.solver.y, proposed_step(self.solver))

    def _bridge(self, t, y) -> None:
        """Cross a singular passage ahead where the formulation bridges, and go on from its
        far side."""
        form, bridge, solver = self.form, self.bridge, self.solver
        if not form.bridging:
            h_free = proposed_step(solver)
            if h_free:
                bridge.note_step(min(h_free, self.bound.max_step), h_free >= self.bound.max_step)
            return
        crossed = bridge_passage(form, bridge, self.monitor, solver, self.bound, t,
                                 *form.state(t, y), self.s.t_end, form.extension_of(y))
        if crossed is None:
            return
        t_b, q_b, v_b, interp, t_star, history = crossed[:6]
        self.stats.bridges += 1
        n = self.problem.n
        recorded = self.out.count
        if self.out.ts is not None:
            self.out.within(t, t_b, True, interp, self._bridge_samples)
        else:
            self.out.record(t_b, q_b, v_b, interp(t_b))
        self._add_work(t, t_b, lambda tk: split_rows(interp(tk).T, n), recorded, [])
        self.monitor.crossed(t, t_b, t_star, interp(t_star)[:n])
        self.monitor.observe(t_b, q_b, v_b)
        self.passage_times.note(t, t_b, lambda tk: np.split(interp(tk), [n, 2 * n]))
        y_b = form.resume(t_b, q_b, v_b, crossed.extra)
        after = form.after_step(t_b, y_b, t_b - t).y
        rate, y_b = (crossed.rate_at(y_b), y_b) if after is None else (None, after)
        self.t_reached = t_b
        old = self._replace(t_b, y_b, proposed_step(solver), rate=rate)
        if self.keep_past:
            # The history goes on from the states the bridge was built on, all outside the
            # passage's band, with the bridge's own step and the order its error estimate
            # found still gaining there (near the passage the accelerations carry round-off
            # amplified by 1/σ_min²).
            self.past.clear()
            self.past.extend(history)
            self.stats.nfev += warm_start(self.solver, old, form, self.past, crossed.order,
                                          crossed.step)
            self.past.append((t_b, np.array(q_b), np.array(v_b)))

    # --- parts -------------------------------------------------------------------------------
    def make(self, t, y, step, bound=None, rate=None):
        """A new integrator at (t, y) from `step` (a fixed step stays), within `bound`
        (default: the run's max_step), `rate` the formulation's rate there if known."""
        s = self.s
        bound = s.max_step if bound is None else bound
        step = s.first_step if s.h is not None else step
        kw = {"first_step": min(step, s.t_end - t, bound)} if step else {}
        tol = self.tolerances
        kw |= {"f0": rate} if self.solver_cls is CompiledDOP853 else {}
        solver = self.solver_cls(self.form.integrand, t, y, s.t_end, rtol=tol.rtol,
                                 atol=tol.atol, max_step=bound, **kw)
        if isinstance(solver, CompiledDOP853):       # its steps in C where the rate is
            solver.rate = self.form.compiled_rate
        if isinstance(solver, AdamsPECE):
            # It projects before its step's last evaluation: after_step needs no other one.
            solver.project = self.form.project_now
        return solver

    def _replace(self, t, y, step, bound=None, rate=None):
        """Retire the running integrator for `make`'s new one at (t, y); returns the old one."""
        old = self.solver
        self.stats.retire(old)
        self.stats.restarts += 1
        self.solver = self.make(t, y, step, bound, rate)
        return old

    def _stop(self, message) -> bool:
        self.status, self.message = Status.FAILED, message
        return False

    def _bridge_samples(self, tk, Y):
        """A bridge's output samples, onto the constraints as the steps' are."""
        Q, V = split_rows(np.array(Y), self.problem.n)
        compiled = getattr(self.bridge, "compiled", False)    # as its own projections
        settle_samples(self.problem, tk, Q, V, self.form.tol.manifold, compiled)
        return Q, V

    def _add_work(self, a, b, states, recorded, more) -> None:
        """Integrate the work over the step [a, b] and keep W at the samples it recorded
        (from index `recorded`, and `more` times still to be recorded)."""
        if self.work is None:
            return
        times = list(self.out.times_since(recorded)) + list(more)
        W = self.work.add(a, b, states, times)
        if W is not None:
            self.out.work.extend(W)

    # --- the result ----------------------------------------------------------------------------
    def _explain(self) -> None:
        """Add to the message what the run's end and its passages mean."""
        problem, form, monitor = self.problem, self.form, self.monitor
        if self.status == Status.FAILED:
            if form.failure and not self._told(form.failure):
                self.message += f"; last trouble: {form.failure}"
            if problem.driver_laws and not self._drivers_told():
                h = proposed_step(self.solver) if self.solver is not None else None
                t = self.t_reached
                trial = min(self.s.t_end, t + (h if h else self.s.t_end - t))
                self.message += troubled_drivers(problem, (t, trial))
            if monitor.inside or monitor.last < monitor.enter:   # (relative to the peak)
                s, _, u = monitor.measure(self.out.q[-1], self.out.t[-1])
                self.message += (f"; Φ_q is nearly singular there (σ_min/σ_max = {s:.3g}, "
                                 f"joints {', '.join(monitor.joints_of(u))})")
        monitor.close(self.t_reached)
        if monitor.blind:
            self.message += (f"; σ_min/σ_max of the mass-scaled constraint Jacobian stayed "
                             f"at {monitor.peak:.2g} (very unequal masses), below round-off: "
                             "singular passages were not watched")
        passages = monitor.passages
        beyond = self.bridge.beyond[self._bridge_start[2]:] if self.bridge is not None else []
        if beyond:
            worst = max(beyond, key=lambda b: b[1])
            self.message += (
                f"; {len(beyond)} singular passage(s) (first at t = {beyond[0][0]:.6g}) were "
                f"crossed with an estimated relative error up to {worst[1]:.2g} (at t = "
                f"{worst[0]:.6g}), above the run's tolerance: the round-off of the "
                "accelerations near the configuration, which no closer step resolves "
                "(stepping through the passage instead would be slower and no more accurate)")
        if self.status != Status.SUCCESS:
            return
        first = passages[0] if passages else None
        if passages and not form.resolves_passages:
            self.message += (
                f"; the run passed {len(passages)} singular configuration(s) (first at "
                f"t = {first.t_min or first.t_start:.6g}) that method {form.name!r} does not "
                "resolve: its motion may have left its branch there (see singular_passages "
                "and passage_drift(); methods 'hybrid' and 'projection' follow the branch)")
        if self.fully_driven and passages:
            self.message += (
                f"; the drivers carried the mechanism through {len(passages)} singular "
                f"configuration(s) (first at t = {first.t_min or first.t_start:.6g}, joints "
                f"{', '.join(first.joints)}), following the branch it moved on: there Φ_q "
                "loses rank, so the drivers alone do not decide which branch follows, and "
                "the joint reactions and driver efforts are not unique")
        self._explain_jumps()

    def _told(self, failure: str) -> bool:
        """Is `failure` (the formulation's last trouble) what ended the run, its message
        said already?"""
        return isinstance(self.exception, ConstraintSolveError) and \
            str(self.exception) == failure

    def _drivers_told(self) -> bool:
        """Does the message name the cause among the drivers already: a user's function
        that raised (a LoadError names its driver or load), or a non-finite motion whose
        check named the drivers behind it?"""
        exc = self.exception
        return isinstance(exc, LoadError) or (isinstance(exc, NonFiniteState) and
                                              bool(exc.drivers))

    def _explain_jumps(self) -> None:
        jumps = [(a, b) for a, b in self.form.sign_changes
                 if not any(p.t_start <= b and a <= p.t_end for p in self.monitor.passages)]
        if jumps:
            self.message += (
                f"; the motion may have left its assembly branch in {len(jumps)} step(s) "
                f"(first [{jumps[0][0]:.6g}, {jumps[0][1]:.6g}] s): the partition's "
                "det(Φ_q D) changed sign within one step where no singular configuration was "
                "found; check the result with a smaller rtol or max_step")

    def _statistics(self) -> dict:
        st, solver, bridge = self.stats, self.solver, self.bridge
        counters, before = self.problem.counters, self.counters_before
        bridge_evals = bridge.evaluations - self._bridge_start[0] if bridge is not None else 0
        return {
            "method": self.method,
            "integrator": integrator_name(self.solver_cls),
            "steps": st.steps,
            "rejected_steps": (st.rejected + int(solver.n_rejected)
                               if solver is not None and hasattr(solver, "n_rejected")
                               else None),
            "rhs_evaluations": st.nfev + (solver.nfev if solver is not None else 0)
            + bridge_evals,
            "jacobian_evaluations": st.njev + int(getattr(solver, "njev", 0)),
            "lu_decompositions": st.nlu + int(getattr(solver, "nlu", 0)),
            "restarts": st.restarts,
            "corrections_in_place": st.corrections,
            **{name: getattr(counters, key) - before[key] for name, key in (
                ("projections", "projections"), ("partitions", "partitions"),
                ("factorizations", "factorizations"),
                ("constraint_evaluations", "constraint_terms"), ("switches", "switches"))},
            "bridges": st.bridges,
            "bridge_evaluations": bridge_evals,
            "bridges_over_tolerance": (bridge.over_tolerance - self._bridge_start[1]
                                       if bridge is not None else 0),
            "work_evaluations": self.work.evaluations if self.work is not None else 0,
            "wall_time": time.perf_counter() - self.start,
        }

    def _result(self) -> SimulationResult:
        out = self.out
        t, q, v = out.take()
        work = self._work_record()
        if out.failure is not None and not self.stream_failed:
            self.status = Status.FAILED
            self.message += (f"; writing the stream failed at its end ({out.failure}): every "
                             "sample is in this result, not all in the stream's files")
        res = SimulationResult(t, q, v, self.problem.coordinate_names, problem=self.problem,
                               status=self.status, message=self.message,
                               stats=self._statistics(),
                               singular_passages=self.passage_times.attach(
                                   self.monitor.passages),
                               switches=self.form.switches, exception=self.exception,
                               work=work)
        res.event = self.event
        return res

    def _work_record(self) -> WorkRecord | None:
        """What the result keeps of the work integral: the channels, W at the first samples,
        and what limits it (a failure, pieces not resolved)."""
        work = self.work
        if work is None:
            return None
        notes = [work.failure] if work.failure else []
        if work.unresolved:
            notes.append(f"{work.unresolved} piece(s) of steps not resolved to the "
                         "quadrature's tolerance")
        return WorkRecord(tuple(work.channels), self.out.work.take(), "; ".join(notes))
