"""The hybrid solver manager of seed 001, section 3 (steps 1–13).

LU coordinate partitioning is cheap per step but may jump branch at a singular
configuration; the projection method passes singular configurations but, as the seed
computes it, costs an SVD per evaluation (mechsim's takes a Cholesky factor clear of the
band and is about as cheap as LU; see `mechsim.formulations.projection`). The manager
integrates with LU, switches to projection when the singularity monitor reports that Φ_q is
nearly rank-deficient (σ_min/σ_max below its `enter` threshold) — or on the paper's symptom
of the independent set changing `repartition_burst` times within `burst_steps` steps — and
switches back to LU after `stable_steps` consecutive steps with the monitor above `leave`,
steps not shrinking, and an unchanged LU choice of independent coordinates (the paper: 5
steps at the largest step with a stable set). Each switch is recorded with its time and
reason.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

from ..options import Option
from ..records import Switch
from .base import Correction, Formulation
from .basis import SPARSE_MIN
from .partitioned import Partitioned
from .projection import Projection


@dataclass
class SwitchPolicy:
    """When the hybrid method leaves LU partitioning for the projection method and when it
    comes back (seed 001, section 3), from what the singularity monitor reads after each
    accepted step. It decides; `Hybrid` switches. Each decision is a reason (the text of
    the `Switch` record) or None.

    stable_steps : projection steps clear of the band, not shrinking, with LU ready, before
        going back to LU
    repartition_burst, burst_steps : LU re-partitions within that many steps that send the
        run to projection (the paper's symptom of a passage)
    """
    stable_steps: int = 5
    repartition_burst: int = 3
    burst_steps: int = 10
    steps: int = 0                  # accepted steps seen
    stable: int = 0                 # consecutive projection steps fit for LU
    held: int = 0                   # consecutive LU steps held by the limit
    limit: float | None = None      # the limit LU's last step was taken under
    previous: float = 0.0           # the last projection step's length
    recent: list[int] = field(default_factory=list)    # steps at which LU re-partitioned

    def switched(self) -> None:
        """A switch happened: every count starts again."""
        self.stable, self.limit, self.held = 0, None, 0
        self.recent.clear()

    def lu_limit(self, mon) -> float | None:
        """The largest next LU step: LU may not stride across a singular configuration, so
        the next step may only reach half the linearly predicted entry into the band (σ
        falls faster than its tangent when the motion accelerates into the singularity, as
        the seed's falling four-bar does), where the manager switches; None where σ is not
        falling towards the band."""
        if mon is None or not mon.rate < 0.0:
            return None
        s = mon.last
        if not s > mon.enter:
            return None
        return max(0.5 * (s - mon.enter) / -mon.rate, 1e-6)

    def leave_lu(self, mon, step: float, limit: float | None) -> str | None:
        """Why LU, having taken a step of length `step`, hands over to projection now.
        Each step held by the limit covers half the rest of the way to the entry, so an
        integrator whose steps are short anyway (Adams) would creep up to it in steps
        halving down to the limit's floor (40 steps a passage on the double four-bar):
        after two held steps it switches."""
        held = self.limit is not None and step >= 0.99 * self.limit
        self.held = self.held + 1 if held else 0
        self.limit = limit
        if not mon or not (mon.predicted_within(step) or self.held >= 2):
            return None
        s = mon.last
        if mon.inside:
            return (f"σ_min/σ_max at {s:.3g} of its peak (< {mon.enter:g}): near a "
                    f"singular configuration (joints {', '.join(mon.open_passage.joints)})")
        return (f"σ_min/σ_max at {s:.3g} of its peak, falling {-mon.rate:.3g}/s: "
                "a singular configuration ahead")

    def repartitioned(self) -> str | None:
        """LU chose a new partition at this step: why that sends the run to projection."""
        self.recent = [k for k in self.recent if self.steps - k < self.burst_steps]
        self.recent.append(self.steps)
        if len(self.recent) >= self.repartition_burst:
            return (f"independent set changed {len(self.recent)} times in "
                    f"{self.burst_steps} steps")
        return None

    def back_to_lu(self, mon, step: float, lu_ready) -> str | None:
        """Why projection, having taken a step of length `step`, hands back to LU now:
        `stable_steps` steps in a row with σ above `leave` and not predicted to fall into
        the band within a step, steps not shrinking, and `lu_ready()` (LU's partition well
        conditioned there)."""
        growing = step >= 0.99 * self.previous
        self.previous = step
        clear = not mon or (mon.last > mon.leave and not mon.predicted_within(step))
        if clear and growing and lu_ready():
            self.stable += 1
        else:
            self.stable = 0
        if self.stable < self.stable_steps:
            return None
        s = mon.last if mon else 1.0
        return (f"{self.stable} stable steps clear of the singularity "
                f"(σ_min/σ_max at {s:.3g} of its peak)")


class Hybrid(Formulation):
    name = "hybrid"
    needs_freedom = True
    resolves_passages = True
    default_integrator = "DOP853"    # see docs/design-notes.md; "adams" on request
    options = {"stable_steps": Option.integer(5, low=1),
               "repartition_burst": Option.integer(3, low=1),
               "burst_steps": Option.integer(10, low=1)}

    def __init__(self, problem, rtol, atol, **options):
        super().__init__(problem, rtol, atol, **options)
        self.lu = Partitioned(problem, rtol, atol, monitor=self.monitor)
        self.proj = Projection(problem, rtol, atol, monitor=self.monitor)
        self.active = self.lu
        self.sign_changes = self.lu.sign_changes
        self.bridge = self.proj.bridge
        self.policy = SwitchPolicy(self.stable_steps, self.repartition_burst,
                                   self.burst_steps)
        # LU's block is dense below SPARSE_MIN rows: its condition may come compiled.
        self._dense_block = problem.m < SPARSE_MIN

    def initial_state(self, t, q, v):
        mon = self.monitor
        reason = None
        if mon is not None and mon.redundant:
            # Redundant constraints: a partition's dependent block is not square, so LU
            # would go without its chord and its branch test; the projection method's
            # truncation drops the redundant directions exactly.
            reason = f"{mon.redundant} redundant constraint equation(s)"
        else:
            # Starts on a singular configuration: no partition is safe. (A small
            # σ_min/σ_max alone may come from very unequal masses, with Φ_q of full rank
            # and a well-conditioned partition, which LU's reduced equations take.)
            s = mon.measure(q, t)[0] if mon is not None else 1.0
            if s < 1e-8 and not self._full_rank_partition(q, t):
                reason = f"starts near a singular configuration (σ ratio {s:.3g})"
        if reason is None:
            return self.lu.initial_state(t, q, v)
        self.active = self.proj
        self.switches.append(Switch(t, "lu", "projection", reason))
        return self.proj.initial_state(t, q, v)

    @property
    def bridging(self):
        return self.active is self.proj and self.proj.bridging

    @property
    def bridges_passages(self):
        return self.proj.bridging

    def resume(self, t, q, v, extra=None):
        return self.active.resume(t, q, v, extra)

    def keeps_branch(self, t, y):
        return self.active.keeps_branch(t, y)

    def rhs(self, t, y):
        return self.active.rhs(t, y)

    @property
    def integrand(self):
        return self.active.rhs

    def compiled_rate(self):
        return self.active.compiled_rate()

    def state(self, t, y):
        return self.active.state(t, y)

    def states(self, ts, Y):
        return self.active.states(ts, Y)

    def positions(self, ts, Y):
        return self.active.positions(ts, Y)

    def positions_context(self):
        return self.active.positions_context()

    def derivative(self, t, q, v):
        return self.active.derivative(t, q, v)

    def project_now(self, t, y):
        project = self.active.project_now
        return None if project is None else project(t, y)

    @property
    def failure(self) -> str:
        """What went wrong last in the formulation running now (or in the other one)."""
        return self.active.failure or self.lu.failure or self.proj.failure

    def lu_condition_limit(self) -> float | None:
        """The bound under which cond₁ of LU's block lets the run go back to LU
        (`_lu_ready`), where that test is compiled (a dense block, the engine, no redundant
        constraints; `mechsim.run.segment`); else None."""
        mon = self.monitor
        if not self._dense_block or mon is None or mon.redundant or \
                self.problem.algebra.engine is None:
            return None
        return 0.1 * self.lu.cond_max

    def _lu_ready(self, q, t) -> bool:
        """Would LU partitioning be well conditioned here? cond(Φ_u) of the set its pivoting
        picks, against a tenth of its re-partition threshold."""
        mon = self.monitor
        # Asked only where the monitor finds σ_min/σ_max clear of a passage: Φ_q has full
        # row rank there, unless that ratio is itself at round-off (redundant constraints).
        if mon is not None and mon.redundant:
            return False                  # projection throughout (see `initial_state`)
        full = mon is not None and mon.last * mon.peak > 1e-6
        if full and self._dense_block:
            cond = self.problem.algebra.lu_condition(t, q)
            if cond is not None:
                return cond < 0.1 * self.lu.cond_max
        J = self.problem.phi_q(q, t)
        basis = self.lu.choose(J, J.shape[0] if full else None)
        return basis.block(J).condition() < 0.1 * self.lu.cond_max

    def _full_rank_partition(self, q, t) -> bool:
        """Does Φ_q have full row rank at (q, t), with a well-conditioned LU partition?"""
        J = self.problem.phi_q(q, t)
        basis = self.lu.choose(J)
        return basis.r == J.shape[0] and basis.block(J).condition() < 0.1 * self.lu.cond_max

    def _switch(self, t, y, to, reason, step_limit=None) -> Correction:
        q, v = self.active.state(t, y)
        name_from = self.active.name
        self.active = to
        self.policy.switched()
        self.switches.append(Switch(t, name_from, to.name, reason))
        self.problem.counters.switches += 1
        return Correction(to.initial_state(t, q, v), layout_changed=True,
                          step_limit=step_limit)

    def after_step(self, t, y, step):
        policy, mon = self.policy, self.monitor
        policy.steps += 1
        if self.active is self.lu:
            limit = policy.lu_limit(mon)
            why = policy.leave_lu(mon, step, limit)
            if why:
                return self._switch(t, y, self.proj, why, limit)
            out = self.lu.after_step(t, y, step)
            if out.layout_changed:
                why = policy.repartitioned()
                if why:
                    return self._switch(t, out.y, self.proj, why, limit)
            return dataclasses.replace(out, step_limit=limit)
        out = self.proj.after_step(t, y, step)
        y_here = y if out.y is None else out.y
        why = policy.back_to_lu(mon, step,
                                lambda: self._lu_ready(self.proj.state(t, y_here)[0], t))
        if why:
            return self._switch(t, y_here, self.lu, why)
        return out
