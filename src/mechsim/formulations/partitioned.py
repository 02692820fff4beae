"""Generalized coordinate partitioning (Wehage–Haug) and its QR and SVD variants.

The coordinates are split as q = q_ref + B z + D w: B spans the independent directions
(integrated), D the dependent ones (solved for); for "lu" and "qr" they are subsets of q and
are applied by indexing (`CoordinateBasis`), for "svd" they are matrices (`MatrixBasis`). Only z and ż are integrated; then

    w  from  Φ(q_ref + B z + D w, t) = 0        by Newton–Raphson (seed 001, eq. 6)
    ẇ  from  Φ_q D ẇ = −Φ_q B ż − Φ_t
    q̈, λ from the augmented system (eq. 3), and z̈ = Bᵀ q̈.

The bases come from a factorisation of Φ_q at the partition point (the `choose` hook):
  "lu":  LU with pivoting of Φ_qᵀ — the pivot columns of Φ_q are dependent coordinates;
  "qr":  QR with column pivoting of Φ_q (Kim–Vanderploeg's choice of the dependent set);
  "svd": D and B are the row space and null space of Φ_q from its SVD (tangent-space
         coordinates rather than a subset of q).
For "lu" and "qr", B and D are columns of the identity, so z are real coordinates.

Newton is a chord iteration with the factorisation of Φ_q D from the last accepted step,
started from a second-order prediction; it falls back to fresh Jacobians when it stalls. A
new partition is taken (and the integrator restarted) when cond(Φ_q D) has grown `GROWTH`
times beyond its value at the partition (at most to `cond_max`) or Newton needed fresh
Jacobians twice, and the pivoting then picks a different independent set. At a true singular configuration
no partition is well conditioned: Newton may then converge to another branch. That is the
method's known weakness, which "hybrid" removes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla

from ..linalg import dense, sparse
from ..integrators.compiled import CompiledRate
from ..linalg.newton import CHORD_CONTRACTION, newton
from ..options import Option
from .base import KEEP, Correction, Formulation
from .basis import ConstraintSolveError, CoordinateBasis, DenseBlock, MatrixBasis


# A partition is given up when cond(Φ_q D) has grown this many times beyond its value at
# the partition. The dependent coordinates and velocities carry the state's errors (the
# integrator's, the chord Newton's residual) amplified by that condition, and a new
# partition integrates some of them on: at a fixed threshold of 1e4 a double pendulum's
# error stopped following rtol after its re-partition (1.2e-7 at rtol 1e-10, 5.3e-7 at
# 1e-11); re-partitioning at 10 times the starting condition gives 1.5e-10 and 1.1e-11,
# in fewer steps. Relative, because a good partition's own condition grows with the
# mechanism (10 on a slider-crank, 300 on the 40-window chain).
GROWTH = 10.0
# The independent coordinates are measured from a reference state that moves to the present
# one when any of them has gone further than this (a radian of a crank, a metre of a slider).
REFERENCE_SPAN = 1.0
# The dependent coordinates are solved to 1e-2 atol. A fixed floor of 1e-13 there made
# the error of LU, QR and SVD partitioning stop following rtol below 1e-10 (a double
# pendulum at rtol 1e-12: 8e-12 to 9e-11, depending on the CPU's round-off; 2e-12 to
# 4e-12 solved to 1e-15).
ROUND_OFF = 1e-13


@dataclass
class SolvedState:
    """The state `Partitioned.full_state` solved for last: at time t and y (its bytes
    `key`), out = (q, v, Φ_q, n_fresh), and Φ_q D there factored (`block`; None while only
    the compiled engine, whose buffers hold the state, has solved it)."""
    t: float
    key: bytes
    out: tuple
    block: object = None
    compiled: bool = False


class Partitioned(Formulation):
    name = "lu"
    needs_freedom = True
    # Whether its basis follows Φ_q wherever it is chosen (tangent coordinates): a
    # re-partition then always changes the coordinates, where a pivoting keeps its set.
    moving_basis = False
    default_integrator = "DOP853"    # see docs/design-notes.md; "adams" on request
    options = {"cond_max": Option.real(1e4, low=1.0),
               "newton_tol": Option.positive(None, optional=True),
               "max_newton": Option.integer(12, low=1)}

    def __init__(self, problem, rtol, atol, **options):
        super().__init__(problem, rtol, atol, **options)
        if self.newton_tol is None:
            self.newton_tol = self.tol.newton
        # Below ROUND_OFF, ‖Φ‖ may reach the round-off of the coordinates before the
        # tolerance: Newton then stops where it stalls under ROUND_OFF (`mechsim.linalg.newton`).
        # Above it, a chord that contracts slowly has a stale factor, not round-off, and
        # takes a fresh one.
        self.stall = self.newton_tol < ROUND_OFF
        self.n = problem.n
        self._cache: SolvedState | None = None
        self.independent = ()
        self._rheonomic = bool(problem.rheonomic_rows)      # Φ_t ≠ 0 (drivers)
        self.engine = None                                  # see `_compiled_engine`

    # --- the hook ----------------------------------------------------------------------------
    def choose(self, J, rank=None) -> CoordinateBasis:
        """The independent and dependent directions at Φ_q = J (f = n − r and r of them).
        `rank`: Φ_q's rank if the caller knows it (its SVD is dear on long chains)."""
        algebra = self.problem.algebra
        if rank is None:
            r, perm = algebra.choice(J)
        else:
            r, perm = rank, algebra.pivots(J)       # dense LU, or a long chain's banded LU
        return self._coordinate_bases(perm[r:], perm[:r])

    def _coordinate_bases(self, independent, dependent):
        self.independent = tuple(sorted(int(i) for i in independent))
        model = self.problem.model
        pattern = (model.JACOBIAN_ROWS, model.JACOBIAN_COLS) \
            if hasattr(model, "JACOBIAN_ROWS") else None
        schur = self.problem.schur                  # a long chain's constraints as a band
        return CoordinateBasis(independent, dependent, pattern,
                               None if schur is None else schur.perm)

    # --- partitioning --------------------------------------------------------------------------
    def partition(self, t, q, v, basis=None):
        J = self.problem.phi_q(q, t)
        self.basis = bs = basis if basis is not None else self.choose(J)
        self.q_ref = np.array(q, float)
        self.engine = self._compiled_engine(bs)
        self._accept(t, np.zeros(bs.f), bs.Bt(v), np.zeros(bs.r), bs.Dt(v), J, first=True)
        self._cache = None
        self.problem.counters.partitions += 1
        self._repartition_at = self._threshold(self._chord.condition() if self._square else 1.0)
        self._sign = self._chord.sign() if self._square else 0
        self._end_sign = 0        # at the end of the step being taken (`keeps_branch`)
        return np.concatenate([np.zeros(bs.f), bs.Bt(v)])

    def _accept(self, t, z, zd, w, wd, J, first=False, block=None):
        """Remember an accepted state: the chord factor and the predictor's coefficients.
        `block` is Φ_q D at this state, factored, if the caller has it already."""
        prev = None if first else (self.t_last, self.z_last, self.w_last)
        self.t_last, self.z_last = t, z
        self._square = self.basis.r == J.shape[0]
        reduced = None
        if self._square:
            # The chord factor: convergence is judged on ‖Φ‖, so its conditioning affects
            # only the rate.
            self._chord = self.basis.block(J) if block is None else block
            reduced = getattr(self._chord, "reduced", None)
            self.problem.counters.factorizations += 1
        self.w_last = w
        # The prediction (see `_predict`) is w(t, z) = a0 + a1 d + a2 d² + G z, d = t − t_last:
        # the path through the accepted states bent through the one before (O(h³)), corrected
        # to first order for z off that path. Folded into one matrix here, once per step: in
        # the engine where it factored this Φ_q D (the numbers of a step in a segment,
        # `mechsim.run.segment`).
        if self.engine is not None and self._square and reduced is not None:
            self._P = self.engine.predictor(t, z, zd, w, wd, prev, reduced,
                                            self._chord.inverse(), self.q_ref)
            return
        G = -self._chord.chord(self.basis.JB(J)) if self._square else \
            np.zeros((self.basis.r, self.basis.f))
        cw, cz = np.zeros_like(w), np.zeros_like(z)
        if prev is not None and prev[0] != t:
            t0, z0, w0 = prev
            e = t0 - t
            cw = (w0 - w - wd * e) / e**2
            cz = (z0 - z - zd * e) / e**2
        # [a0 a1 a2 G]: the prediction is one product with [1, d, d², z].
        self._P = np.column_stack([w - G @ z, wd - G @ zd, cw - G @ cz, G])
        if self.engine is not None:      # a dense Φ_q D: `_chord` is a `DenseBlock`
            self.engine.accept(t, self.q_ref, self._P,
                               self._chord.inverse() if self._square else None, z, w)

    def plain_start(self):
        """(sign of det Φ_q D, the condition at which the partition is given up, `cond_max`,
        `GROWTH`) where its next steps can be taken in the engine (`mechsim.run.segment`: a
        compiled, square, dense Φ_q D on a signed branch, chosen by LU's pivoting); else
        None."""
        engine = self.engine
        if engine is None or not engine.ready or not self._square or not self._sign or \
                type(self) is not Partitioned:
            return None
        return self._sign, self._repartition_at, self.cond_max, GROWTH

    def accepted_in_engine(self, J, inverse, reduced, sign, condition,
                           repartition_at) -> None:
        """Steps were accepted in the engine (`mechsim.run.segment`), the last at Φ_q = J
        with Φ_q D's inverse, A⁻¹ Φ_q B `reduced`, its sign and condition there, the
        partition given up at `repartition_at` from then on: take the partition's state
        from the engine's buffers, where its predictor left it."""
        self._repartition_at = repartition_at
        engine = self.engine
        self.q_ref = engine.q_ref.copy()
        self.t_last, self.z_last, self.w_last = engine.ctx.t_last, engine.last_z.copy(), \
            engine.last_w.copy()
        self._P = engine.P.copy()
        self._chord = DenseBlock(self.basis.JD(J), inverse, sign, condition, reduced)
        self._sign = self._end_sign = sign
        self._cache = None

    def _compiled_engine(self, basis):
        """The compiled evaluation of this partition (the problem's algebra's
        `partition_solver`) where it applies: a subset of coordinates with a square, dense
        Φ_q D (no redundant constraints, no long chain); None elsewhere."""
        if type(basis) is not CoordinateBasis or basis.sparse:
            return None
        return self.problem.algebra.partition_solver(
            basis.ind, basis.dep, self.newton_tol, self.max_newton, self._rheonomic,
            ROUND_OFF if self.stall else None)

    def initial_state(self, t, q, v):
        return self.partition(t, q, v)

    # --- state reconstruction ------------------------------------------------------------------
    def _predict(self, t, z):
        """Dependent coordinates for (t, z): the path through the last accepted states
        extrapolated in time (tangent at t_last bent through the state before it), then
        corrected to first order for how far z lies off that path (∂w/∂z = −Φ_u⁻¹ Φ_q B).
        Integrator stages lie O(h²) off the smooth path, so the correction matters."""
        d = t - self.t_last
        return self._P @ np.array([1.0, d, d * d] + z.tolist())

    def _positions(self, z, t):
        """Chord Newton on Φ(q_ref + B z + D w, t) = 0 with the factorisation of Φ_q D from
        the last accepted step; a fresh Jacobian only if the chord stalls. If Newton fails
        from the prediction (a long jump, e.g. dense output of a fully driven mechanism
        whose empty state lets the integrator stride to the end), follow the path from the
        last accepted state in sub-steps instead."""
        try:
            return self._newton(z, t, self._predict(t, z))
        except ConstraintSolveError:
            return self._follow(z, t)

    def _follow(self, z, t, first=4):
        """Positions for (z, t) by Newton along the straight path from the last accepted
        state in `first`, then 4 and 16 times as many pieces."""
        for pieces in (first, 4 * first, 16 * first):
            try:
                w = self.w_last
                for k in range(1, pieces + 1):
                    a = k / pieces
                    zk = self.z_last + a * (z - self.z_last)
                    q, n_fresh = self._newton(zk, self.t_last + a * (t - self.t_last), w,
                                              fresh=True)
                    w = self.basis.Dt(q - self.q_ref)
                return q, n_fresh
            except ConstraintSolveError:
                continue
        raise ConstraintSolveError(self.failure)

    def _newton(self, z, t, w, fresh=False):
        """(q, n_fresh) on Φ(q_ref + B z + D w, t) = 0 from the guess w: the chord with the
        factor of Φ_q D from the last accepted step, fresh Jacobians from the iteration where
        the chord contracts too slowly (`mechsim.linalg.newton`) or where `fresh`; n_fresh counts
        those. ConstraintSolveError where Newton fails."""
        prob, bs = self.problem, self.basis
        fresh = [fresh or not self._square, 0]

        def residual(w):
            q = bs.combine(self.q_ref, z, w)
            return prob.phi(q, t), q

        def correct(w, phi, q, slow):
            if slow:
                fresh[0] = True
            if fresh[0]:
                fresh[1] += 1
                return w - bs.block(prob.solver_phi_q(q, t)).solve(phi)
            return w - self._chord.chord(phi)

        done = newton(w, residual, correct, self.newton_tol, self.max_newton,
                      stall=self.stall, round_off=ROUND_OFF,
                      contraction=CHORD_CONTRACTION)
        if done.converged:
            return done.aux, fresh[1]
        where = "diverged: the coordinates left the range of the constraint functions" \
            if done.aux is None else f"residual {prob.worst_constraint(prob.phi(done.aux, t))}"
        self.failure = (f"Newton on the dependent coordinates did not converge at t = {t:.9g} "
                        f"({where})")
        raise ConstraintSolveError(self.failure)

    def full_state(self, t, y):
        """(q, v, Φ_q, n_fresh) of the integrated state y = [z; ż]; `n_fresh` counts the Newton
        iterations that needed a fresh Jacobian because the chord stalled (a sign that Φ_q D
        is changing fast)."""
        c = self._cache
        key = y.tobytes()
        if c is not None and c.t == t and c.key == key:
            return c.out
        engine = self.engine
        if engine is not None and engine.ready:
            out = engine.state(t, y)
            if out is not None:
                self._cache = SolvedState(t, key, out, compiled=True)
                return out
        bs = self.basis
        z, zd = y[:bs.f], y[bs.f:]
        q, n_fresh = self._positions(z, t)
        J = self.problem.solver_phi_q(q, t)
        block = bs.block(J)
        r = -(bs.JB(J) @ zd)
        if self._rheonomic:
            r -= self.problem.phi_t(q, t)
        wd = block.solve(r)
        v = bs.assemble(zd, wd)
        out = (q, v, J, n_fresh)
        self._cache = SolvedState(t, key, out, block)
        return out

    def state(self, t, y):
        q, v, _, _ = self.full_state(t, y)
        return q, v

    def states(self, ts, Y):
        """The output samples of a step (`_solve_samples`), each on the branch of the
        last accepted state: det(Φ_q D) of the same sign (see `after_step`). In a step
        that kept its sign end to end (`keeps_branch`), a sample whose Newton solve,
        started from the step's prediction, landed on the other branch (a long step) is
        solved again by following the path from the last accepted state. Dense blocks
        only; a long chain's samples are not checked."""
        Q, V, signs = self._solve_samples(ts, Y)
        bs = self.basis
        if not self._square or not self._sign or self._end_sign != self._sign or bs.sparse:
            return Q, V           # (a step that crossed a passage: its samples stand)
        if signs is None:
            prob = self.problem
            J = np.array([prob.phi_q(q, t) for q, t in zip(Q, ts)])
            signs = np.linalg.slogdet(bs.JD(J))[0]
        for k in np.flatnonzero((signs != 0) & (signs != self._sign)):
            try:
                Q[k], V[k] = self._followed_state(ts[k], Y[k])
            except (ConstraintSolveError, np.linalg.LinAlgError):
                pass
        return Q, V

    def _followed_state(self, t, y):
        """(q, v) of y at t, the positions found by following the path from the last
        accepted state in small pieces (staying on its branch)."""
        bs, prob = self.basis, self.problem
        z, zd = y[:bs.f], y[bs.f:]
        q = self._follow(z, t, first=16)[0]
        J = prob.phi_q(q, t)
        r = -(bs.JB(J) @ zd)
        if self._rheonomic:
            r -= prob.phi_t(q, t)
        return q, bs.assemble(zd, bs.block(J).solve(r))

    def positions(self, ts, Y):
        """The configurations at the times `ts` inside a step, solved together
        (`_solve_samples`), or one by one where those are not solved together."""
        if len(ts) < 2 or not self._square or self.basis.sparse:
            return super().positions(ts, Y)
        return self._solve_samples(ts, Y, alone=self._alone)[0]

    def positions_context(self):
        engine = self.engine
        if engine is None or not engine.ready or self.basis.sparse:
            return None
        return engine.context

    def _alone(self, ts, Y):
        return super().positions(ts, Y), None, None

    def _one_by_one(self, ts, Y):
        return *super().states(ts, Y), None

    def _solve_samples(self, ts, Y, alone=None):
        """The output samples of a step, solved for together: the chord Newton on all
        samples at once (one product with the chord factor and one convergence test per
        iteration for all of them), then the velocity solves stacked in one LAPACK call.
        The model's functions run once per sample where they are scalar code (a fused
        model: on a step's dozen samples numpy ufuncs over all of them cost twice as much),
        once for all samples where they are arrays already (`NumericProblem.phi_many`). A
        chord that stalls on any sample, a non-square Φ_q D (redundant constraints), a
        singular or a sparse one (long chains) leaves the samples to `alone(ts, Y)` (by
        default `state`, one by one). Returns (Q, V, signs): signs those of det(Φ_q D) at
        the samples where the solve gave them, else None."""
        prob, bs = self.problem, self.basis
        alone = alone or self._one_by_one
        if len(ts) < 2 or not self._square or bs.sparse:
            return alone(ts, Y)
        if self.engine is not None and self.engine.ready:
            done = self.engine.states(ts, Y)
            if done is not None:
                return done
        ts = np.asarray(ts, float)
        Z, Zd = Y[:, :bs.f].T, Y[:, bs.f:]                  # (f, k), (k, f)
        d = ts - self.t_last
        W = self._P @ np.vstack([np.ones_like(d), d, d * d, Z])
        base = self.q_ref[:, None]

        def residual(W):
            Q = bs.combine(base, Z, W).T                     # (k, n)
            return prob.phi_many(Q, ts).T, Q

        def correct(W, phi, Q, slow):
            return None if slow else W - self._chord.chord(phi)

        done = newton(W, residual, correct, self.newton_tol, self.max_newton,
                      stall=self.stall, round_off=ROUND_OFF,
                      contraction=CHORD_CONTRACTION)
        if not done.converged:
            return alone(ts, Y)
        Q = done.aux
        J = prob.phi_q_many(Q, ts)                                       # (k, m, n)
        r = -(bs.JB(J) @ Zd[:, :, None])[:, :, 0]
        if self._rheonomic:
            r -= np.array([prob.phi_t(q, t) for q, t in zip(Q, ts)])
        A = bs.JD(J)
        try:
            Wd = np.linalg.solve(A, r[:, :, None])[:, :, 0]
        except np.linalg.LinAlgError:
            return alone(ts, Y)
        return Q, bs.assemble(Zd.T, Wd.T).T, np.linalg.slogdet(A)[0]

    def rhs(self, t, y):
        prob = self.problem
        prob.counters.rhs += 1
        engine, Q = self.engine, prob.constant_forces()
        if Q is not None and engine is not None and engine.ready:
            # Forces that do not depend on the state: one compiled call for the whole rate.
            out = engine.rhs(t, y, Q)
            self._cache = None                 # (the engine's buffers hold another state)
            if out is not None:
                prob.counters.factorizations += 1
                return out
        try:
            q, v, J, _ = self.full_state(t, y)
        except ConstraintSolveError:
            # A trial step too far for Newton: NaN makes the integrator reject and shrink it.
            return np.full(y.shape, np.nan)
        if self._cache.compiled:
            out = self.engine.accelerations(t, prob.forces(t, q, v))
            if out is not None:
                prob.counters.factorizations += 1
                return out
        block = self._cache.block
        return np.concatenate([y[self.basis.f:], self.basis.Bt(self._qdd(t, q, v, J, block))])

    def compiled_rate(self):
        """The engine's rate for the next step where it is `rhs`'s first choice: the
        partition's engine ready and the applied forces constant."""
        prob = self.problem
        engine, Q = self.engine, prob.constant_forces()
        if Q is None or engine is None or not engine.ready:
            return None
        engine.Q[:] = Q
        self._cache = None                 # (the engine's buffers will hold other states)
        return CompiledRate.of(engine, 1, prob.counters.compiled_rates)

    def derivative(self, t, q, v):
        qdd = self._qdd(t, q, v, self.problem.phi_q(q, t))
        return np.concatenate([self.basis.Bt(v), self.basis.Bt(qdd)])

    def _qdd(self, t, q, v, J, block=None):
        """q̈ of the consistent state (q, v) from this partition's reduced equations
        (`reduced_accelerations`)."""
        return reduced_accelerations(self.problem, self.basis, t, q, v, J, block)

    def _threshold(self, condition):
        """The condition of Φ_q D at which a partition of `condition` is given up."""
        return min(self.cond_max, GROWTH * max(condition, 1.0))

    def _block_at(self, t, y):
        """(q, v, J, n_fresh, Φ_q D factored) at the integrated state y: in one compiled
        call where the engine serves (`PartitionedEngine.end`)."""
        c, engine = self._cache, self.engine
        if engine is not None and engine.ready and not (
                c is not None and c.t == t and c.block is not None and c.key == y.tobytes()):
            ended = engine.end(t, y)
            if ended is not None:
                q, v, J, n_fresh, inverse, reduced, sign, condition = ended
                block = DenseBlock(self.basis.JD(J), inverse, sign, condition, reduced)
                self._cache = SolvedState(t, y.tobytes(), (q, v, J, n_fresh), block)
                return q, v, J, n_fresh, block
        q, v, J, n_fresh = self.full_state(t, y)
        block = self._cache.block               # Φ_q D at this state, from full_state
        if block is None:                        # solved by the compiled engine
            block = self._cache.block = self.basis.block(J)
            self._cache.compiled = False         # the Python path serves this state now
        return q, v, J, n_fresh, block

    def keeps_branch(self, t, y):
        """Whether det(Φ_q D) at the step's end has the sign it had at the last accepted
        step (see `after_step`): a step across which it changed sign crossed a singular
        configuration or left the assembly branch, and the manager takes it again shorter."""
        self._end_sign = 0
        if not self._square or not self._sign:
            return True
        try:
            self._end_sign = self._block_at(t, y)[4].sign()
        except ConstraintSolveError:
            return True                         # the integrator's own failure handling
        return self._end_sign in (0, self._sign)

    def after_step(self, t, y, step):
        q, v, J, n_fresh, block = self._block_at(t, y)
        bs = self.basis
        # det(Φ_q D) keeps its sign while the motion stays on its branch with this
        # partition: the two assembly branches at the same independent coordinates lie on
        # either side of a fold where it vanishes. A change within one step means the step
        # crossed a singular configuration, or Newton landed on the other branch.
        sign = block.sign() if self._square else 0
        if sign and self._sign and sign != self._sign:
            self.sign_changes.append((t - step, t))
        self._sign = sign or self._sign
        condition = block.condition()
        if n_fresh >= 2 or condition > self._repartition_at:
            before = self.independent
            basis = self.choose(J)
            if self.moving_basis or self.independent != before:
                return Correction(self.partition(t, q, v, basis), layout_changed=True)
            # The pivoting keeps this set: it is as good as any, so keep it until its
            # condition grows as much again.
            self._repartition_at = self._threshold(condition)
        z, zd = y[:bs.f].copy(), y[bs.f:].copy()
        if np.max(np.abs(z), initial=0.0) > REFERENCE_SPAN:
            # Re-reference: the integrator's error control is relative to |z|, and a crank
            # angle that has turned many times loosens it by as much (a slider-crank turned
            # 15 rad: LU's error 4.7e-6 at rtol 1e-8 against 5.9e-6 at 1e-7). The same
            # partition from q_ref + B z, z = 0: the same motion, the state shifted by a
            # constant (`shifted`), which the integrator takes in place.
            self.q_ref = self.q_ref + bs.assemble(z, np.zeros(bs.r))
            self.z_last = self.z_last - z
            self._accept(t, np.zeros(bs.f), zd, bs.Dt(q - self.q_ref), bs.Dt(v), J,
                         block=block)
            self._cache = None
            return Correction(np.concatenate([np.zeros(bs.f), zd]), shifted=True)
        self._accept(t, z, zd, bs.Dt(q - self.q_ref), bs.Dt(v), J, block=block)
        return KEEP


