"""A formulation's motion with its forward sensitivities to the model's Parameters.

`Tangent` wraps any formulation (the hybrid, LU partitioning, the projection method): its
state is the wrapped formulation's, whatever coordinates that holds at the moment (a
partition's independent ones, all of q and v after a switch), followed by the
sensitivities (q_k, v_k) of all coordinates, which keep their meaning through every switch
and new partition. They are integrated with the motion, under the same error control:
q_k' = v_k and v_k' = q̈_k from the differentiated equations of motion
(`mechsim.problem.sensitivity.MotionEquations`), and put back on the constraints' tangent
after a step where they drift from it (or where the motion was corrected).

Through a singular passage the sensitivities follow the branch the motion follows: the
passage bridge (`mechsim.formulations.bridge`) carries them over with the motion in its one
Adams step, all of whose evaluations lie outside the passage's band (`Tangent` is its
extension); where the bridge stands down, the run steps through the band, q̈_k's
components along the directions crossing it interpolated as the projection method's q̈'s
are (`Tangent._across`).
"""

from __future__ import annotations

import numpy as np

from .base import Correction, Formulation
from ..problem.sensitivity import ROUND_OFF
from .projection import RCOND, crossing_cluster, end_state, truncation_cut


# Newton's steps at most refining a passage's instant for its time sensitivity.
PASSAGE_NEWTON = 4


