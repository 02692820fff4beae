"""The constraint algebra of a problem, chosen once when the problem is built: how the
solvers hold Φ_q and factor, decompose and pivot it and its mass-scaled form J̃ = Φ_q L⁻ᵀ.
The formulations and the singularity monitor are written once against this interface;
which algebra serves is decided here, with the tuning that belongs to it, and never again
by an `if` inside an algorithm.

`ConstraintAlgebra` is the contract. A new algebra is a subclass implementing its
methods (see the class docstring); `NumericProblem.algebra` chooses `DenseAlgebra` or, for a
long chain with the banded Schur complement, `BandedAlgebra` (assign it to install
another). The compiled engine (`mechsim.codegen.engine`) computes as the dense algebra
does and serves in its place where it takes the problem (`compiles`).
"""

from __future__ import annotations

import math
from functools import cached_property

import numpy as np
import scipy.linalg as sla

from ..linalg import dense, sparse

# The projection method's truncation cut is `rcond` relative to σ_min/σ_max of J̃'s own
# level: `SCALE_REF` for an ordinary mechanism (a peak below it means very unequal
# masses, not a singular configuration), `CHAIN_REF` for a long chain, whose ratio falls
# as 1/N with N windows and moves as slowly near a passage.
SCALE_REF = 1e-3
CHAIN_REF = 0.1
# Mechanisms with at most this many constraint rows are small: J̃'s SVD costs little (the
# singularity monitor searches inside a step freely, bounds its rate by Weyl's bound, and
# with the dense algebra measures many states together by one stacked SVD). A larger one's
# SVD costs milliseconds: there the rates seen bound the search.
SMALL_ROWS = 60
# The states whose J̃ the passage search keeps for its later questions about the same
# states (`ConstraintAlgebra._scaled_at`: a step's grid and halvings).
NODES = 64


# Φ_q's numerical rank counts its singular values above max(m, n) ε RANK_FACTOR σ_max.
RANK_FACTOR = 1e3


