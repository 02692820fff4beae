"""Formulations in all coordinates: the state is y = [q; v] and q̈ comes from the whole
constrained system. After a step whose ‖Φ‖∞ exceeds `projection_tol`, positions and
velocities are projected back onto the constraint manifold (mass metric); the run puts the
projected state into the running integrator in place where its adapter allows that
(`mechsim.integrators.adapters`) and restarts the integrator otherwise. Subclasses supply
`accelerations(t, q, v)`.
"""

from __future__ import annotations

import numpy as np

from ..options import Option
from ..linalg.newton import newton_stalled
from ..linalg.sparse import transpose_times
from ..problem.numeric import velocities_hold
from .base import Correction, Formulation
from .basis import ConstraintSolveError

# An output sample is projected onto the constraints where it leaves them by more than this
# (relative to its largest coordinate, at least 1).
ROUND_OFF = 1e-13
# Stacked Newton steps that settle a step's output samples onto the constraints at most.
SETTLE_STEPS = 4


class FullCoordinates(Formulation):
    options = {"projection": Option.flag(True),
               "projection_tol": Option.positive(None, optional=True)}
    # Whether the problem's algebra may settle samples compiled (`settle_samples`).
    compiled = False

    def __init__(self, problem, rtol, atol, **options):
        super().__init__(problem, rtol, atol, **options)
        if self.projection_tol is None:
            self.projection_tol = self.tol.manifold
        self.n = problem.n

    def initial_state(self, t, q, v):
        return np.concatenate([q, v])

    def state(self, t, y):
        return y[:self.n], y[self.n:]

    def states(self, ts, Y):
        """The output samples inside a step, put onto the constraints (`settle_samples`):
        the dense output between two projected steps drifts off them (2.6e-8 at samples
        where the steps held 3e-13)."""
        Q, V = np.array(Y[:, :self.n]), np.array(Y[:, self.n:])
        if self.projection:
            settle_samples(self.problem, ts, Q, V, 0.01 * self.projection_tol,
                           self.compiled)
        return Q, V

    def positions(self, ts, Y):
        return np.array(Y[:, :self.n])

    def positions_context(self):
        return 0

    def accelerations(self, t, q, v) -> np.ndarray:
        raise NotImplementedError

    def derivative(self, t, q, v):
        return np.concatenate([v, self.accelerations(t, q, v)])

    def rhs(self, t, y):
        self.problem.counters.rhs += 1
        return self.derivative(t, y[:self.n], y[self.n:])

    def after_step(self, t, y, step):
        return Correction(self.project_now(t, y))

    def project_now(self, t, y):
        """The state projected onto the constraints (mass metric) where ‖Φ‖∞ exceeds
        `projection_tol`, else None. The manager also hands this to an integrator that can
        project inside its step, before its last evaluation (Adams: P E C, project, E),
        so that the projection costs no extra evaluation of the right-hand side."""
        if not self.projection:
            return None
        prob, n = self.problem, self.n
        q, v = y[:n], y[n:]
        phi = prob.phi(q, t)
        if phi.size == 0 or np.max(np.abs(phi)) <= self.projection_tol:
            return None
        q, _, err = self.project_positions(q, t)
        if not err <= max(1e-9, 1e3 * self.projection_tol):   # slow near a singularity is fine
            self.failure = (f"the constraints cannot be satisfied at t = {t:.9g}: projection "
                            f"leaves residual {prob.worst_constraint(prob.phi(q, t))}")
            raise ConstraintSolveError(self.failure)
        return np.concatenate([q, self.project_velocities(q, v, t)])

    def project_positions(self, q, t):
        return self.problem.project_positions(q, t, tol=0.01 * self.projection_tol)

    def project_velocities(self, q, v, t):
        return self.problem.project_velocities(q, v, t)


def settle_samples(problem, ts, Q, V, accept, compiled=False) -> None:
    """Project each output sample (rows of Q, V at times ts, in place) onto the constraints,
    positions then velocities in the mass metric, where it leaves them by more than
    round-off (`ROUND_OFF` of its largest coordinate). Rigid mechanisms take Newton steps
    for all such samples at once (stacked Schur complements, `_settle_together`) and each
    velocity its projection at the new positions; a sample that does not land, every sample of a long chain (whose banded
    complement costs O(n) where a stacked dense one costs O(n³)) and every sample of a
    flexible mechanism, is
    projected on its own (`NumericProblem.project_state`, the full projections where its
    chord fails). A sample at a singular configuration, where the projection ends above
    `accept`, is kept as it was. `compiled`: every sample is first projected by the
    problem's algebra in one call where it is compiled (`project_states`)."""
    if not problem.m or not len(ts):
        return
    if compiled:
        floors = ROUND_OFF * np.maximum(1.0, np.max(np.abs(Q), axis=1))
        Qc, Vc = np.ascontiguousarray(Q), np.ascontiguousarray(V)
        status = problem.algebra.project_states(ts, Qc, Vc, floors)
        compiled = status is not None
    if compiled:
        Q[:], V[:] = Qc, Vc
        left = np.flatnonzero(status == 1)
        if not left.size:
            return
        sub_Q, sub_V = Q[left], V[left]
        settle_samples(problem, np.asarray(ts)[left], sub_Q, sub_V, accept)
        Q[left], V[left] = sub_Q, sub_V
        return
    floors = ROUND_OFF * np.maximum(1.0, np.max(np.abs(Q), axis=1))
    phis = problem.phi_many(Q, ts)
    off = np.flatnonzero(np.max(np.abs(phis), axis=1) > floors)
    if not off.size:
        return
    if problem.algebra.dense_complement:
        off = _settle_together(problem, ts, Q, V, phis, floors, off)
    elif problem.sparse and problem.mass_model.constant:
        off = _settle_each(problem, ts, Q, V, phis, floors, off)
    for k in off:
        t = ts[k]
        done = problem.project_state(Q[k], V[k], t, tol=floors[k])
        if done is None:          # no factor, or the chord does not converge: the full way
            q, _, err = problem.project_positions(Q[k], t, tol=floors[k])
            if err <= max(floors[k], accept):
                Q[k], V[k] = q, problem.project_velocities(q, V[k], t)
        else:
            Q[k], V[k] = done


