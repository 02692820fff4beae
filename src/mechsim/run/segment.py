"""Consecutive plain steps of a small rigid mechanism, in LU or by the projection method,
taken in the compiled engine.

A step of LU partitioning or of the projection method on a small rigid mechanism costs the
compiled engine tens of microseconds and the Python loop around it several times that: the
output samples, the singularity monitor's observation, the hybrid's policy, the
partition's end or the state's projection, the passage bridge's plan, the run's
bookkeeping, each a few numpy calls on arrays of a dozen numbers. Where a step is plain
(nothing happens but the step, its samples, the monitor's measurement, the partition's
predictor or the projection: no passage in reach, no change of partition or of
formulation, no crossing), all of that is arithmetic that
`mechsim_lu_segment` (LU) or `mechsim_projection_segment` (projection: the hybrid's
projection phase between passages and after them, the bridge's approach to a landing
point included) does in C, step after step, until a step is not plain. A step whose end
is the loop's to decide (a switch of the hybrid, a new partition, a crossing by the
passage bridge, a sample due at its end, the run's end) or to observe (in LU where its
tolerances change inside a passage: a passage open at its start, the band, a dip the
monitor's search finds) the segment still takes, with its samples, up to that point, and
hands it over pending (`Pending`: the loop finishes it, `Run._finish_pending`); any other
step it drops, and the Python loop (`mechsim.run.loop.Run`) takes it from the same state,
with its own decisions. Where the bridge crosses the passages (the run's tolerances stay
its own inside them), a projection segment observes the passages itself as the monitor
does (the open one going on, closing, opening, the dips a search finds refined to their
minima); so does an LU segment where the run's tolerances stay the local ones inside a
passage (`Run.passage_tolerances`: bridged, or a local rtol from `PASSAGE_FLOOR` up);
elsewhere it records the passages that begin and end inside a step (the tolerances
change inside one: a step that ends there is the loop's). The loop names their joints from the
singular vectors the segment kept.

The contract is the Python loop's numbers to the bit: the segment makes the decisions the
loop would make (the same comparisons in the same order on the same doubles) and calls the
engine's functions the loop calls (the DOP853 step, its dense output, the partition's end
and predictor, the projections, the samples' and the monitor's evaluations); the few
formulas the loop evaluates in Python floats (the monitor's rates and bounds, the
policy's limit, the re-reference, the bridge's prediction of the singular instant) it
evaluates in the same order. The bridge's state after the steps is the engine's copy of
what its `plan` keeps (`PassageBridge.planned_in_engine`). A run with segments and one
without them give bitwise the same samples, steps and counts (tests).

It applies to runs of "lu", "projection" and the hybrid with the compiled DOP853 on a
compiled rate (`Partitioned.compiled_rate`, `Projection.compiled_rate`) and the compiled
monitor (a dense algebra's engine, no redundant constraints), with an output grid or a
sample at every step, and nothing else to do at a step: no events, work integral,
streamed output, state extras, sensitivities or fixed step. After a segment declines its
first step the loop tries that formulation's again only after twice as many steps as the
last time (up to `BACKOFF_MAX`), so a mechanism whose steps are seldom plain pays little
for the tries; after a segment that stopped on a step it declined, that step is the
loop's without a try (taking the segment's passage search of it). The engine's side
is `mechsim.codegen.steps.PlainSteps`, which the problem's algebra gives
(`plain_steps`).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..formulations.hybrid import Hybrid
from ..formulations.monitor import (BLIND, CHORD, GRID, HERMITE_MARGIN, RATE_STEP,
                                    REFINE_TOL, SKIP_RISE, WEYL_SPAN, Fall, Observation, OpenPassage)
from ..records import SingularPassage
from ..problem.algebra import RANK_FACTOR
from ..formulations.full import ROUND_OFF
from ..formulations.partitioned import REFERENCE_SPAN, Partitioned
from ..formulations.projection import Projection
from ..integrators.compiled import (SAFETY, CompiledDOP853, Interpolant, dense_matrix,
                                    extra_tableau, tableau)
from .runaway import RUNAWAY_EVERY, RUNAWAY_FROM

# The longest wait, in steps, before a segment is tried again after it declined its first.
BACKOFF_MAX = 64
# Segments can be switched off (`enabled = False`), for the test that compares.
enabled = True
# A pending step whose observation is the loop's (`mechsim_segment.pending`; 1: its
# decisions only).
PENDING_OBSERVE = 2


class Pending(NamedTuple):
    """A segment's last step, taken in the engine up to its observation by the monitor
    (`observe` False: the formulation's and the bridge's decisions after it are the
    loop's) or without it (`observe` True: the loop observes it, then decides), from
    t_old to t_new with its end y_new; `interpolant`: its dense output where the engine
    formed it (for the samples or the search), else None (`Run._finish_pending`)."""
    t_old: float
    t_new: float
    y_new: np.ndarray
    observe: bool
    interpolant: object


class Segment:
    """The segments of one run (`for_run`); `advance()` takes one, or says it did not."""

    def __init__(self, run, lu, proj, plain, min_advance):
        self.run, self.lu, self.proj = run, lu, proj
        self.hybrid = run.form if isinstance(run.form, Hybrid) else None
        self.plain = plain                 # formulation -> its engine's `PlainSteps`
        self.steps = None                  # the `PlainSteps` of the latest segment
        # The latest segment's last step where the loop finishes it (`Pending`), else None.
        self.pending = None
        self.min_advance = min_advance
        self.wait = dict.fromkeys(plain, 0)
        self.backoff = dict.fromkeys(plain, 0)
        self.every_step = run.out.ts is None          # a sample at every step's end
        if not self.every_step:
            for steps in plain.values():
                steps.point("ts", run.out.ts)

    @classmethod
    def for_run(cls, run, min_advance) -> "Segment | None":
        """The run's segments, where they apply to it (module docstring); else None.
        `min_advance`: the shortest step a segment takes (shorter ones are the stall
        rule's to judge, `mechsim.run.loop.STALL_SPAN`)."""
        form, s, prob = run.form, run.s, run.problem
        if not enabled or not issubclass(run.solver_cls, CompiledDOP853) or SAFETY is None:
            return None
        hybrid = form if type(form) is Hybrid else None
        lu = hybrid.lu if hybrid is not None else form if type(form) is Partitioned else None
        proj = hybrid.proj if hybrid is not None else form if type(form) is Projection else None
        if s.events is not None or s.stream is not None or s.h is not None or \
                run.work is not None or run.out.extras is not None or \
                run.passage_times.form is not None or run.keep_past or \
                run.monitor is None or run.monitor.redundant:
            return None
        rows = 1 if s.ts is None else min(len(s.ts), 4096)
        tableaus = (tableau(), extra_tableau(), dense_matrix())
        plain = {}
        basis = getattr(lu, "basis", None)
        if lu is not None and type(lu) is Partitioned and lu.engine is not None and \
                basis is not None and not basis.sparse:
            plain[lu] = prob.algebra.plain_steps(basis.f, rows, tableaus)
        if proj is not None and proj.engine is not None:
            plain[proj] = prob.algebra.plain_steps(prob.n, rows, tableaus)
        plain = {k: v for k, v in plain.items() if v is not None}
        return cls(run, lu, proj, plain, min_advance) if plain else None

    def advance(self) -> bool:
        """Steps taken in a segment from the run's present state (True), or none (False:
        the loop takes the next step)."""
        run = self.run
        form = self.hybrid.active if self.hybrid is not None else run.form
        steps = self.plain.get(form)
        if steps is None:
            return False
        if self.wait[form]:
            self.wait[form] -= 1
            return False
        solver, monitor = run.solver, run.monitor
        if not isinstance(solver, CompiledDOP853) or solver.status != "running" or \
                solver.t == solver.t_bound or solver.y.dtype != np.float64 or \
                monitor.blind or \
                run.tolerances != run.local or solver.rate is None:
            return False
        lu = form is self.lu
        start = form.plain_start()
        if start is None:
            return False
        compiled = solver.rate()
        if compiled is None or compiled.kind != int(lu) or \
                compiled.context != form.engine.context:
            return False
        if not lu and (compiled.min_rcond, compiled.cut) != \
                (-1.0 if start[2] else start[0], start[1]):
            return False                 # not the rate the segment's steps take
        self.steps = steps
        self._load(run, solver, monitor.observation())
        if lu:
            self._load_partition(start)
            count = steps.run(form.engine.context, run.problem.algebra.engine.context)
        elif self._load_projection(start, form):
            count = steps.run_projection(form.engine.context)
        else:
            return False
        if not count:
            self.wait[form] = self.backoff[form] = min(max(2 * self.backoff[form], 1),
                                                       BACKOFF_MAX)
            return False
        # A segment that stopped on a step it declined leaves that very step next: the
        # loop's, without another try.
        self.backoff[form], self.wait[form] = 0, int(steps.declined and not steps.s.pending)
        if lu:
            compiled = self._store_partition(form, solver, compiled)
        else:
            compiled = self._store_projection(form, solver)
        self._store(run, monitor, count, compiled)
        return True

    def _load_projection(self, start, proj) -> bool:
        """The projection method's numbers (`Projection.plain_start`), the passage bridge's
        plan and the hybrid's way back to LU into the structure, where the bridge has
        nothing planned and that way is tested compiled; False where not."""
        s, bridge = self.steps.s, self.run.bridge
        plan = bridge.plain_start() if bridge is not None else (0.0, 0.0, None, None, None,
                                                                False)
        limit = self.hybrid.lu_condition_limit() if self.hybrid is not None else 0.0
        if plan is None or limit is None:
            return False
        s.min_rcond, s.cut, far, s.project_tol, s.skip_tol = start
        s.far, s.round_off = bool(far), ROUND_OFF
        s.edge, s.landing_share, prev, landing, free, free_bound = plan
        s.free_bound = bool(free_bound)
        s.bridging = bridge is not None and bool((self.hybrid or proj).bridging)
        # Bridged, the run's tolerances stay its own inside a passage: the segment
        # observes the passages itself (`mechsim_projection_segment`).
        s.handles_passages = s.through = s.bridging
        s.has_bprev, s.has_landing, s.has_free = (x is not None for x in (prev, landing, free))
        s.has_planned = s.plan_reset = False
        s.bprev_t, s.bprev_rate = prev if prev is not None else (0.0, 0.0)
        s.landing = landing if landing is not None else 0.0
        s.free_step = free if free is not None else 0.0
        s.projections = 0
        if self.hybrid is not None:
            policy = self.hybrid.policy
            s.policy_steps, s.stable, s.stable_steps = policy.steps, policy.stable, \
                policy.stable_steps
            s.previous, s.lu_limit = policy.previous, limit
        return True

    def _load(self, run, solver, o) -> None:
        """The run's state into the engine's structure and buffers: the integrator's, the
        samples' and the monitor's."""
        steps = self.steps
        s, b, (n, m, _) = steps.s, steps.buffers, steps.shape
        samples = run.out.samples
        s.steps = run.stats.steps
        s.max_steps = -1 if run.s.max_steps is None else run.s.max_steps
        s.runaway_from, s.runaway_every = RUNAWAY_FROM, RUNAWAY_EVERY
        steps.load_integrator(solver)
        s.every_step = self.every_step
        s.n_ts, s.next = (0, 0) if self.every_step else (len(run.out.ts), run.out.next)
        s.held, s.capacity = samples.held, len(samples.data)
        steps.point("rows", samples.data)
        s.evaluations = s.factorizations = s.corrections = 0
        s.run_max_step = run.bound.max_step
        s.min_advance = self.min_advance
        s.hybrid = self.hybrid is not None
        monitor = run.monitor
        s.open_at_start = monitor.open_passage is not None     # its first step: pending
        s.small = bool(run.problem.algebra.small)
        s.max_skip, s.enter, s.leave = monitor.max_skip, monitor.enter, monitor.leave
        s.blind, s.weyl_span, s.hermite_margin = BLIND, WEYL_SPAN, HERMITE_MARGIN
        s.grid, s.chord, s.rate_step, s.skip_rise = GRID, 1.0 + CHORD, RATE_STEP, SKIP_RISE
        s.machine_eps, s.rank_factor = np.finfo(float).eps, RANK_FACTOR
        s.skipped = o.skipped
        s.peak, s.peak_rate, s.last, s.rate = o.peak, o.peak_rate, o.last, o.rate
        s.has_prev = o.prev is not None
        if o.prev is not None:
            s.prev_t, s.prev_s, s.prev_rate = o.prev
        s.has_floor = o.floor is not None
        if o.floor is not None:
            s.floor_t, s.floor_v = o.floor
        s.has_measured = o.measured is not None
        if o.measured is not None:
            b["Jm"].reshape(m, n)[:] = o.measured[0]
            s.m_smin, s.m_smax, s.m_speed = o.measured[1:]
        s.ratio_speed = o.ratio_speed
        s.has_fall, s.cur = o.fall is not None, 0
        if o.fall is not None:
            b["Js"][:m * n] = o.fall.J.ravel()
            b["Ds"][:m * n] = o.fall.D.ravel()
            b["Ps"][:m * n] = o.fall.P.ravel()
            b["fall_scalars"][:4] = o.fall.t, o.fall.smin, o.fall.smax, o.fall.rise
        known = list(o.known.items())[:2]
        s.known_n = len(known)
        for j, (tk, (smin, smax)) in enumerate(known):
            b["known"][3 * j:3 * j + 3] = tk, smin, smax
        s.has_vector = o.vector is not None
        if o.vector is not None:
            s.vector_t = o.vector[0]
            b["vector"][:m] = o.vector[1]
        # the passages (`_load_projection`, `_load_partition`): the open one as the
        # monitor has it (its joints stay the loop's until the segment moves its minimum)
        s.handles_passages, s.passages_n, s.refine_tol = False, 0, REFINE_TOL
        here = self.open = monitor.open_passage
        s.has_open, s.open_u_set = here is not None, False
        if here is not None:
            s.open_t_start, s.open_t_min, s.open_s_min = here.t_start, here.t_min, here.s_min
            s.open_bridged = float(here.bridged)

    def _load_partition(self, start) -> None:
        """The partition's numbers (`Partitioned.plain_start`) and the hybrid's LU policy
        into the structure."""
        s = self.steps.s
        s.sign, s.repartition_at, s.cond_max, s.growth = start
        s.reference_span = REFERENCE_SPAN
        # the passages inside a step observed there; through the band too where the run's
        # tolerances stay the local ones inside a passage (else a step that ends inside
        # one, or begins in one, is the loop's: `Run.passage_tolerances`)
        s.handles_passages = True
        s.through = self.run.passage_tolerances() == self.run.local
        if self.hybrid is not None:
            policy = self.hybrid.policy
            s.held_steps, s.policy_steps = policy.held, policy.steps
            s.has_limit = policy.limit is not None
            s.limit = policy.limit if policy.limit is not None else 0.0

    def _store_partition(self, lu, solver, compiled):
        """What the committed steps changed in the integrator, the partition and the
        hybrid's LU policy; returns the rate the last step was taken on."""
        steps = self.steps
        s, b, (n, m, f) = steps.s, steps.buffers, steps.shape
        N, r = 2 * f, n - f
        solver.stepped_in_engine(compiled, s.t, s.t_old, s.h_abs, s.h_previous,
                                 b["y"][:N].copy(), b["fy"][:N].copy(), b["y_old"][:N].copy(),
                                 b["K"].reshape(solver.K_extended.shape), s.evaluations)
        if s.count > bool(s.pending):            # a step committed whole: the partition's end
            lu.accepted_in_engine(b["J_end"].reshape(m, n).copy(),
                                  b["kept_inverse"][:r * r].reshape(r, r).copy(),
                                  b["kept_reduced"][:r * f].reshape(r, f).copy(), int(s.sign),
                                  float(b["kept_block"][1]), s.repartition_at)
        self.run.problem.counters.factorizations += s.factorizations
        if self.hybrid is not None:
            policy = self.hybrid.policy
            policy.held, policy.steps = s.held_steps, s.policy_steps
            policy.limit = s.limit if s.has_limit else None
        return compiled

    def _store_projection(self, proj, solver):
        """What the committed steps changed in the integrator (its state's rate evaluated
        again after each projection, as `adapters.correct_in_place` does), the projection
        method and the hybrid's count towards LU; returns the rate the last step was
        taken on."""
        steps = self.steps
        s, b, N = steps.s, steps.buffers, 2 * steps.shape[0]
        # the rate of the last step (a pending step's: the far flag it was taken with)
        compiled = proj.compiled_rate(far=bool(s.far if s.pending else s.far_taken))
        solver.stepped_in_engine(compiled, s.t, s.t_old,
                                 s.h_abs, s.h_previous, b["y"][:N].copy(), b["fy"][:N].copy(),
                                 b["y_old"][:N].copy(), b["K"].reshape(solver.K_extended.shape),
                                 s.evaluations)
        # each correction in place evaluated the rate again (`correct_in_place`)
        solver.nfev += s.corrections
        counters = self.run.problem.counters
        counters.rhs += s.corrections
        counters.factorizations += s.corrections
        counters.projections += s.projections
        proj.accepted_in_engine(bool(s.far))
        if self.hybrid is not None:
            policy = self.hybrid.policy
            policy.steps, policy.stable, policy.previous = s.policy_steps, s.stable, s.previous
        return compiled

    def _store_passages(self, monitor, m) -> None:
        """The passages a segment recorded and the one it is inside, into the monitor,
        their joints from the singular vectors it kept (the loop's open passage's where the
        segment left its minimum as it was)."""
        s, b = self.steps.s, self.steps.buffers
        loaded = self.open.joints if self.open is not None else ()

        def joints(vector_set, u):
            return monitor.joints_of(u) if vector_set else loaded
        rows = b["passages"][:s.passages_n * (6 + m)].reshape(-1, 6 + m)
        closed = []
        for row in rows:
            t_start, t_end, s_min, t_min, bridged, vector_set = row[:6].tolist()
            closed.append(SingularPassage(t_start, t_end, s_min, joints(vector_set, row[6:]),
                                          t_min, bool(bridged)))
        still = OpenPassage(s.open_t_start, s.open_t_min, s.open_s_min,
                            joints(s.open_u_set, b["open_u"][:m]), bool(s.open_bridged)) \
            if s.has_open else None
        monitor.took(closed, still)

    def _interpolant(self, solver, compiled):
        """A pending step's dense output as `CompiledDOP853.dense_output` would form it,
        from the coefficients the engine formed (the same extra stages, counted there);
        None where it formed none."""
        steps = self.steps
        s = steps.s
        if not (s.pending == PENDING_OBSERVE and s.dense_formed):
            return None
        rows, N = s.dense_rows + 3, 2 * steps.shape[2]
        F = steps.buffers["F"][:rows * N].reshape(rows, N).copy()
        return Interpolant(s.t_old, s.t, np.ascontiguousarray(solver.y_old, dtype=float), F,
                           compiled.interpolate)

    def _store(self, run, monitor, count, compiled) -> None:
        """What `count` committed steps changed in the monitor and the run (the last on the
        rate `compiled`), and what a pending step leaves to the loop (`pending`)."""
        steps = self.steps
        s, b, (n, m, _) = steps.s, steps.buffers, steps.shape
        size = m * n
        run.solver.max_step = s.max_step
        fall = None
        if s.has_fall:
            c = s.cur
            t, smin, smax, rise = b["fall_scalars"][4 * c:4 * c + 4].tolist()
            part = slice(c * size, (c + 1) * size)
            fall = Fall(t, b["Js"][part].reshape(m, n).copy(),
                        (b["Ds"][part].reshape(m, n).copy(), b["Ps"][part].reshape(n, m).copy()),
                        smin, smax, rise)
        monitor.resume(Observation(
            s.skipped, (s.floor_t, s.floor_v) if s.has_floor else None,
            (s.prev_t, s.prev_s, s.prev_rate) if s.has_prev else None, s.last, s.rate,
            s.peak, s.peak_rate,
            (b["Jm"].reshape(m, n).copy(), s.m_smin, s.m_smax, s.m_speed)
            if s.has_measured else None,
            s.ratio_speed, fall,
            {b["known"][3 * j]: (b["known"][3 * j + 1], b["known"][3 * j + 2])
             for j in range(s.known_n)},
            (s.vector_t, b["vector"][:m].copy()) if s.has_vector else None))
        if s.handles_passages:
            self._store_passages(monitor, m)
        # the run (Run._advance, _accept, _bridge)
        stats, log = run.stats, steps.log[:count]
        first = stats.steps + 1
        stats.steps, stats.retries = s.steps, 0
        stats.corrections += s.corrections
        run.out.samples.held = s.held
        # a pending step's end sample is the loop's to record (`pending`)
        run.out.next = run.out.next + count - bool(s.pending) if self.every_step else s.next
        run.t_reached = s.t
        run.recent.extend(log[:, 0].tolist())
        bridge, bound = run.bridge, run.bound.max_step
        planned = bridge is not None and s.kind == 0 and s.bridging
        self.pending = None
        if s.pending:
            self.pending = Pending(s.t_old, s.t, run.solver.y, s.pending == PENDING_OBSERVE,
                                   self._interpolant(run.solver, compiled))
        run.runaway.note_speeds(first, log[:, 1], log[:, 2])
        # the bridge after Run._bridge's plans, which planned nothing or a landing (the
        # engine's, `bridge_plan`); a pending step's is the loop's own, after its end
        if planned:
            bridge.planned_in_engine(
                (s.bprev_t, s.bprev_rate) if s.has_bprev else None,
                s.landing if s.has_landing else None, s.free_step if s.has_free else None,
                bool(s.free_bound),
                ((s.planned_t, s.planned_star), s.plan_rate) if s.has_planned else None,
                bool(s.plan_reset))
        elif bridge is not None:
            for h_free in log[:count - bool(s.pending), 3].tolist():
                bridge.note_step(min(h_free, bound), h_free >= bound)