class SSNewmark(Partitioned):
    """Seed 000's average-velocity rule on the mechanism's reduced state-space ODE: LU
    coordinate partitioning, integrated by the implicit trapezoidal rule at the fixed step
    `h` (a keyword of `simulate`), Newton each step. A-stable: for stiff (flexible)
    mechanisms at steps far beyond an explicit method's limit."""
    name = "ss-newmark"
    default_integrator = "trapezoidal"


class QRPartitioned(Partitioned):
    name = "qr"

    def choose(self, J, rank=None):
        r = self.problem.rank(J) if rank is None else rank
        _, P = sla.qr(sparse.dense(J), pivoting=True, mode="r", check_finite=False)
        return self._coordinate_bases(P[r:], P[:r])


class SVDPartitioned(Partitioned):
    name = "svd"
    moving_basis = True

    def choose(self, J, rank=None):
        r = self.problem.rank(J) if rank is None else rank
        _, _, Vt = np.linalg.svd(sparse.dense(J))
        self.independent = ()
        return MatrixBasis(Vt[r:].T, Vt[:r].T)


def reduced_accelerations(problem, basis, t, q, v, J, block=None):
    """q̈ of the consistent state (q, v), Φ_q = J there (`block`: Φ_q D there, factored,
    if the caller has it), from the partition `basis`'s reduced equations

        (Rᵀ M R) z̈ = Rᵀ (Q − M s),    q̈ = R z̈ + s,

    R = B − D A⁻¹ Φ_q B spanning the motions the constraints allow, s = D A⁻¹ γ, A = Φ_q D
    (Wehage and Haug's partitioned equations). Their conditioning is that of the partition
    (A, kept below `cond_max`) and of the mechanism's reduced inertia, not that of the
    constraint forces' Schur complement Φ_q M⁻¹ Φ_qᵀ, which grows with the ratio of the
    masses: a 1 kg point mass (inertia 1e-9 kg·m²) on a 0.5 m link makes it 1e8, a 1e20 kg
    body with unit inertia 1e20. Redundant constraints (A not square) take the
    least-squares Schur path. Also the reduced map of `mechsim.engineering.reduced`."""
    Q, gamma = problem.forces(t, q, v), problem.gamma(q, v, t)
    if basis.r != J.shape[0]:
        return problem.accelerations(J, Q, gamma, q)[0]
    if block is None:
        block = basis.block(J)
    sol = block.solve(np.column_stack([basis.JB(J), gamma]))
    X, s_dep = sol[:, :-1], sol[:, -1]
    R = basis.assemble(np.eye(basis.f), -X)              # n × f
    s = basis.assemble(np.zeros(basis.f), s_dep)
    if problem.constant_mass:
        m = problem.mass_diagonal
        MR, Ms = R * m[:, None], m * s
    else:
        M = problem.mass(q)
        MR, Ms = M @ R, M @ s
    problem.counters.factorizations += 1
    zdd = dense.solve_psd(R.T @ MR, R.T @ (Q - Ms))
    return R @ zdd + s
