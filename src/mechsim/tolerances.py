"""`Tolerances`: a run's rtol and atol, and every tolerance mechsim derives from them, in one
place. The formulations, the passage bridge, the output samples and the work integral ask
it; none re-derives its own from rtol and atol."""

from __future__ import annotations

import math
from dataclasses import dataclass


# The share of the asked rtol a run's local error test gets from `LOCAL_FULL` up, and the
# rtol from which down it gets all of it (`Tolerances.local`).
LOCAL_SHARE = 1.0 / 100.0
LOCAL_FULL = 1e-6
LOCAL_FLOOR = 1e-11
# The tightest relative local tolerance a run steps through a singular passage's band with
# (`Tolerances.through_passage`).
PASSAGE_FLOOR = 1e-9


@dataclass(frozen=True)
class Tolerances:
    """The integrator's tolerances and what follows from them (all absolute, in the
    coordinates' units unless said otherwise).

    rtol, atol : the local error test's relative and absolute tolerances, as in scipy's
        `solve_ivp` (error ≤ atol + rtol·abs(y) per component)

    A run asks for an accuracy of its motion and integrates with `local()` of it.
    """
    rtol: float
    atol: float

    def __post_init__(self):
        for name, value in (("rtol", self.rtol), ("atol", self.atol)):
            if not (isinstance(value, (int, float)) and not isinstance(value, bool)
                    and value > 0 and math.isfinite(value)):
                raise ValueError(f"`{name}` must be a positive number, got {value!r:.40}")

    def local(self) -> "Tolerances":
        """The tolerances a run integrates with when these are the accuracy asked of its
        motion: `LOCAL_SHARE` of them from rtol `LOCAL_FULL` up, all of them from
        `LOCAL_FLOOR` down, and between a share falling geometrically with rtol (so the
        local tolerance still falls ~16× for each 100× rtol); atol in the same proportion.

        A local error test passed at every step leaves a global error that adds up over
        the steps and the turns of a mechanism; the share keeps a run's error of the
        order of rtol, also over the many turns of a mechanism that turns over and over
        (whose energy errors grow into its speed). Near `LOCAL_FLOOR` round-off, not
        truncation, sets the error, and a tighter local tolerance only costs time
        (docs/design-notes.md, tolerances).
        """
        r = self.rtol
        if r >= LOCAL_FULL:
            share = LOCAL_SHARE
        elif r <= LOCAL_FLOOR:
            share = 1.0
        else:
            share = LOCAL_SHARE ** (math.log(r / LOCAL_FLOOR) /
                                    math.log(LOCAL_FULL / LOCAL_FLOOR))
        return Tolerances(r * share, self.atol * share)

    def through_passage(self) -> "Tolerances":
        """The tolerances to step through a singular passage's band with, where no bridge
        crosses it, when these are the local ones: these, but rtol not below
        `PASSAGE_FLOOR` (atol in proportion). Close to the configuration the projection
        method's q̈ carries round-off amplified by 1/σ_min² and the truncation's switch
        where σ_min crosses its cut, about 1e-9 relative (the bridge's estimates there
        read the same); a tighter local test resolves that noise, not the motion, and its
        steps crawl through the configuration (docs/design-notes.md, tolerances)."""
        if self.rtol >= PASSAGE_FLOOR:
            return self
        return Tolerances(PASSAGE_FLOOR, self.atol * PASSAGE_FLOOR / self.rtol)

    @property
    def newton(self) -> float:
        """Newton's tolerance on ‖Φ‖ for the dependent coordinates of a partition: well
        below what the integrator resolves, so its error is the integrator's."""
        return 1e-2 * self.atol

    @property
    def manifold(self) -> float:
        """How far off the constraints (‖Φ‖∞) a state of the full coordinates may drift
        before it is projected back, and to what output samples are settled: above one
        step's own error (a lower threshold would restart the integrator after every
        step; multistep methods then never leave their start-up)."""
        return max(10.0 * self.rtol, 100.0 * self.atol)

    @property
    def tight_manifold(self) -> float:
        """The same for the projection method: near a singular configuration any
        inconsistency of (q, v) enters γ and is amplified by 1/σ_min in J̃⁺γ, so states
        are kept on the manifold to round-off."""
        return max(1e-13, 1e-3 * self.atol)

    def inner(self) -> "Tolerances":
        """The tolerances of an integration inside a step (the bridge's reference
        solution over a passage): a hundredth of these, rtol not below 1e-13."""
        return Tolerances(max(1e-13, 1e-2 * self.rtol), 1e-2 * self.atol)

    @property
    def work(self) -> float:
        """The relative tolerance of the work integral along the steps (a tenth of rtol,
        not below 1e-13): the energy balance then measures the solver."""
        return max(0.1 * self.rtol, 1e-13)
