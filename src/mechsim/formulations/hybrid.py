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

from ..options import Option
from ..records import Switch
from .base import Formulation
from .basis import SPARSE_MIN
from .partitioned import Partitioned
from .projection import Projection


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
        self.lu = Partitioned(problem, rtol, atol)
        self.proj = Projection(problem, rtol, atol)
        self.active = self.lu
        self.sign_changes = self.lu.sign_changes
        self.bridge = self.proj.bridge
        self._stable = 0
        self._recent: list[int] = []      # steps at which LU re-partitioned
        self._step = 0
        self._limit = None                # the step limit LU's last step was taken under
        self._held = 0                    # consecutive LU steps held by that limit
        # The compiled condition of LU's block (`_lu_ready`) where the block is dense.
        self.engine = self.proj.engine if problem.m < SPARSE_MIN else None

    def initial_state(self, t, q, v):
        self.proj.monitor = mon = self.monitor
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

    def resume(self, t, q, v):
        return self.active.resume(t, q, v)

    def keeps_branch(self, t, y):
        return self.active.keeps_branch(t, y)

    def rhs(self, t, y):
        return self.active.rhs(t, y)

    @property
    def integrand(self):
        return self.active.rhs

    def state(self, t, y):
        return self.active.state(t, y)

    def states(self, ts, Y):
        return self.active.states(ts, Y)

    def positions(self, ts, Y):
        return self.active.positions(ts, Y)

    def derivative(self, t, q, v):
        return self.active.derivative(t, q, v)

    def project_now(self, t, y):
        project = self.active.project_now
        return None if project is None else project(t, y)

    @property
    def failure(self) -> str:
        """What went wrong last in the formulation running now (or in the other one)."""
        return self.active.failure or self.lu.failure or self.proj.failure

    def _lu_ready(self, q, t) -> bool:
        """Would LU partitioning be well conditioned here? cond(Φ_u) of the set its pivoting
        picks, against a tenth of its re-partition threshold."""
        mon = self.monitor
        # Asked only where the monitor finds σ_min/σ_max clear of a passage: Φ_q has full
        # row rank there, unless that ratio is itself at round-off (redundant constraints).
        if mon is not None and mon.redundant:
            return False                  # projection throughout (see `initial_state`)
        full = mon is not None and mon.last * mon.peak > 1e-6
        if full and self.engine is not None:
            return self.engine.lu_condition(t, q) < 0.1 * self.lu.cond_max
        J = self.problem.phi_q(q, t)
        basis = self.lu.choose(J, J.shape[0] if full else None)
        return basis.block(J).condition() < 0.1 * self.lu.cond_max

    def _full_rank_partition(self, q, t) -> bool:
        """Does Φ_q have full row rank at (q, t), with a well-conditioned LU partition?"""
        J = self.problem.phi_q(q, t)
        basis = self.lu.choose(J)
        return basis.r == J.shape[0] and basis.block(J).condition() < 0.1 * self.lu.cond_max

    def _switch(self, t, y, to, reason):
        q, v = self.active.state(t, y)
        name_from = self.active.name
        self.active = to
        self._stable = 0
        self._limit, self._held = None, 0
        self._recent.clear()
        self.switches.append(Switch(t, name_from, to.name, reason))
        self.problem.counters.switches += 1
        self.layout_changed = True
        return to.initial_state(t, q, v)

    def after_step(self, t, y):
        # The projection formulation reads these as the manager's own formulation would.
        proj = self.proj
        proj.monitor, proj.last_step = self.monitor, self.last_step
        self._step += 1
        self.layout_changed = self.shifted = False
        self.step_limit = None
        mon = self.monitor
        s = mon.last if mon else 1.0
        if self.active is self.lu and mon and mon.rate < 0.0 and s > mon.enter:
            # Do not let LU stride across a singular configuration: the next step may only
            # reach the predicted entry into the band, where the manager switches.
            # Half the linear prediction: s falls faster than its tangent when the motion
            # accelerates into the singularity (the seed's falling four-bar does).
            self.step_limit = max(0.5 * (s - mon.enter) / -mon.rate, 1e-6)
        if self.active is self.lu:
            # Each step held by the limit covers half the rest of the way to the entry, so
            # an integrator whose steps are short anyway (Adams) would creep up to it in
            # steps halving down to the limit's floor, and then climb back from there (40
            # steps a passage on the double four-bar): after two held steps it switches.
            held = self._limit is not None and self.last_step >= 0.99 * self._limit
            self._held = self._held + 1 if held else 0
            self._limit = self.step_limit
            if mon and (mon.predicted_within(self.last_step) or self._held >= 2):
                if mon.inside:
                    why = (f"σ_min/σ_max at {s:.3g} of its peak (< {mon.enter:g}): near a "
                           f"singular configuration (joints {', '.join(mon.open_passage.joints)})")
                else:
                    why = (f"σ_min/σ_max at {s:.3g} of its peak, falling {-mon.rate:.3g}/s: "
                           "a singular configuration ahead")
                return self._switch(t, y, self.proj, why)
            out = self.lu.after_step(t, y)
            self.layout_changed, self.shifted = self.lu.layout_changed, self.lu.shifted
            if out is not None and self.lu.layout_changed:
                self._recent = [k for k in self._recent if self._step - k < self.burst_steps]
                self._recent.append(self._step)
                if len(self._recent) >= self.repartition_burst:
                    return self._switch(t, out, self.proj,
                                        f"independent set changed {len(self._recent)} times in "
                                        f"{self.burst_steps} steps")
            return out
        out = self.proj.after_step(t, y)
        q, _ = self.proj.state(t, y if out is None else out)
        growing = self.last_step >= 0.99 * getattr(self, "_prev_step", 0.0)
        self._prev_step = self.last_step
        clear = not mon or (s > mon.leave and not mon.predicted_within(self.last_step))
        if clear and growing and self._lu_ready(q, t):
            self._stable += 1
        else:
            self._stable = 0
        if self._stable >= self.stable_steps:
            return self._switch(t, y if out is None else out, self.lu,
                                f"{self._stable} stable steps clear of the singularity "
                                f"(σ_min/σ_max at {s:.3g} of its peak)")
        return out
