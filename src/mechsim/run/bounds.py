"""The run's bookkeeping around its integrator: the one bound on the next step, and the
counts of what the run spent (`mechsim.run.loop`)."""

from __future__ import annotations

from dataclasses import dataclass

from ..integrators.adapters import proposed_step


class StepBound:
    """The one bound on the next step: the run's `max_step`, lowered by the formulation's
    `step_limit` (the hybrid ahead of a singularity) and by the passage bridge's landing.
    scipy's RK, Radau and BDF and the Adams method read `max_step` at every step, so a bound
    applies at once; LSODA takes its bound only when it starts, so a new bound restarts it
    (`restart_for`)."""

    def __init__(self, max_step: float, read_at_start: bool):
        self.max_step = max_step
        self._started_with = max_step if read_at_start else None

    def after_step(self, solver, limit: float | None) -> None:
        """Bound the next step by the run's max_step and the formulation's `limit`."""
        solver.max_step = self.max_step if limit is None else min(self.max_step, limit)

    def land(self, solver, reach: float) -> None:
        solver.max_step = min(solver.max_step, reach)

    def restart_for(self, solver):
        """(first step, bound) for an LSODA restart where the bound decides the next step (a
        tighter one below the step it would take, or a looser one where the old bound held
        it); None otherwise."""
        if self._started_with is None:
            return None
        want = getattr(solver, "max_step", self._started_with)
        h_next = proposed_step(solver) or 0.0
        if (want < self._started_with and h_next > want) or \
                (want > self._started_with and h_next >= 0.9 * self._started_with):
            self._started_with = want
            return (min(h_next, want) or None), want
        return None


@dataclass
class Statistics:
    """What a run spent, beyond the live integrator's own counts."""
    steps: int = 0
    restarts: int = 0
    rejected: int = 0
    corrections: int = 0
    retries: int = 0            # consecutive retakes of a step that left its branch
    bridges: int = 0
    nfev: int = 0
    njev: int = 0
    nlu: int = 0

    def retire(self, solver) -> None:
        """Add the counts of an integrator the run replaces."""
        self.nfev += solver.nfev
        self.njev += int(getattr(solver, "njev", 0))
        self.nlu += int(getattr(solver, "nlu", 0))
        self.rejected += int(getattr(solver, "n_rejected", 0))