class ConstraintAlgebra:
    """The contract of a constraint algebra: one per problem (`problem`), with

    - ``cut_reference``: float, the level of σ_min/σ_max of J̃ that the projection
      method's truncation cut `rcond` is relative to (`mechsim.formulations.projection`)
    - ``small``: bool, J̃'s SVD is cheap (dense, at most `SMALL_ROWS` constraint rows)
    - ``batched``: bool, J̃ of many states is measured together by one stacked dense SVD
    - ``dense_complement``: bool, Φ_q M⁻¹ Φ_qᵀ is formed dense with a constant diagonal
      mass: many right-hand sides share one factor (a step's samples, friction's responses)
    - ``compiles``: bool, the compiled engine (`mechsim.codegen.engine`) computes as this
      algebra does and may serve its runs
    - ``jacobian(q, t)``: Φ_q in the form the solvers take (dense, or CSR)
    - ``pivots(J)``: the coordinates, the first rank(J) dependent (LU pivoting of Φ_qᵀ)
    - ``rank(J)``: the numerical rank of Φ_q = J (singular values > 1e3 ε max(m, n) σ_max);
      ``choice(J)``: (rank(J), pivots(J)), for a partition's choice
    - ``extremes(J̃, k)``: (σ_k, u_k, v_k, σ_max, u_max, v_max), the k-th largest singular
      value of J̃ (k = m − 1 − redundant rows) with its singular vectors, and the largest;
      σ_max = 0 where J̃ lost that rank (u_k then a left singular vector of the smallest)
    - ``clear_solver(J, f, cut, bound)``: r ↦ (J̃J̃ᵀ)⁻¹ r where every singular value of
      J̃ = f.cols(J) is clear of the truncation cut (relative to σ_max; `bound`: the
      smallest acceptable estimate of 1/cond₁(J̃J̃ᵀ)), else None
    - ``clear_accelerations(J, Q, gamma, q, cut, bound, far)``: q̈ where J̃ is clear of
      the cut, else None (the formulation then decides by the SVD); `far`: the last
      accepted step found the motion far from any singular configuration, so no
      condition estimate is needed
    - ``measure(q, t, v, eps, k, J=None)``: (σ_k, σ_max, σ̇_k, σ̇_max, u_k, J̃,
      ‖dJ̃/dt‖_F, fall) at (q, t), rates along v from J̃ at (q + eps v, t + eps) (0 where
      eps is 0; `J`: J̃ at q if at hand); σ_max = 0 where J̃ lost that rank; fall:
      (dJ̃/dt, `mechsim.linalg.dense.fall_basis`) where small and eps > 0, else None;
      ``forget()``: a run's start (the compiled measure's start from the last SVD dropped)
    - ``chords(times, Q)``, ``singular_extremes(times, Q, k)``: bounds of ‖J̃ᵢ₊₁ − J̃ᵢ‖₂
      (`chord_bound`), (σ_k, σ_max) at each configuration: the passage search's grid
    - ``anchored``, ``passage_minimum``: the search in a step in C (`codegen.search`), or None
    - ``compiled_accelerations(t, q, v, Q, cut, bound, far)``: q̈ at (t, q, v) under the
      applied forces Q by the compiled engine where it takes the state, else None (then
      `clear_accelerations` on the terms the caller evaluates once)
    - ``derivative(t, y, Q, cut, bound, far)``: [v; q̈] at y = [q; v] in one compiled call
      where the engine takes it, else None (then `accelerations`)
    - ``project_state(t, q, v, tol, bound, skip_tol, extra)``:
      `NumericProblem.project_state` compiled: (q, v) on the constraints, False where
      ‖Φ‖∞ ≤ skip_tol already, None where the Python path must decide
    - ``project_states(ts, Q, V, tols)``: `project_state` of many states in one call, Q
      and V (C-contiguous) in place: a status per state (0 projected, 2 within its
      tolerance already, 1 left for the Python path), or None where nothing is compiled
    - ``partition_solver(independent, dependent, newton_tol, max_newton, rheonomic,
      round_off)``: the compiled evaluation of one coordinate partition of the
      partitioned method (`mechsim.codegen.engine.PartitionedEngine`: the dependent
      coordinates' chord Newton, their velocities and the reduced accelerations, of one
      state or of a step's samples) for the dependent coordinates `dependent` of a
      full-row-rank Φ_q, or None where nothing is compiled
    - ``lu_condition(t, q)``: cond₁ of Φ_q D for the dependent set `pivots` picks at
      (q, t), Φ_q of full row rank, inf where that block is singular; None where nothing
      is compiled (the caller factors the block itself)
    - ``multipliers(T, Q, V, F, min_rcond, min_pivot, lam, phi_t=None)``: λ at the states
      (T[i], Q[i], V[i]) under the applied forces F[i] into the rows of `lam`, where the
      Cholesky factor of Φ_q M⁻¹ Φ_qᵀ has a condition estimate above min_rcond (< 0: not
      estimated) and every pivot above min_pivot times its largest diagonal: (N,) bool,
      where it did; None where nothing is compiled (`mechsim.problem.multipliers`).
      `phi_t` (N, m), if given, gets Φ_t at every state (the drivers' powers)
    - ``engine``: the compiled engine (`mechsim.codegen.engine.ProjectionEngine`) that
      serves in the algebra's place where it takes the problem, one per problem; None
    """
    name = ""
    cut_reference = SCALE_REF
    batched = False
    dense_complement = False
    compiles = False

    def __init__(self, problem):
        self.problem = problem
        self._nodes = {}               # J̃ of the passage search's latest states (`_scaled_at`)
        self._plain = {}               # f -> the engine's plain steps (`plain_steps`)
        self._partitions = {}          # the engine's partitions made (`partition_solver`)

    @property
    def small(self) -> bool:
        return self.problem.m <= SMALL_ROWS

    def jacobian(self, q, t):
        return self.problem.solver_phi_q(q, t)

    def pivots(self, J) -> np.ndarray:
        raise NotImplementedError

    def choice(self, J):
        return self.rank(J), self.pivots(J)

    def rank(self, J) -> int:
        if J.shape[0] == 0:
            return 0
        s = dense.svdvals(sparse.dense(J))
        return int(np.sum(s > max(J.shape) * np.finfo(float).eps * RANK_FACTOR * s[0]))

    def extremes(self, Jt, k):
        return _svd_extremes(Jt, k)[0]

    def clear_solver(self, J, f, cut, bound):
        raise NotImplementedError

    def clear_accelerations(self, J, Q, gamma, q, cut, bound, far):
        raise NotImplementedError

    engine = None

    def scaled_jacobian(self, q, t):
        """J̃ = Φ_q L⁻ᵀ, the mass-scaled Jacobian, in the form `jacobian` gives."""
        return self.problem.mass_factor(q).cols(self.jacobian(q, t))

    def measure(self, q, t, v, eps, k, J=None):
        if J is None:
            J = self.scaled_jacobian(q, t)
        basis = None
        if eps and self.small:          # the SVD `extremes` takes, its fall basis beside
            found, basis = _svd_extremes(J, k, fall=True)
        else:
            found = self.extremes(J, k)
        smin, u_min, v_min, smax, u_max, v_max = found
        if not smax > 0.0:
            return 0.0, 0.0, 0.0, 0.0, u_min, J, 0.0, None
        d_min = d_max = rate_norm = 0.0
        fall = None
        if eps:
            dJ = sparse.difference(self.scaled_jacobian(q + eps * v, t + eps), J, 1.0 / eps)
            d_min = u_min @ (dJ @ v_min)
            d_max = u_max @ (dJ @ v_max)
            rate_norm = sparse.frobenius(dJ)
            if basis is not None:
                fall = (sparse.dense(dJ), basis)
        return smin, smax, d_min, d_max, u_min, J, rate_norm, fall

    def plain_steps(self, f, sample_rows, tableaus):
        """Where the compiled engine takes a run's plain LU steps itself: its `PlainSteps`
        (`mechsim.codegen.steps`); None here."""
        return None

    def forget(self):
        """Forget what an earlier run left behind (a run's start, `NumericProblem.start_run`);
        nothing here."""

    def change(self, q, t, Jm):
        """(J̃ at (q, t), ‖J̃ − Jm‖_F): how far J̃ moved since Jm, which bounds how far each
        singular value did (Weyl; the singularity monitor's skip)."""
        J = self.scaled_jacobian(q, t)
        return J, sparse.frobenius(sparse.difference(J, Jm))

    def extreme_bounds(self, J):
        """(a lower bound of σ_min, an upper bound of σ_max) of a small mechanism's J̃
        without an SVD (`mechsim.linalg.dense.extreme_bounds`; the singularity monitor's
        skip), or None where J̃J̃ᵀ is too ill-conditioned for them."""
        return dense.extreme_bounds(J)

    def fall_rates(self, a, b):
        """`mechsim.linalg.dense.fall_rates` of the monitor's ends a and b."""
        return dense.fall_rates(a, b)

    def chords(self, times, Q):
        return chord_bound(np.diff(self._scaled_at(times, Q), axis=0))

    def passage_minimum(self, lu_context, dense, ta, tb, k, xatol):
        return None

    def anchored(self, lu_context, dense, ends, budget, known, k, search):
        return None

    def singular_extremes(self, times, Q, k):
        sig = np.linalg.svd(self._scaled_at(times, Q), compute_uv=False)
        low = sig[:, k] if 0 <= k < sig.shape[1] else np.zeros(len(sig))
        return np.column_stack([low, sig[:, 0]])

    def _scaled_at(self, times, Q) -> np.ndarray:
        """J̃ (dense) at each state (times[i], Q[i]), stacked. The passage search asks for
        the same states' J̃ more than once (its chords, then the SVDs of some of them;
        each halving's chords again at the interval's ends): the latest `NODES` states'
        are kept, by their exact time and coordinates."""
        memo = self._nodes
        Q = [np.asarray(q, dtype=float) for q in Q]
        keys = [(float(tk), q.tobytes()) for tk, q in zip(times, Q)]
        new = list(dict.fromkeys(key for key in keys if key not in memo))
        if len(memo) + len(new) > NODES:
            memo.clear()
            new = list(dict.fromkeys(keys))
        if new:
            at = {key: i for i, key in enumerate(keys)}
            memo.update(zip(new, self._scaled_many([times[at[key]] for key in new],
                                                   [Q[at[key]] for key in new])))
        return np.array([memo[key] for key in keys])

    def _scaled_many(self, times, Q) -> list:
        """J̃ (dense) at each state: one evaluation of Φ_q for all of them where the model
        takes many states at once and the mass is constant (`NumericProblem.phi_q_many`;
        J̃ = Φ_q diag(s), as `scaled_jacobian` scales each), else one by one."""
        prob = self.problem
        if hasattr(prob.model, "phi_q_many") and not prob.sparse and prob.constant_mass:
            factor = prob.mass_factor(Q[0])
            if factor.Linv is None:
                return list(sparse.scale_columns(prob.phi_q_many(np.array(Q), times),
                                                 factor.s))
        return [sparse.dense(self.scaled_jacobian(q, tk)) for tk, q in zip(times, Q)]

    def compiled_accelerations(self, t, q, v, Q, cut, bound, far):
        return None

    def derivative(self, t, y, Q, cut, bound, far):
        return None

    def project_state(self, t, q, v, tol, bound=-1.0, skip_tol=-1.0, extra=0):
        return None

    def project_states(self, ts, Q, V, tols):
        return None

    def partition_solver(self, independent, dependent, newton_tol, max_newton, rheonomic,
                         round_off=None):
        return None

    def lu_condition(self, t, q):
        return None

    def multipliers(self, T, Q, V, F, min_rcond, min_pivot, lam, phi_t=None):
        return None