def _settle_each(problem, ts, Q, V, phis, floors, off, max_iter=8):
    """`NumericProblem.project_state` for the samples `off` of a long chain, side by side:
    each its own chord (one factor of the banded complement at its own q, serving its
    velocities too) under `newton`'s rules (tol its floor, round-off stalls, `max_iter`),
    but Φ and Φ_q of all of them in one call each where the model evaluates many states
    together (the assembled model): a step's samples cost about what one does. Returns
    the samples it did not settle (no factor, no convergence), for their own projections."""
    f = problem.mass_factor(Q[off[0]])
    tk, q, tol = ts[off], Q[off].copy(), floors[off]
    Js = problem.solver_phi_q_many(q, tk)
    solves = [problem.complement_solver(J, f) for J in Js]
    Jt = [f.cols(J) for J in Js]
    landed = np.zeros(len(off), dtype=bool)
    phi, prev = phis[off], np.full(len(off), np.inf)
    active = np.flatnonzero([solve is not None for solve in solves])
    for k in range(max_iter + 1):
        err = np.max(np.abs(phi[active]), axis=1)
        done = (err <= tol[active]) | newton_stalled(err, prev[active], tol[active])
        landed[active[done]] = True
        active, err = active[~done], err[~done]
        # Non-finite residuals, or the iteration limit: left to their own projections.
        going = np.isfinite(err) if k < max_iter else np.zeros(len(active), dtype=bool)
        prev[active[going]] = err[going]
        active = active[going]
        if not active.size:
            break
        for i in active:
            problem.counters.projections += 1
            q[i] -= f.right(transpose_times(Jt[i], solves[i](phi[i])))
        phi[active] = problem.phi_many(q[active], tk[active])
    idx = np.flatnonzero(landed)
    for i, J in zip(idx, problem.solver_phi_q_many(q[idx], tk[idx])):
        V[off[i]] = problem.velocities_by(q[i], V[off[i]], tk[i], solves[i], J)
        Q[off[i]] = q[i]
    return off[~landed]


def _settle_together(problem, ts, Q, V, phis, floors, off):
    """Newton steps (constant diagonal mass), stacked for the samples `off` that have not
    landed within their floor, at most `SETTLE_STEPS` (a sample off by a long step's error,
    1e-4, lands in two or three), then each landed sample's velocity projection, stacked;
    returns the ones it did not bring within their floor."""
    w = problem.inverse_mass_diagonal
    tk = ts[off]
    q_new, phi = Q[off].copy(), phis[off]
    landed = np.zeros(len(off), dtype=bool)
    for _ in range(SETTLE_STEPS):
        todo = np.flatnonzero(~landed)
        J = problem.phi_q_many(q_new[todo], tk[todo])                       # (s, m, n)
        try:
            lam = np.linalg.solve((J * w) @ J.transpose(0, 2, 1), phi[todo][..., None])
        except np.linalg.LinAlgError:
            break
        q_new[todo] -= w * np.einsum("smn,sm->sn", J, lam[..., 0])
        phi[todo] = problem.phi_many(q_new[todo], tk[todo])
        landed[todo] = np.max(np.abs(phi[todo]), axis=1) <= floors[off][todo]
        if landed.all():
            break
    if not np.any(landed):
        return off
    idx, q_new, tk = off[landed], q_new[landed], tk[landed]
    J = problem.phi_q_many(q_new, tk)
    phi_t = np.array([problem.phi_t(q, t) for q, t in zip(q_new, tk)]) \
        if problem.rheonomic_rows else np.zeros((len(idx), problem.m))
    r = np.einsum("smn,sn->sm", J, V[idx]) + phi_t
    try:
        mu = np.linalg.solve((J * w) @ J.transpose(0, 2, 1), r[..., None])[..., 0]
    except np.linalg.LinAlgError:
        return off
    v_new = V[idx] - w * np.einsum("smn,sm->sn", J, mu)
    # A rank-deficient complement (redundant rows) solves to garbage without an error:
    # velocities that do not hold their constraints go on to the sample's own projection.
    held = np.array([velocities_hold(*args) for args in zip(J, v_new, phi_t)], dtype=bool)
    Q[idx[held]], V[idx[held]] = q_new[held], v_new[held]
    return np.sort(np.concatenate([off[~landed], idx[~held]]))
