"""The sensitivities of the singular passages' instants, for a run that carries its
motion's sensitivities (`mechsim.formulations.tangent.Tangent.passage_time`).

A passage's instant t_min is where the monitor found its smallest singular value (observed
at a step's end, refined inside a step, or predicted by the passage bridge). Each time a
step or a bridge holds the instant of the open passage or of one just recorded, the state
and sensitivities about it (the step's dense output, the bridge's interpolant) give
∂t*/∂k, the instant refined first where Φ_q's singular value crosses zero;
the result's `SingularPassage.time_sensitivity` takes the one computed at its final
instant.
"""

from __future__ import annotations

from dataclasses import replace


class PassageTimes:
    """∂t*/∂k of the passages `monitor` records, where `form` carries sensitivities (else
    nothing is computed)."""

    def __init__(self, form, monitor):
        self.form = form if hasattr(form, "passage_time") else None
        self.monitor = monitor
        self.at = {}                     # instant -> {name: ∂t*/∂name}
        self.seen = 0                    # the passages recorded at the last note

    def note(self, t_old, t_new, state_at) -> None:
        """Compute at the instants of the open passage and of those recorded since the last
        note that lie in (t_old, t_new] (a closed passage's instant no longer moves: it was
        the open one's when its step came); `state_at(t) -> (q, v, x)`, x the
        sensitivities."""
        if self.form is None:
            return
        monitor = self.monitor
        here = [p.t_min for p in monitor.passages[self.seen:]]
        self.seen = len(monitor.passages)
        if monitor.open_passage is not None:
            here.append(monitor.open_passage.t_min)
        for tm in here:
            if tm is not None and t_old < tm <= t_new and tm not in self.at:
                self.at[tm] = self.form.passage_time(tm, state_at, (t_old, t_new))

    def attach(self, passages) -> list:
        """The passages, each with the time sensitivity computed at its instant."""
        if self.form is None:
            return passages
        return [replace(p, time_sensitivity=dict(self.at.get(p.t_min, {})))
                for p in passages]