class DenseAlgebra(ConstraintAlgebra):
    """Φ_q as a dense array: J̃J̃ᵀ by dense Cholesky with LAPACK's condition estimate,
    singular values by the SVD, pivots by LU of Φ_qᵀ. Serves every mechanism."""
    name = "dense"
    compiles = True

    @property
    def batched(self) -> bool:
        return 0 < self.problem.m and self.small

    @property
    def dense_complement(self) -> bool:
        return self.problem.constant_mass

    def choice(self, J):
        """(rank, pivots) of Φ_q = J in one compiled call where the engine serves the
        problem (the same singular values and LU as `rank`'s and `pivots`')."""
        p = self.problem
        if self.engine is not None and J.shape == (p.m, p.n) and sparse.is_dense(J) and \
                p.m and p.m <= p.n:
            got = self.engine.choice(J, np.finfo(float).eps, RANK_FACTOR)
            if got is not None:
                return got
        return super().choice(J)

    def pivots(self, J):
        import warnings
        with warnings.catch_warnings():      # a rank-deficient Φ_q (redundancy) is expected
            warnings.simplefilter("ignore", sla.LinAlgWarning)
            _, piv = sla.lu_factor(sparse.dense(J).T, check_finite=False)
        perm = np.arange(self.problem.n)
        for i, p in enumerate(piv):
            perm[i], perm[p] = perm[p], perm[i]
        return perm

    @cached_property
    def engine(self):
        """The compiled engine where it takes the problem (`compiles`), built on first use
        and shared by the formulations and the monitor of every run of the problem."""
        if not self.compiles:
            return None
        from ..codegen import engine
        lib = engine.for_problem(self.problem)
        return None if lib is None else engine.ProjectionEngine(lib, self.problem)

    def forget(self):
        """The compiled monitor's next SVD from J̃ itself, not from the last one's rotation
        (`ProjectionEngine.forget`), where the engine was made."""
        engine = self.__dict__.get("engine")
        if engine is not None:
            engine.forget()

    def _compiled(self, k):
        """The engine where it may measure: J̃ without redundant rows (k = m − 1) whose
        σ_min is a singular value (m ≤ n)."""
        p = self.problem
        return self.engine if k == p.m - 1 and p.m <= p.n else None

    def measure(self, q, t, v, eps, k, J=None):
        engine = self._compiled(k)
        if engine is not None:
            got = engine.measure(t, q, v, eps, fall=self.small)
            if got is not None:
                return got
        return super().measure(q, t, v, eps, k, J)

    def plain_steps(self, f, sample_rows, tableaus):
        """The engine's plain LU steps (`mechsim.codegen.steps.PlainSteps`) for partitions
        of f independent coordinates with room for `sample_rows` samples a step, or None
        without the engine or where its monitor's measure does not serve (redundant rows:
        m > n). Kept for the problem's later runs, as the engine is (a run loads its whole
        state into it at each call)."""
        if self.engine is None or self.problem.m > self.problem.n:
            return None
        kept = self._plain.get(f)
        if kept is None or len(kept.Y) < sample_rows:
            from ..codegen.steps import PlainSteps
            p = self.problem
            kept = self._plain[f] = PlainSteps(self.engine.lib, p.n, p.m, f, sample_rows,
                                               tableaus, self.engine.steps.search)
        return kept

    def change(self, q, t, Jm):
        if self.engine is not None and Jm.flags.c_contiguous and Jm.dtype == np.float64:
            return self.engine.change(t, q, Jm)
        return super().change(q, t, Jm)

    def extreme_bounds(self, J):
        if self.engine is not None and J.flags.c_contiguous and J.dtype == np.float64:
            lo, hi = self.engine.bounds_of(J).tolist()
            return None if math.isnan(lo) else (lo, hi)
        return super().extreme_bounds(J)

    def fall_rates(self, a, b):
        if self.engine is not None:
            return self.engine.fall_rates(a, b)
        return super().fall_rates(a, b)

    def chords(self, times, Q):
        if self.engine is not None:
            return self.engine.chords(times, Q)
        return super().chords(times, Q)

    def passage_minimum(self, lu_context, dense, ta, tb, k, xatol):
        engine = self._on_step(dense, k)
        return None if engine is None else \
            engine.steps.passage_minimum(lu_context or None, dense, ta, tb, k, xatol)

    def anchored(self, lu_context, dense, ends, budget, known, k, search):
        engine = self._on_step(dense, k)
        return None if engine is None else \
            engine.steps.anchored(lu_context or None, dense, ends, budget, known, k, search)

    def _on_step(self, dense, k):
        """The engine where it may search on the step's dense output `dense` (DOP853's
        interpolant, `mechsim.integrators.compiled.Interpolant`, whose `coefficients` C
        reads, of states of at most 2 n entries), else None."""
        engine = self._compiled(k)
        found = getattr(dense, "coefficients", None)
        if engine is None or found is None or found[3].shape[1] > 2 * self.problem.n:
            return None
        return engine

    def singular_extremes(self, times, Q, k):
        engine = self._compiled(k)
        if engine is not None:
            got = engine.extremes(times, Q, k)
            if got is not None:
                return got
        return super().singular_extremes(times, Q, k)

    def compiled_accelerations(self, t, q, v, Q, cut, bound, far):
        if self.engine is None:
            return None
        out = self.engine.accelerations(t, q, v, Q, -1.0 if far else bound, cut)
        if out is not None:
            self.problem.counters.factorizations += 1
        return out

    def derivative(self, t, y, Q, cut, bound, far):
        if self.engine is None:
            return None
        out = self.engine.rhs(t, y, Q, -1.0 if far else bound, cut)
        if out is not None:
            self.problem.counters.factorizations += 1
        return out

    def project_state(self, t, q, v, tol, bound=-1.0, skip_tol=-1.0, extra=0):
        if self.engine is None:
            return None
        return self.engine.project_state(t, q, v, tol, bound, skip_tol=skip_tol,
                                         extra=extra)

    def project_states(self, ts, Q, V, tols):
        if self.engine is None:
            return None
        return self.engine.project_states(ts, Q, V, tols)

    def partition_solver(self, independent, dependent, newton_tol, max_newton, rheonomic,
                         round_off=None):
        if self.engine is None or len(dependent) != self.problem.m:
            return None
        # One per partition and settings, kept for the problem's later runs: a partition
        # that comes back (the hybrid's after each passage) loads its state again
        # (`accept`, `predictor`) and needs no new buffers.
        key = (tuple(int(i) for i in independent), tuple(int(i) for i in dependent),
               float(newton_tol), int(max_newton), bool(rheonomic), round_off)
        kept = self._partitions.get(key)
        if kept is None:
            from ..codegen import engine
            kept = self._partitions[key] = engine.PartitionedEngine(
                self.engine.lib, self.problem, independent, dependent, newton_tol,
                max_newton, rheonomic, round_off)
        kept.ready = False
        return kept

    def lu_condition(self, t, q):
        return None if self.engine is None else self.engine.lu_condition(t, q)

    def multipliers(self, T, Q, V, F, min_rcond, min_pivot, lam, phi_t=None):
        if self.engine is None:
            return None
        return self.engine.multipliers(T, Q, V, F, min_rcond, min_pivot, lam, phi_t)

    def clear_solver(self, J, f, cut, bound):
        Jt = f.cols(sparse.dense(J))
        c = dense.cholesky_conditioned(Jt @ Jt.T, bound) if Jt.shape[0] else None
        return None if c is None else (lambda r: dense.cho_solve(c, r))

    def clear_accelerations(self, J, Q, gamma, q, cut, bound, far):
        prob = self.problem
        f = prob.mass_factor(q)
        Jt = f.cols(sparse.dense(J))
        S = Jt @ Jt.T
        c = dense.cho_factor_or_none(S) if far else dense.cholesky_conditioned(S, bound)
        if c is None:
            return None
        prob.counters.factorizations += 1
        x = f.left(Q)                                      # L⁻¹ Q
        return f.right(x - Jt.T @ dense.cho_solve(c, Jt @ x - gamma))


