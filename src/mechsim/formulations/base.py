"""The contract between a formulation and the run that integrates it (`mechsim.run.loop.Run`).

A formulation turns a `NumericProblem` into a first-order ODE y' = f(t, y) whose state y may
be any coordinates (all of q and v, independent ones, …) and says how to get back the full
(q, v). The run owns the integrator, the output, the singularity monitor and the status; it
calls the formulation as the `Formulation` docstring below says, and uses nothing else.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..options import check_all, unknown_names
from ..problem import NumericProblem
from ..tolerances import Tolerances


@dataclass(frozen=True)
class Correction:
    """What a formulation's `after_step` did after an accepted step. A `y` with neither
    flag keeps its meaning (a projection): it goes into the integrator in place where the
    integrator allows.

    Attributes
    ----------
    y : ndarray or None
        The state the run goes on from; None: the integrator's own.
    layout_changed : bool
        `y` means other coordinates (a new partition, a switch of formulation): the run
        restarts the integrator there.
    shifted : bool
        `y` is the integrator's state shifted by a constant (another reference): the
        integrator takes it in place where it can.
    step_limit : float or None
        The largest next step the formulation can take safely.
    """
    y: np.ndarray | None = None
    layout_changed: bool = False
    shifted: bool = False
    step_limit: float | None = None


KEEP = Correction()          # nothing corrected, no limit


class Formulation:
    """Base class and complete contract of a formulation (scipy's `OdeSolver` is the model).

    It is made with (problem, rtol, atol, monitor): the `NumericProblem`, the run's
    tolerances (`tol` derives the others) and its `SingularityMonitor` (None: unwatched).
    A new formulation is a subclass that sets `name` (its key in `METHODS`) and implements
    `initial_state`, `rhs` and `state`; everything else has a working default. A minimal
    one, the index-1 system without stabilization::

        class Index1(Formulation):
            name = "index-1"
            def initial_state(self, t, q, v):
                return np.concatenate([q, v])
            def rhs(self, t, y):
                self.problem.counters.rhs += 1
                q, v = self.state(t, y)
                _, J, _, gamma = self.problem.terms(q, v, t)
                qdd = self.problem.accelerations(J, self.problem.forces(t, q, v), gamma, q)[0]
                return np.concatenate([v, qdd])
            def state(self, t, y):
                return np.split(y, 2)

    Declared by the class
    ---------------------
    name, default_integrator : its key in `METHODS`; a key of `integrators.INTEGRATORS`
    options : dict of `mechsim.options.Option`: the `simulate` keywords it takes (checked
        before any work, set as attributes)
    needs_freedom : bool, it integrates independent coordinates (0 DOF: projection instead)
    resolves_passages : bool, it follows the assembly branch through singular
        configurations (else a run meeting one says it may have left its branch)

    Called by the run
    -----------------
    initial_state(t, q, v) -> y : the state of a consistent (q, v) at the start
    rhs(t, y) -> y' : counting itself in `problem.counters.rhs`; NaN where y admits no
        state (the integrator then rejects the step and shrinks it)
    integrand : the callable the integrator about to start gets (default: `rhs`)
    state(t, y) -> (q, v) : the full coordinates and velocities
    states(ts, Y) -> (Q, V) : the same for the output samples inside a step (rows)
    keeps_branch(t, y) -> bool : the step just taken stayed on its assembly branch
    after_step(t, y, step) -> Correction : after each accepted step (or a bridge's
        crossing) to (t, y): the state to go on from, what it means, the largest next step
    derivative(t, q, v) -> y' : `rhs` at the y of a consistent (q, v), re-expressing a
        multistep history after a restart (NotImplementedError: history not carried over)
    resume(t, q, v, extra=None) -> y : the state of (q, v) in the present layout after a
        bridge (`extra`: what `extension_of(y)` gave before it, carried over)
    extension_of(y), extras(ts, Y, Q, V) : what y carries besides the motion (None:
        nothing), and its `width` numbers at the output samples, which the run keeps
    project_now : None or (t, y) -> projected y or None: projection inside an integrator's
        step where it can (Adams: P E C, project, E)

    Read by the run (the formulation's own state; the run never writes them)
    -------------------------------------------------------------------------
    bridge, bridging : a `PassageBridge` that crosses singular passages in one step (else
        None), and whether the run may use it at the present step
    bridges_passages : whether the run's passages are bridged at all (by a phase of the
        formulation that may not be the present one), else stepped through
    failure : what went wrong last, for the message of a failed run
    switches : list of `Switch`, its changes of formulation
    sign_changes : steps (t_a, t_b) across which its partition's det(Φ_q D) changed sign
    """
    name = ""
    default_integrator = "DOP853"
    options: dict = {}
    needs_freedom = False
    resolves_passages = False
    failure = ""
    bridge = None
    bridging = False
    project_now = None
    extras = None
    width = 0

    @property
    def bridges_passages(self) -> bool:
        return self.bridging

    @classmethod
    def cannot_resolve(cls, problem: NumericProblem, q: np.ndarray, t: float, rtol: float,
                       redundant: int = 0) -> str:
        """Why this method cannot integrate the mechanism at (q, t) to rtol, said before
        any work ("" where it can): `simulate` raises it as a ValueError."""
        return ""

    def derivative(self, t: float, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """y' in the present layout at a consistent full state (q, v): what `rhs` gives at
        the y of that state, without solving for the state first. The manager uses it to
        re-express a multistep integrator's history after a switch or a new partition."""
        raise NotImplementedError

    def resume(self, t: float, q: np.ndarray, v: np.ndarray, extra=None) -> np.ndarray:
        """The state y for a consistent (q, v) at t in the present layout (after a bridge;
        `extra`: what `extension_of` gave, carried over by it)."""
        return self.initial_state(t, q, v)

    def extension_of(self, y: np.ndarray):
        """The numbers the state y carries besides the motion, which a bridge carries
        over a passage with it (None: nothing)."""
        return None

    def __init__(self, problem: NumericProblem, rtol: float, atol: float, monitor=None,
                 **options):
        message = unknown_names(options, self.options, f"method {self.name!r}")
        if message:
            raise ValueError(message)
        self.problem = problem
        self.rtol, self.atol = rtol, atol
        self.tol = Tolerances(rtol, atol)       # and every tolerance derived from them
        self.monitor = monitor
        for key, value in check_all(self.options, options, f"method {self.name!r}").items():
            setattr(self, key, value)
        self.switches: list = []
        # Steps (t_a, t_b) across which the partition's det(Φ_q D) changed sign: the
        # motion crossed a singular configuration or left its assembly branch there.
        self.sign_changes: list[tuple[float, float]] = []

    def initial_state(self, t: float, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def rhs(self, t: float, y: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def compiled_rate(self):
        """The rate as one compiled call at every state of the next step
        (`mechsim.integrators.compiled.CompiledRate`), for `CompiledDOP853` to take the
        step in the engine; None (the default) where the Python rate serves."""
        return None

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

    def positions(self, ts: np.ndarray, Y: np.ndarray) -> np.ndarray:
        """Q with rows q of `state(t, y)` for each time of `ts` and row of Y (what the
        singularity monitor measures inside a step); a formulation whose positions take a
        solve overrides it to solve for all at once."""
        return np.array([self.state(t, y)[0] for t, y in zip(ts, Y)])

    def positions_context(self):
        """How the compiled engine finds the positions of a state on a step's dense output,
        for the singularity monitor's search there (`ConstraintAlgebra.anchored`,
        `passage_minimum`): the address of the partition's compiled context it solves them
        on, 0 where they are the state's first n entries, None where the engine does not
        (the monitor then searches in Python)."""
        return None

    def compiled_step(self, dense_output):
        """(`positions_context()`, `dense_output()`: the step's interpolant) where the
        compiled engine may search the step for a passage, else None."""
        context = self.positions_context()
        return None if context is None else (context, dense_output())

    def after_step(self, t: float, y: np.ndarray, step: float) -> Correction:
        return KEEP

    def keeps_branch(self, t: float, y: np.ndarray) -> bool:
        """Whether the step just taken to (t, y) stayed on the assembly branch, as far as
        the formulation can tell; the manager takes a step that did not again, shorter."""
        return True
