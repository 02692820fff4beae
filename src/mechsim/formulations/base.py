"""The contract every formulation fulfils (scipy's `OdeSolver` docstring style).

A formulation holds a NumericProblem and exposes a first-order ODE y' = f(t, y). To add one:

1. set `name` (its key in `METHODS`) and `default_integrator`;
2. `initial_state(t, q, v)` -> y0, from a consistent (assembled) state;
3. `rhs(t, y)` -> y', counting itself in `problem.counters.rhs`;
4. `state(t, y)` -> (q, v), the full coordinates and velocities;
5. `after_step(t, y)` -> a corrected y or None. A correction that keeps the meaning of the
   state (a projection) is applied in place where the integrator allows it; one that changes
   it (a new partition, a switch of formulation) must set `self.layout_changed = True`, and
   the manager restarts the integrator there; one that moves the state by a constant with
   the motion unchanged (a partition re-referenced) sets `self.shifted = True`, and the
   integrator takes the offset in place where it can.

`options` declares the keyword arguments of `simulate` that the formulation accepts, each an
`mechsim.options.Option` (default, type, range); they are checked before any work and set
as attributes. Anything it does not know is an error naming the option and the closest
valid name.
"""

from __future__ import annotations

import numpy as np

from ..options import check_all, unknown_names
from ..problem import NumericProblem


class Formulation:
    name = ""
    default_integrator = "DOP853"
    options: dict = {}
    monitor = None        # the manager's SingularityMonitor, set before initial_state
    last_step = 0.0       # size of the step just accepted, set before after_step
    failure = ""          # what went wrong last, for the manager's failure message
    layout_changed = False  # set by after_step when its correction changes the coordinates
    shifted = False         # set by after_step when its correction is a constant offset
    step_limit = None       # largest next step the formulation can take safely (None: any)
    bridge = None           # a PassageBridge when the formulation can cross passages by one
    bridging = False        # whether the manager may use it at the present step
    # Whether it integrates independent coordinates (partitioning): a mechanism with no
    # degree of freedom has none, and the manager runs it by the projection method instead.
    needs_freedom = False
    # Whether it resolves singular passages (follows the branch through them); where it
    # does not, a run that meets one says its motion may have left the branch there.
    resolves_passages = False

    def derivative(self, t: float, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """y' in the present layout at a consistent full state (q, v): what `rhs` gives at
        the y of that state, without solving for the state first. The manager uses it to
        re-express a multistep integrator's history after a switch or a new partition."""
        raise NotImplementedError

    def resume(self, t: float, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """The state y for a consistent (q, v) at t in the present layout (after a bridge)."""
        return self.initial_state(t, q, v)

    def __init__(self, problem: NumericProblem, rtol: float, atol: float, **options):
        message = unknown_names(options, self.options, f"method {self.name!r}")
        if message:
            raise ValueError(message)
        self.problem = problem
        self.rtol, self.atol = rtol, atol
        for key, value in check_all(self.options, options, f"method {self.name!r}").items():
            setattr(self, key, value)
        self.singular_passages: list = []
        self.switches: list = []
        # Steps (t_a, t_b) across which the partition's det(Φ_q D) changed sign: the
        # motion crossed a singular configuration or left its assembly branch there.
        self.sign_changes: list[tuple[float, float]] = []

    def initial_state(self, t: float, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def rhs(self, t: float, y: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    @property
    def integrand(self):
        """The right-hand side the integrator about to start calls: `rhs` (a manager of
        formulations hands over its active one's, a call less per evaluation; it restarts
        the integrator at every switch)."""
        return self.rhs

    def state(self, t: float, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        raise NotImplementedError

    def states(self, ts: np.ndarray, Y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(Q, V) with rows (q, v) = state(t, y) for each time of `ts` and row of Y (the
        output samples inside a step). One by one here; a formulation whose state takes
        a solve overrides it to solve for all samples at once."""
        pairs = [self.state(t, y) for t, y in zip(ts, Y)]
        return np.array([q for q, _ in pairs]), np.array([v for _, v in pairs])

    def after_step(self, t: float, y: np.ndarray) -> np.ndarray | None:
        return None

    def keeps_branch(self, t: float, y: np.ndarray) -> bool:
        """Whether the step just taken to (t, y) stayed on the assembly branch, as far as
        the formulation can tell; the manager takes a step that did not again, shorter."""
        return True