class BandedAlgebra(DenseAlgebra):
    """A long chain's: Φ_q as CSR of its fixed pattern where the model gives it
    (`mechsim.linalg.sparse`), J̃J̃ᵀ as a band in reverse Cuthill–McKee order
    (`mechsim.linalg.banded`: Cholesky, extreme eigenvalues by inverse iteration and
    Lanczos), pivots by banded LU; each falls back to the dense algebra where the band
    cannot decide (too near singular). O(n) a step."""
    name = "banded"
    cut_reference = CHAIN_REF
    batched = False
    dense_complement = False
    compiles = False
    # Its measurement (inverse iteration and Lanczos on the band, about a millisecond at
    # any length) is not cheap even under `SMALL_ROWS` rows: the singularity monitor bounds
    # its search by the rates seen, as for any long chain (docs/benchmarks.md).
    small = False

    def __init__(self, problem, band):
        super().__init__(problem)
        self.band = band

    def pivots(self, J):
        return self.band.pivoted_coordinates(J)

    def rank(self, J) -> int:
        band = self.band
        c = band.factor(J, scaled=True)
        low = band.smallest(c) if c is not None else None
        if low is not None and low[0] > 1e-12 * band.largest()[0]:
            return self.problem.m          # σ_min > 1e-6 σ_max: full row rank
        return super().rank(J)

    def extremes(self, Jt, k):
        """By the band: σ_min's left vector u by inverse iteration on S = J̃J̃ᵀ (on S +
        δ I, δ at round-off of its largest eigenvalue, where S is too near singular for
        its own Cholesky factor: the iteration's vector is no less accurate, its direction
        set by the gap to the next eigenvalue, not by the factor's condition), σ_max by
        `BandedSchur.largest`. σ_min is √λ_min where λ_min > 1e-12 λ_max, else ‖J̃ᵀu‖
        (squared, a σ_min under 1e-6 σ_max would be lost to round-off; J̃ᵀu keeps it to
        round-off of σ_max): near a long chain's singular configurations too, where a
        dense SVD costs O(m³). Under 1e-6 σ_max the value is that of
        the vector the iteration settles on, at least σ_min: where several singular
        values are that small together (every window of a chain at once) it may be the
        next one of them. The dense SVD where the iteration does not settle, or with
        redundant rows."""
        band = self.band
        if k == self.problem.m - 1:        # no redundant rows (the band sees all of them)
            c = band.factor(Jt, scaled=True)
            near = c is None
            if near:
                c = band.shifted_factor(1e-14 * band.largest_bound())
            low = band.smallest(c) if c is not None else None
            if low is not None:
                lam_min, u_min = low
                lam_max, u_max = band.largest()
                smax = np.sqrt(lam_max)
                v_max = sparse.transpose_times(Jt, u_max) / smax
                if not near and lam_min > 1e-12 * lam_max:
                    smin = np.sqrt(lam_min)
                    return (smin, u_min, sparse.transpose_times(Jt, u_min) / smin, smax,
                            u_max, v_max)
                w = sparse.transpose_times(Jt, u_min)
                smin = float(np.linalg.norm(w))
                # ‖J̃ᵀu‖ ≥ σ_min for every unit u, and here σ_min is under 1e-6 σ_max
                # (S without a Cholesky factor: at round-off of it), so a larger value
                # means the iteration settled on another eigenvector.
                if 0.0 < smin <= 1e-6 * smax:
                    return smin, u_min, w / smin, smax, u_max, v_max
        return super().extremes(Jt, k)

    def _clear_factor(self, J, cut, far=False):
        """The banded Cholesky factor of S = Φ_q M⁻¹ Φ_qᵀ where every singular value of J̃
        is clear of the cut (σ_min² > (2 cut)² times a Gershgorin bound of σ_max²: S less
        that much of the identity has a Cholesky factor too, a certificate at the cost of
        one more banded factorisation; `far`: the monitor found the motion far from the
        band, so S's own factor serves, as the dense path's), else None."""
        band = self.band
        c = band.factor(J)
        if c is None or not far and band.shifted_factor(
                -(2.0 * cut) ** 2 * band.largest_bound()) is None:
            return None
        return c

    def clear_solver(self, J, f, cut, bound):
        c = self._clear_factor(J, cut)
        return None if c is None else (lambda r: self.band.solve(c, r))

    def clear_accelerations(self, J, Q, gamma, q, cut, bound, far):
        c = self._clear_factor(J, cut, far) if J.shape[0] else None
        if c is None:
            return None
        return self.problem.accelerations(J, Q, gamma, factor=c)[0]