class Tangent(Formulation):
    """`base`'s motion and its sensitivities: the equations `equations` (a
    `MotionEquations`), starting from the sensitivities (Sq0, Sv0) of the state given to
    `initial_state` (put on the tangent there). `extras(ts, Y)` gives the sensitivities
    at output samples, rows of 2 n K numbers (q_k then v_k, each n × K row-major)."""

    project_now = None

    def __init__(self, base: Formulation, equations, Sq0, Sv0):
        self.base, self.eq = base, equations
        self.problem, self.monitor = base.problem, base.monitor
        self.rtol, self.atol, self.tol = base.rtol, base.atol, base.tol
        self.name = base.name
        self.resolves_passages = base.resolves_passages
        self.needs_freedom = base.needs_freedom
        self.width = equations.width
        self.start = (np.asarray(Sq0, float), np.asarray(Sv0, float))
        n = self.problem.n
        self._scale = max(1.0, float(np.max(np.abs(np.concatenate(self.start)), initial=0.0)))
        self._full = 2 * n
        # The base's bridge, carrying the sensitivities over too (the base never reads it).
        self.bridge = None if base.bridge is None else base.bridge.extended(self)

    @property
    def bridging(self):
        return self.base.bridging

    @property
    def bridges_passages(self):
        return self.base.bridges_passages

    # What the run reads, from the formulation integrating the motion.
    @property
    def switches(self):
        return self.base.switches

    @property
    def sign_changes(self):
        return self.base.sign_changes

    @property
    def failure(self):
        return self.base.failure

    @property
    def cut(self) -> float:
        """The truncation of Φ_q's small singular values in q̈_k (the projection method's
        default)."""
        return truncation_cut(RCOND, self.monitor, self.problem.algebra)

    def _split(self, y):
        nb = len(y) - self.width
        return y[:nb], *self.eq.split(y[nb:])

    def _join(self, yb, Sq, Sv):
        return np.concatenate([yb, Sq.ravel(), Sv.ravel()])

    def initial_state(self, t, q, v):
        yb = self.base.initial_state(t, q, v)
        return self._join(yb, *self.eq.project(t, q, v, *self.start))

    def resume(self, t, q, v, extra=None):
        yb = self.base.resume(t, q, v)
        return self._join(yb, *self.eq.project(t, q, v, *self.eq.split(extra)))

    def passage_time(self, t, state_at, within) -> dict:
        """{name: ∂t*/∂name} of the singular passage whose instant was found at t;
        `state_at(t) -> (q, v, x)` (x the sensitivities) over `within` = (t0, t1). The
        instant is first refined where Φ_q's singular value crosses zero (Newton's steps
        on `MotionEquations.passage_time`'s estimate, staying within): a predicted or
        sampled instant off by δ errs in ∂t*/∂k by about δ times its rate."""
        index = self.problem.m - 1 - self.monitor.redundant
        t0, t1 = within
        for _ in range(PASSAGE_NEWTON):
            q, v, x = state_at(t)
            slopes, shift = self.eq.passage_time(t, q, v, self.eq.split(x)[0], index)
            t_next = min(max(t + shift, t0), t1)
            if abs(t_next - t) <= 1e-13 * max(1.0, abs(t)):
                break
            t = t_next
        return dict(zip(self.eq.names, slopes.tolist()))

    def split(self, t, y):
        """(q, v, x) of the state y at t, x the sensitivities."""
        return (*self.state(t, y), self.extension_of(y))

    def extension_of(self, y):
        return y[len(y) - self.width:]

    # --- the passage bridge's extension (`mechsim.formulations.bridge.PassageBridge`) ------
    def rates(self, t, q, v, a, x):
        """(v_k, q̈_k) of the sensitivities x at a consistent state out of the band."""
        Sq, Sv = self.eq.split(x)
        ak = self.eq.accelerations(t, q, v, Sq, Sv, self.cut, a)[0]
        return np.concatenate([Sv.ravel(), ak.ravel()])

    def consistent(self, t, q, v, x):
        """The sensitivities x on the constraints' tangent at the consistent (t, q, v)."""
        Sq, Sv = self.eq.project(t, q, v, *self.eq.split(x))
        return np.concatenate([Sq.ravel(), Sv.ravel()])

    def rhs(self, t, y):
        yb, Sq, Sv = self._split(y)
        d = self.base.integrand(t, yb)
        q, v = self.base.state(t, yb)
        # A formulation of all of (q, v) gives q̈ itself (through a passage: the projection
        # method's, continuous across its band).
        a = d[self.problem.n:] if len(yb) == self._full else None
        ak, a, dropped = self.eq.accelerations(t, q, v, Sq, Sv, self.cut, a)
        if dropped is not None:
            ak = self._across(t, q, v, a, Sq, Sv, ak, dropped)
        return self._join(d, Sv, ak)

    def _across(self, t, q, v, a, Sq, Sv, ak, dropped):
        """q̈_k inside a passage's truncation band: its components along the directions
        crossing the band interpolated from the exact q̈_k at consistent states a time δ
        before and after, as the projection method does for q̈ (`Projection._across`):
        the Taylor states and sensitivities there, put on the constraints and their
        tangent, two passes of the fixed point."""
        prob, eq = self.problem, self.eq
        f = prob.mass_factor(q)
        crossing = crossing_cluster(prob, t, q, v, dropped.Jt, f, dropped.r, dropped.U,
                                    dropped.sig, dropped.Vt, self.cut)
        if crossing is None or crossing[0] is None:
            return ak
        W, delta, _ = crossing
        # The motion's end states depend on q̈ alone, not on the passes over q̈_k.
        ends = [(h, end_state(prob, t, q, v, a, h)) for h in (delta, -delta)]
        x = f.unright(ak)
        for _ in range(2):
            ak = f.right(x)
            mean = np.zeros_like(ak)
            for h, (ts, qs, vs, acc) in ends:
                Sqs, Svs = eq.project(ts, qs, vs, Sq + h * Sv + 0.5 * h * h * ak, Sv + h * ak)
                mean += 0.5 * eq.accelerations(ts, qs, vs, Sqs, Svs, ROUND_OFF, acc)[0]
            x = x + W @ (W.T @ (f.unright(mean) - x))
        return f.right(x)

    def state(self, t, y):
        return self.base.state(t, y[:len(y) - self.width])

    def states(self, ts, Y):
        Y = np.atleast_2d(Y)
        return self.base.states(ts, Y[:, :Y.shape[1] - self.width])

    def positions(self, ts, Y):
        Y = np.atleast_2d(Y)
        return self.base.positions(ts, Y[:, :Y.shape[1] - self.width])

    def keeps_branch(self, t, y):
        return self.base.keeps_branch(t, y[:len(y) - self.width])

    def extras(self, ts, Y, Q, V):
        """The sensitivities at the output samples (ts, rows Y of the state, the samples'
        (Q, V) as recorded), each put on the tangent at its sample's state."""
        Y = np.atleast_2d(Y)
        out = np.empty((len(ts), self.width))
        for k, (t, q, v, y) in enumerate(zip(ts, Q, V, Y)):
            _, Sq, Sv = self._split(y)
            Sq, Sv = self.eq.project(t, q, v, Sq, Sv)
            out[k] = np.concatenate([Sq.ravel(), Sv.ravel()])
        return out

    def after_step(self, t, y, step):
        """The motion's correction, and the sensitivities back on the tangent where the
        motion was corrected or they drifted beyond the manifold tolerance."""
        yb, Sq, Sv = self._split(y)
        c = self.base.after_step(t, yb, step)
        yb_new = yb if c.y is None else c.y
        if c.shifted:
            # (A constant shift of the motion's coordinates: the sensitivities stand.)
            return Correction(self._join(yb_new, Sq, Sv), c.layout_changed, True,
                              c.step_limit)
        q, v = self.base.state(t, yb_new)
        scale = max(self._scale, float(np.max(np.abs(Sq), initial=0.0)),
                    float(np.max(np.abs(Sv), initial=0.0)))
        moved = self.eq.project(t, q, v, Sq, Sv,
                                None if c.y is not None else self.tol.manifold * scale)
        if moved is None:
            return c
        return Correction(self._join(yb_new, *moved), c.layout_changed, False, c.step_limit)
