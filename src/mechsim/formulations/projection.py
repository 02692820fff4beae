"""Blajer's projection method (seed 001, eqs. 7–13), in the mass metric.

With J̃ = Φ_q M^{-1/2} = U Σ Vᵀ, the right inverse I_R = M^{-1/2} J̃⁺ and the null-space
projector P_T = I − J̃⁺J̃ give the constrained accelerations with the constraint forces
eliminated:

    q̈ = M^{-1/2} [ J̃⁺ γ + P_T M^{-1/2} Q ]

(the mass-orthogonal complement makes Blajer's M₁₁ = P_Tᵀ M P_T the identity on the null
space, so eq. 10 needs no further solve). The projector is rebuilt at every evaluation, so
the null space is tracked every step: where every singular value of J̃ is clear of the
truncation cut, J̃⁺ = J̃ᵀ(J̃J̃ᵀ)⁻¹ exactly, and a Cholesky factor of J̃J̃ᵀ (banded for long
chains) gives the same q̈ as the SVD at a fraction of its cost; nearer the cut the SVD
decides. In the accelerations, singular values below
`rcond · σ_max` are dropped (`regularization="truncate"`; "damp" uses σ/(σ² + μ²) instead):
inside that narrow band the nearly-lost constraint direction is held by the position and
velocity projections, which use the exact pseudo-inverse, instead of by J̃⁺γ, whose
1/σ_min would amplify any inconsistency of the state.

Inside the band, where the motion crosses the singular configuration, the components of
q̈ along the lost directions (0/0 on the configuration) are interpolated from the exact
accelerations at consistent states just outside the band on either side (`_across`), for
all small singular values together (a passage of the double four-bar loses two at once).
Positions are corrected by Newton on [Φ_q; P_Tᵀ] Δq = [−Φ; 0], the minimum-norm (row-space)
correction −I_R Φ, whenever ‖Φ‖ exceeds `projection_tol`.

`factorization="svd"` is the seed's own method: the SVD at every evaluation and projection,
also clear of the band; the same steps and motion at a higher cost. The measurements behind
these choices are in docs/design-notes.md.
"""

from __future__ import annotations

import numpy as np

from ..linalg import dense, sparse
from ..integrators.compiled import CompiledRate
from ..linalg.newton import newton
from .bridge import PassageBridge
from ..options import Option
from ..tolerances import Tolerances
from .base import Correction
from .full import FullCoordinates

# Singular values below this multiple of the truncation cut join the crossing cluster.
_CLUSTER = 10.0
# Larger clusters are left truncated: a long chain loses many directions over a stretch of
# its passage, each crossing the band slowly, and interpolating them all is no smoother than
# truncating them and costs several times the evaluations (docs/design-notes.md).
_MAX_CLUSTER = 4
# The smallest σ_min/σ_max of J̃ that unequal masses may give (`cannot_resolve`).
RESOLUTION = 1e-7
# The default truncation of J̃'s singular values in the accelerations (`rcond`).
RCOND = 1e-4


def truncation_cut(rcond, monitor, algebra) -> float:
    """`Projection.cut` for the truncation `rcond`, the run's `monitor` (or None) and the
    problem's `algebra`."""
    peak = monitor.peak if monitor is not None and monitor.peak > 0.0 else 1.0
    return rcond * min(1.0, max(peak, 1e-12) / algebra.cut_reference)


