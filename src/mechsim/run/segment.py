"""Consecutive plain steps of a small rigid mechanism in LU, taken in the compiled engine.

A step of LU partitioning on a small rigid mechanism costs the compiled engine tens of
microseconds and the Python loop around it several times that: the output samples, the
singularity monitor's observation, the hybrid's policy, the partition's end, the run's
bookkeeping, each a few numpy calls on arrays of a dozen numbers. Where a step is plain
(nothing happens but the step, its samples and the partition's predictor: no passage in
reach, no change of partition or of formulation, no sample due at its end), all of that is
arithmetic that `mechsim_lu_segment` does in C, step after step, until a step is not
plain. That step it drops; the Python loop (`mechsim.run.loop.Run`) takes it from the same
state, with its own decisions.

The contract is the Python loop's numbers to the bit: the segment makes the decisions the
loop would make (the same comparisons in the same order on the same doubles) and calls the
engine's functions the loop calls (the DOP853 step, its dense output, the partition's end
and predictor, the samples' and the monitor's evaluations); the few formulas the loop
evaluates in Python floats (the monitor's rates and bounds, the policy's limit, the
re-reference) it evaluates in the same order. A run with segments and one without them give
bitwise the same samples, steps and counts (a test).

It applies to runs of "lu" and of the hybrid in its LU phase with the compiled DOP853 on a
compiled partition (`Partitioned.compiled_rate`) and the compiled monitor (a dense
algebra's engine, no redundant constraints), with an output grid or a sample at every
step, and nothing else to do at a step: no events, work integral, streamed output, state
extras, sensitivities or fixed step. After a segment declines its first step the loop
tries it again only after twice as many steps as the last time (up to `BACKOFF_MAX`), so a
mechanism whose steps are seldom plain (the double four-bar near its passages) pays little
for the tries; after a segment that stopped on a step it declined, that step is the
loop's without a try (taking the segment's passage search of it). The engine's side
is `mechsim.codegen.steps.PlainSteps`, which the problem's algebra gives
(`plain_steps`).
"""

from __future__ import annotations

import numpy as np

from ..formulations.hybrid import Hybrid
from ..formulations.monitor import (BLIND, CHORD, GRID, HERMITE_MARGIN, RATE_STEP, WEYL_SPAN,
                                    Fall, Observation)
from ..problem.algebra import RANK_FACTOR
from ..formulations.partitioned import REFERENCE_SPAN, Partitioned
from ..integrators.compiled import (MAX_FACTOR, MIN_FACTOR, SAFETY, CompiledDOP853,
                                    dense_matrix, extra_tableau, tableau)
from .runaway import RUNAWAY_EVERY, RUNAWAY_FROM

# The longest wait, in steps, before a segment is tried again after it declined its first.
BACKOFF_MAX = 64
# Segments can be switched off (`enabled = False`), for the test that compares.
enabled = True