def _svd_extremes(Jt, k, fall=False):
    """(`ConstraintAlgebra.extremes` of J̃ by its SVD, and with `fall` its
    `mechsim.linalg.dense.fall_basis` where J̃ has that rank, else None)."""
    U, sig, Vt = dense.svd(sparse.dense(Jt))
    if k >= sig.size or k < 0 or sig[0] <= 0.0:
        return (0.0, U[:, -1], None, 0.0, None, None), None
    found = (sig[k], U[:, k], Vt[k], sig[0], U[:, 0], Vt[0])
    return found, dense.fall_basis(sig, Vt.T, k) if fall else None


def chord_bound(D) -> np.ndarray:
    """Upper bounds of the spectral norms of the matrices D[..., :, :]: the smaller of the
    Frobenius norm and √(‖D‖₁ ‖D‖∞) (as the compiled engine's `chords`)."""
    a = np.abs(D)
    frobenius = np.sqrt(np.sum(a * a, axis=(-2, -1)))
    holder = np.sqrt(np.max(np.sum(a, axis=-2), axis=-1) * np.max(np.sum(a, axis=-1), axis=-1))
    return np.minimum(frobenius, holder)


def choose(problem) -> ConstraintAlgebra:
    """The algebra that serves `problem`: banded where it has the banded Schur complement
    (a long rigid chain), else dense."""
    band = problem.schur
    return DenseAlgebra(problem) if band is None else BandedAlgebra(problem, band)