class Projection(FullCoordinates):
    name = "projection"
    resolves_passages = True
    default_integrator = "DOP853"
    options = {**FullCoordinates.options, "rcond": Option.positive(RCOND, high=0.5),
               "exact_projection": Option.flag(True),
               "regularization": Option.choice("truncate", ("truncate", "damp")),
               "bridge_passages": Option.flag(True),
               "factorization": Option.choice("auto", ("auto", "svd"))}

    def __init__(self, problem, rtol, atol, **options):
        if options.get("projection_tol") is None:
            # (The integrators keep ‖Φ‖ that small on their own most of the time, and they
            # take the projected state in place, without a restart.)
            options["projection_tol"] = Tolerances(rtol, atol).tight_manifold
        super().__init__(problem, rtol, atol, **options)
        self._redundant = 0          # singular values found to stay at zero (redundancy)
        self.engine = self._compiled_engine()
        self.compiled = self._cholesky
        # The bound on LAPACK's estimate of 1/cond₁ of J̃J̃ᵀ above which the Cholesky
        # factor stands in for the SVD (see `_clear_solver`).
        # Set after an accepted step far from any passage: until the next one, the
        # integrator's evaluations skip the condition estimate (see `_far_from_band`).
        self._far = False
        if self.regularization == "truncate" and self.bridge_passages:
            self.bridge = PassageBridge(problem, lambda t, q, v: self.accelerations(t, q, v, False),
                                        lambda: self.cut, rtol, atol, compiled=self._cholesky,
                                        rate=lambda: self.compiled_rate(far=False))
            self.bridging = True

    @classmethod
    def cannot_resolve(cls, problem, q, t, rtol, redundant=0) -> str:
        """The mass metric's limit: q̈ comes from J̃ = Φ_q M^{-1/2}, so its round-off is
        about ε σ_max/σ_min of J̃ relative. Where very unequal masses (not the
        configuration: Φ_q's own σ_min/σ_max is 100 times larger) make that ratio smaller
        than `RESOLUTION` or than ε/rtol at the start, the steps collapse (a 1e16 kg body
        of unit inertia on a pin: ratio 2e-8, 3000 steps for 0.2 s) or the error exceeds
        rtol many times (1e14 kg at rtol 1e-10: 95 rtol). Said up front instead; the
        partitioned methods (and the hybrid) solve the reduced equations, whose
        conditioning is the partition's."""
        if not problem.m or problem.m - redundant <= 0:
            return ""
        J = sparse.dense(problem.phi_q(q, t))
        scaled = problem.mass_factor(q).cols(J)
        k = problem.m - redundant - 1
        s_scaled = np.linalg.svd(sparse.dense(scaled), compute_uv=False)
        ratio = s_scaled[k] / s_scaled[0] if s_scaled[0] > 0.0 else 0.0
        limit = max(RESOLUTION, np.finfo(float).eps / rtol)
        if not ratio < limit:                 # (Φ_q's own ratio only decides below it)
            return ""
        s_plain = np.linalg.svd(J, compute_uv=False)
        plain = s_plain[k] / s_plain[0] if s_plain[0] > 0.0 else 0.0
        if not plain > 100.0 * ratio:
            return ""
        m = problem.mass_diagonal if problem.constant_mass else np.diag(problem.mass(q))
        names = problem.coordinate_names
        heavy, light = int(np.argmax(m)), int(np.argmin(m))
        return (f"method 'projection' cannot resolve this mechanism at rtol {rtol:g}: its "
                f"masses are too unequal ({names[heavy]} carries {m[heavy]:.3g}, "
                f"{names[light]} {m[light]:.3g}), so σ_min/σ_max of the mass-scaled "
                f"constraint Jacobian is {ratio:.2g} at the start (of the constraints "
                f"alone {plain:.2g}), below {limit:.2g}: its accelerations would be lost to "
                f"round-off. Use method 'hybrid' or 'lu', which solve the reduced equations")

    @property
    def cut(self) -> float:
        """The truncation cut, relative to σ_max: `rcond`, scaled down for a mechanism
        whose σ_min/σ_max has never risen above the algebra's `cut_reference` (1e-3,
        `mechsim.problem.algebra.SCALE_REF`) in the run (its peak, from
        the singularity monitor). There the ratio is small because the masses are very
        unequal (a point mass on a link, a heavy body of small inertia), not because the
        configuration is singular, and a fixed cut would drop one of the mechanism's own
        constraint equations. The cut keeps its place relative to the mechanism's own
        level; for every mechanism whose ratio reaches that reference it is `rcond`.

        A long chain (one with the banded Schur complement) is never well conditioned
        either, because of its length: σ_min/σ_max peaks near 0.6/N for N windows, and
        near a passage it moves as slowly, so a fixed cut leaves a band whose duration
        grows with N, beyond what the passage bridge's Adams step can span at tight
        tolerances (docs/benchmarks.md, long chains). There the
        cut is `rcond` relative to the chain's own level (the banded algebra's reference,
        0.1), which keeps the band as short as a short chain's."""
        return truncation_cut(self.rcond, self.monitor, self.problem.algebra)

    @property
    def _min_rcond(self) -> float:
        """The bound on LAPACK's estimate of 1/cond₁ of J̃J̃ᵀ above which the Cholesky
        factor stands in for the SVD (see `_clear_solver`)."""
        return max(100, self.problem.m) * self.cut ** 2

    @staticmethod
    def _pinv_exact(Jt):
        """(V_r, Σ_r⁻¹ U_rᵀ) of the mass-scaled J̃, truncated only at round-off: for the
        projections, which must restore consistency in every direction the constraints
        still control. The singular values come third."""
        U, sig, Vt = dense.svd(Jt)
        r = int(np.sum(sig > 1e-12 * sig[0])) if sig.size else 0
        return Vt[:r].T, (U[:, :r] / sig[:r]).T, sig

    def _pinv(self, Jt):
        """(V, Σ⁺ Uᵀ) of J̃ = J M^{-1/2} = J L⁻ᵀ: truncated below rcond·σ_max, or damped
        (1/σ becomes σ/(σ² + μ²), μ = rcond·σ_max), which keeps q̈ continuous as σ_min passes
        μ. The singular values come third."""
        U, sig, Vt = dense.svd(Jt)
        self.problem.counters.factorizations += 1
        return self._regularized(U, sig, Vt) + (sig,)

    def _regularized(self, U, sig, Vt):
        if not sig.size:
            return Vt.T, U.T
        if self.regularization == "truncate":
            r = int(np.sum(sig > self.cut * sig[0]))
            return Vt[:r].T, (U[:, :r] / sig[:r]).T
        mu2 = (self.cut * sig[0]) ** 2
        return Vt.T, (U * (sig / (sig**2 + mu2))).T

    def _compiled_engine(self):
        """The compiled accelerations clear of the band (the problem's algebra's engine)
        where Cholesky may stand in for the SVD; else None."""
        return self.problem.algebra.engine if self._cholesky else None

    @property
    def _cholesky(self):
        """May a Cholesky factor of the Schur complement stand in for the SVD where every
        singular value is clear of the cut? Only when truncating (damping changes every
        σ) and with the default `factorization`."""
        return self.regularization == "truncate" and self.factorization == "auto"

    def _clear_solver(self, J, f):
        """r ↦ (J̃J̃ᵀ)⁻¹ r from a Cholesky factor where every singular value of J̃ is clear
        of the truncation cut (the problem's algebra: dense, or banded for a long chain),
        else None: there truncation drops nothing and the exact Schur complement is the
        projection method's q̈. J̃J̃ᵀ's estimated 1/κ₁ ≤ 1/κ₂ must exceed `_min_rcond`
        (truncation drops σ ≤ cut σ_max, λ ≤ cut² λ_max; margin for an estimate that may
        read high by a factor up to m)."""
        if not self._cholesky:
            return None
        return self.problem.algebra.clear_solver(J, f, self.cut, self._min_rcond)

    def _clear_at(self, J, f):
        """Is every singular value of J̃ clear of the truncation cut?"""
        return self._clear_solver(J, f) is not None

    def initial_state(self, t, q, v):
        self._far = False              # until an accepted step says otherwise (a switch)
        if self.bridge is not None and self.monitor is not None and self.monitor.redundant:
            # The bridge's one-step crossing takes the passage's vanishing singular values
            # for the only small ones; beside a redundant constraint's, which stays at zero,
            # its error estimate missed energy errors of 400 rtol on a parallelogram with a
            # fifth bar (stepping through: 0.6 rtol). Such mechanisms step through.
            self.bridging = False
        return super().initial_state(t, q, v)

    def _far_from_band(self, step):
        """Will every evaluation of the next step find J̃ clear of the truncation cut? So
        the monitor says after this step: σ_min/σ_max above its `leave` threshold, not
        predicted to fall under `enter` within three steps like this one, and the
        threshold itself 100 cuts clear. There the Cholesky factor alone serves, without
        LAPACK's condition estimate (a noticeable part of an evaluation's cost); a trial step that reaches the band anyway gets the untruncated q̈,
        which the error estimate judges like any other."""
        mon = self.monitor
        return (mon is not None and self._cholesky
                and mon.last >= mon.leave and mon.leave * mon.peak > 100.0 * self.cut
                and not mon.predicted_within(3.0 * step))

    def rhs(self, t, y):
        """[v; q̈], in one call of the problem's algebra where it takes the evaluation
        (compiled)."""
        prob, n = self.problem, self.n
        prob.counters.rhs += 1
        q, v = y[:n], y[n:]
        Q = prob.forces(t, q, v)
        if self._cholesky:
            out = prob.algebra.derivative(t, y, Q, self.cut, self._min_rcond, self._far)
            if out is not None:
                return out
        return np.concatenate([v, self._accelerations(t, q, v, Q, None, compiled=False)])

    def plain_start(self):
        """(min_rcond, cut, far, the projection's tolerance, the residual under which a
        state is left as it is) where the next steps can be taken in the engine
        (`mechsim.run.segment`): the compiled Cholesky path, projection on, and the
        truncation cut at `rcond` (the monitor's peak at the algebra's `cut_reference` or
        above, so the cut stays through the steps); else None."""
        mon, prob = self.monitor, self.problem
        if self.engine is None or not self._cholesky or not self.projection or not prob.m or \
                mon is None or not mon.peak >= prob.algebra.cut_reference:
            return None
        return (self._min_rcond, self.cut, self._far, 0.01 * self.projection_tol,
                self.projection_tol)

    def accepted_in_engine(self, far) -> None:
        """Steps were accepted in the engine (`mechsim.run.segment`); after the last,
        `_far_from_band` decided `far`."""
        self._far = far

    def compiled_rate(self, far=None):
        """The engine's rate for the next step where it is `rhs`'s first choice at every
        state: the Cholesky path, the engine built and the applied forces constant. `far`:
        as `accelerations` takes it."""
        prob = self.problem
        Q = prob.constant_forces() if self._cholesky else None
        engine = prob.algebra.engine if Q is not None else None
        if engine is None:
            return None
        engine.Q[:] = Q
        far = self._far if far is None else far
        return CompiledRate.of(engine, 0, prob.counters.compiled_rates,
                               -1.0 if far else self._min_rcond, self.cut)

    def accelerations(self, t, q, v, far=None):
        """q̈ at (t, q, v); `far`: skip the condition estimate (default: as the last
        accepted step decided, `_far_from_band`)."""
        return self._accelerations(t, q, v, self.problem.forces(t, q, v), far)

    def _accelerations(self, t, q, v, Q, far, compiled=True):
        """q̈ under the applied forces Q: the exact Schur complement where J̃ is clear of
        the cut (the problem's algebra, compiled unless `compiled` is False: the engine
        declined this state already), else by the SVD."""
        prob = self.problem
        far = self._far if far is None else far
        if self._cholesky and compiled:
            out = prob.algebra.compiled_accelerations(t, q, v, Q, self.cut, self._min_rcond,
                                                      far)
            if out is not None:
                return out
        J, gamma = prob.solver_dynamics_terms(q, v, t)
        m = J.shape[0]
        if m and self._cholesky:
            out = prob.algebra.clear_accelerations(J, Q, gamma, q, self.cut,
                                                   self._min_rcond, far)
            if out is not None:
                return out
        J = sparse.dense(J)
        f = prob.mass_factor(q)
        x = f.left(Q)                                      # L⁻¹ Q
        if m:
            Jt = f.cols(J)
            U, sig, Vt = dense.svd(Jt)
            prob.counters.factorizations += 1
            V, Ui = self._regularized(U, sig, Vt)
            x = x - V @ (V.T @ x) + V @ (Ui @ gamma)
            r = V.shape[1]
            # Singular values at round-off are redundant constraints, unless they move (a
            # state exactly on the singular configuration): `_across` tells them apart, and
            # remembers how many are redundant so that a redundant mechanism pays once.
            if self.regularization == "truncate" and r < min(Jt.shape) and (
                    sig[r] > 1e-12 * sig[0] or np.sum(sig <= 1e-12 * sig[0]) > self._redundant):
                x = self._across(t, q, v, Jt, f, x, r, U, sig, Vt)
        return f.right(x)

    def _across(self, t, q, v, Jt, f, x, r, U, sig, Vt):
        """Inside the truncation band the lost directions (right singular vectors W of the
        dropped σ) get no constraint acceleration, a jump of a few percent in q̈ that
        collapses the step size where a step lands on the singular configuration. Where σ
        moves through the band, the components along W are interpolated instead: the exact
        constrained accelerations at consistent states a time δ before and after (out of
        the band, so well conditioned), averaged, which is the linear interpolation to t
        with O(δ²) error. The small singular values are treated as one cluster with
        W spanning all below `_CLUSTER` × the cut: the double four-bar loses two at once,
        and the components of both must stay continuous while either is dropped. The
        cluster's subspace is well defined even where its singular vectors are not (on the
        singular configuration itself), so the SVD of this evaluation serves."""
        prob = self.problem
        crossing = crossing_cluster(prob, t, q, v, Jt, f, r, U, sig, Vt, self.cut)
        if crossing is None:
            return x
        W, delta, self._redundant = crossing
        if W is None:
            return x
        # The states δ before and after follow q̈ itself, whose W-components are what is
        # sought (the accelerations there are sensitive to the velocity this close to the
        # singularity): two passes of the fixed point. The first changes q̈ by ~1 (the
        # truncation's error), the second by ~1e-5, a third by the noise of the end values
        # (~1e-6 on the double four-bar). The end states must be consistent to round-off
        # (an inconsistency is amplified by 1/σ² there): the Taylor positions are projected
        # to 1e-13 (one Newton step cost 20 % more evaluations on the double four-bar at
        # rtol 1e-8), and so are the velocities. Out of the band the
        # Schur complement (condition ~ 1/σ² ≤ 1e8) is as accurate as the SVD for the end
        # values, at a fraction of the cost.
        for _ in range(2):
            a = f.right(x)
            mean = np.zeros_like(a)
            for h in (delta, -delta):
                mean += 0.5 * end_state(prob, t, q, v, a, h)[3]
            x = x + W @ (W.T @ (f.unright(mean) - x))
        return x

    def after_step(self, t, y, step):
        """Project an accepted state back onto the constraints (FullCoordinates) with one
        factor of Φ_q M⁻¹ Φ_qᵀ for positions and velocities (`NumericProblem.project_state`)
        where J̃ is clear of the band: the dense Cholesky factor, or the banded one of a
        long chain. On the double four-bar one Jacobian and one factorisation per
        projection instead of four of each."""
        self._far = self._far_from_band(step)
        return Correction(self.project_now(t, y))

    def project_now(self, t, y):
        prob, n = self.problem, self.n
        if not self.projection or not prob.m:
            return super().project_now(t, y)
        q, v = y[:n], y[n:]
        if self._cholesky:
            done = prob.algebra.project_state(t, q, v, 0.01 * self.projection_tol,
                                              self._min_rcond, self.projection_tol)
            if done is False:
                return None
            if done is not None:
                return np.concatenate(done)
        phi, J = prob.solver_position_terms(q, t)
        if max(abs(phi).tolist()) <= self.projection_tol:
            return None
        solve = self._clear_solver(J, prob.mass_factor(q))
        done = None if solve is None else prob.project_state(
            q, v, t, 0.01 * self.projection_tol, solve=solve)
        return super().project_now(t, y) if done is None else np.concatenate(done)

    def project_positions(self, q, t):
        prob = self.problem
        q = np.array(q, float)
        tol = 0.01 * self.projection_tol
        f = prob.mass_factor(q)
        if self._clear_at(prob.solver_phi_q(q, t), f):
            return prob.project_positions(q, t, tol=tol)      # clear of the band: exact Schur
        pinv = self._pinv_exact if self.exact_projection else self._pinv

        def correct(q, phi, J, slow):
            V, Ui, _ = pinv(f.cols(J))
            prob.counters.projections += 1
            return q - f.right(V @ (Ui @ phi))

        done = newton(q, lambda q: prob.position_terms(q, t), correct, tol, 20, stall=True)
        return done.x, done.iterations, done.residual

    def project_velocities(self, q, v, t):
        prob = self.problem
        J = prob.solver_phi_q(q, t)
        f = prob.mass_factor(q)
        if self._clear_at(J, f):
            return prob.project_velocities(q, v, t)
        J = sparse.dense(J)
        Jt = f.cols(J)
        V, Ui, _ = self._pinv_exact(Jt) if self.exact_projection else self._pinv(Jt)
        return v - f.right(V @ (Ui @ (J @ v + prob.phi_t(q, t))))