class Segment:
    """The segments of one run (`for_run`); `advance()` takes one, or says it did not."""

    def __init__(self, run, lu, steps, min_advance):
        self.run, self.lu, self.steps = run, lu, steps
        self.hybrid = run.form if isinstance(run.form, Hybrid) else None
        self.min_advance = min_advance
        self.wait = self.backoff = 0
        self.every_step = run.out.ts is None          # a sample at every step's end
        if not self.every_step:
            steps.point("ts", run.out.ts)

    @classmethod
    def for_run(cls, run, min_advance) -> "Segment | None":
        """The run's segments, where they apply to it (module docstring); else None.
        `min_advance`: the shortest step a segment takes (shorter ones are the stall
        rule's to judge, `mechsim.run.loop.STALL_SPAN`)."""
        form, s, prob = run.form, run.s, run.problem
        if not enabled or not issubclass(run.solver_cls, CompiledDOP853) or SAFETY is None:
            return None
        lu = form.lu if isinstance(form, Hybrid) else form
        if type(lu) is not Partitioned or (form is not lu and type(form) is not Hybrid):
            return None
        if s.events is not None or s.stream is not None or s.h is not None or \
                run.work is not None or run.out.extras is not None or \
                run.passage_times.form is not None or run.keep_past or \
                run.monitor is None or run.monitor.redundant:
            return None
        basis = getattr(lu, "basis", None)
        if lu.engine is None or basis is None or basis.sparse:
            return None
        rows = 1 if s.ts is None else min(len(s.ts), 4096)
        steps = prob.algebra.plain_steps(basis.f, rows,
                                         (tableau(), extra_tableau(), dense_matrix()))
        return None if steps is None else cls(run, lu, steps, min_advance)

    def advance(self) -> bool:
        """Steps taken in a segment from the run's present state (True), or none (False:
        the loop takes the next step)."""
        if self.wait:
            self.wait -= 1
            return False
        run, lu = self.run, self.lu
        solver, monitor = run.solver, run.monitor
        if (self.hybrid is not None and self.hybrid.active is not lu) or \
                not isinstance(solver, CompiledDOP853) or solver.status != "running" or \
                solver.t == solver.t_bound or solver.y.dtype != np.float64 or \
                monitor.open_passage is not None or monitor.blind or \
                run.tolerances != run.local or solver.rate is None:
            return False
        start = lu.plain_start()
        if start is None:
            return False
        compiled = solver.rate()
        if compiled is None or compiled.kind != 1 or compiled.context != lu.engine.context:
            return False
        self._load(run, solver, monitor.observation(), start)
        count = self.steps.run(lu.engine.context, run.problem.algebra.engine.context)
        if not count:
            self.wait = self.backoff = min(max(2 * self.backoff, 1), BACKOFF_MAX)
            return False
        # A segment that stopped on a step it declined leaves that very step next: the
        # loop's, without another try.
        self.backoff, self.wait = 0, int(self.steps.declined)
        self._store(run, lu, solver, monitor, compiled, count)
        return True

    def _load(self, run, solver, o, start) -> None:
        """The run's state into the engine's structure and buffers."""
        steps = self.steps
        s, b, (n, m, _) = steps.s, steps.buffers, steps.shape
        samples = run.out.samples
        s.steps = run.stats.steps
        s.max_steps = -1 if run.s.max_steps is None else run.s.max_steps
        s.runaway_from, s.runaway_every = RUNAWAY_FROM, RUNAWAY_EVERY
        s.stages = solver.n_stages
        s.extra_rows, s.extra_width = solver.A_EXTRA.shape
        s.dense_rows, s.dense_cols = solver.D.shape
        s.every_step = self.every_step
        s.n_ts, s.next = (0, 0) if self.every_step else (len(run.out.ts), run.out.next)
        s.held, s.capacity = samples.held, len(samples.data)
        steps.point("rows", samples.data)
        steps.point("atol", solver.atol_array)
        s.evaluations = s.factorizations = s.corrections = 0
        s.t, s.h_abs, s.t_bound, s.direction = solver.t, solver.h_abs, solver.t_bound, \
            solver.direction
        s.max_step, s.run_max_step, s.rtol = solver.max_step, run.bound.max_step, solver.rtol
        s.safety, s.min_factor, s.max_factor = SAFETY, MIN_FACTOR, MAX_FACTOR
        s.exponent = solver.error_exponent
        s.min_advance = self.min_advance
        b["y"][:] = solver.y
        b["fy"][:] = solver.f
        s.sign, s.repartition_at, s.cond_max, s.growth = start
        s.reference_span = REFERENCE_SPAN
        policy = self.hybrid.policy if self.hybrid is not None else None
        s.hybrid = policy is not None
        if policy is not None:
            s.held_steps, s.policy_steps = policy.held, policy.steps
            s.has_limit = policy.limit is not None
            s.limit = policy.limit if policy.limit is not None else 0.0
        monitor = run.monitor
        s.small = bool(run.problem.algebra.small)
        s.max_skip, s.enter, s.leave = monitor.max_skip, monitor.enter, monitor.leave
        s.blind, s.weyl_span, s.hermite_margin = BLIND, WEYL_SPAN, HERMITE_MARGIN
        s.grid, s.chord, s.rate_step = GRID, 1.0 + CHORD, RATE_STEP
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
            s.m_smin, s.m_smax = o.measured[1], o.measured[2]
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

    def _store(self, run, lu, solver, monitor, compiled, count) -> None:
        """What `count` committed steps changed, back into the run's objects."""
        steps = self.steps
        s, b, (n, m, f) = steps.s, steps.buffers, steps.shape
        N, r, size = 2 * f, n - f, m * n
        solver.stepped_in_engine(compiled, s.t, s.t_old, s.h_abs, s.h_previous,
                                 b["y"][:N].copy(), b["fy"][:N].copy(), b["y_old"][:N].copy(),
                                 b["K"].reshape(solver.K_extended.shape), s.evaluations)
        solver.max_step = s.max_step
        lu.accepted_in_engine(b["J_end"].reshape(m, n).copy(),
                              b["inverse"][:r * r].reshape(r, r).copy(),
                              b["reduced"][:r * f].reshape(r, f).copy(), int(s.sign),
                              float(b["block"][1]), s.repartition_at)
        run.problem.counters.factorizations += s.factorizations
        if self.hybrid is not None:
            policy = self.hybrid.policy
            policy.held, policy.steps = s.held_steps, s.policy_steps
            policy.limit = s.limit if s.has_limit else None
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
            (b["Jm"].reshape(m, n).copy(), s.m_smin, s.m_smax) if s.has_measured else None,
            s.ratio_speed, fall,
            {b["known"][3 * j]: (b["known"][3 * j + 1], b["known"][3 * j + 2])
             for j in range(s.known_n)}))
        # the run (Run._advance, _accept, _bridge)
        stats, log = run.stats, steps.log[:count]
        first = stats.steps + 1
        stats.steps, stats.retries = s.steps, 0
        stats.corrections += s.corrections
        run.out.samples.held = s.held
        run.out.next = run.out.next + count if self.every_step else s.next
        run.t_reached = s.t
        run.recent.extend(log[:, 0].tolist())
        bridge, bound = run.bridge, run.bound.max_step
        for j, (_, h, speed, h_free) in enumerate(log.tolist()):
            run.runaway.note_speed(first + j, h, speed)
            if bridge is not None:
                bridge.note_step(min(h_free, bound), h_free >= bound)