def end_state(prob, t, q, v, a, h):
    """(t + h, q, v, q̈) at the consistent state a time h from (t, q, v) with
    accelerations a (`Projection._across`): the Taylor positions projected to 1e-13, the
    velocities projected, q̈ by the exact Schur complement (out of the band)."""
    ts = t + h
    qs, _, _ = prob.project_positions(q + h * v + 0.5 * h * h * a, ts, tol=1e-13)
    vs = prob.project_velocities(qs, v + h * a, ts)
    Js, gs = prob.solver_dynamics_terms(qs, vs, ts)
    return ts, qs, vs, prob.accelerations(Js, prob.forces(ts, qs, vs), gs, qs)[0]


def crossing_cluster(prob, t, q, v, Jt, f, r, U, sig, Vt, cut):
    """The singular directions crossing the truncation band at (t, q, v) (`Projection`'s
    `_across`): (W, δ, redundant) with W the right singular vectors of the mass-scaled
    Jacobian Jt = U diag(sig) Vt of its cluster of small, moving singular values (None
    where there is none, or more than `_MAX_CLUSTER`), δ the time that takes each of them
    at least 2 cuts out of the band, and the number of singular values at round-off that
    do not move (redundant constraints); None where the mechanism stands still. `r`:
    the singular values kept by the truncation at `cut` (relative to the largest); `f`
    the mass factor."""
    speed = float(np.max(np.abs(v)))
    if speed == 0.0:
        return None
    # dσ_k/dt = u_kᵀ (dJ̃/dt) w_k, with dJ̃/dt from one Φ_q a hair along the motion.
    eps = 1e-7 / speed
    J1 = f.cols(prob.phi_q(q + eps * v, t + eps))
    dJ = (J1 - Jt) / eps
    if sig[-1] <= 1e-12 * sig[0]:
        # On the singular configuration itself the SVD's choice of vectors within the
        # null space is arbitrary (it may mix in the motion's own direction); a hair
        # along the motion they are the directions being lost.
        U, sig, Vt = dense.svd(J1)
    cut = cut * sig[0]
    zero = 1e-12 * sig[0]
    # δ takes every σ of the cluster at least 2 cuts out of the band. A σ that does not
    # move (a redundant constraint's stays at zero) is no crossing and stays dropped,
    # as does one too slow to leave the band within a short distance.
    delta, cluster, redundant = 0.0, [], 0
    for k in range(min(Jt.shape)):
        if k < r and sig[k] > _CLUSTER * cut:
            continue
        slope = abs(U[:, k] @ dJ @ Vt[k])
        if sig[k] <= zero and slope <= 1e-6 * sig[0]:
            redundant += 1
            continue
        step = 3.0 * cut / slope if slope > 0.0 else np.inf
        if step * speed > 1e-2:
            continue
        cluster.append(k)
        delta = max(delta, step)
    if not cluster or len(cluster) > _MAX_CLUSTER:
        return None, delta, redundant
    return Vt[cluster].T, delta, redundant
