"""LinearSystem: M ẍ + C ẋ + K x = f(t) and its state-space form (seed 000, eqs. 1–3)

    q = [ẋ; x],   q̇ = A q + F,   A = [[−M⁻¹C, −M⁻¹K], [I, 0]],   F = [M⁻¹ f; 0]

Methods (fixed step h), each a small class in `LINEAR_METHODS`:
  "ss-newmark"  the state-space Newmark method with a constant average velocity over the step
                (eq. 8): (I − h/2 A) q_{n+1} = q_n + h/2 q̇_n + h/2 F_{n+1}, then q̇_{n+1} by eq. 7;
                I − h/2 A is inverted once per step size;
  "newmark"     the classical average-acceleration Newmark method (β = 1/4, γ = 1/2) on x;
  "rk4"         classical fourth-order Runge–Kutta on the state-space form;
  "exact"       q_{n+1} = e^{Ah} q_n + ∫₀ʰ e^{A(h−s)} F(t_n + s) ds with the forcing
                interpolated on the step and integrated exactly against the exponential
                (φ-functions): exact for stiff systems, interpolation error only.
"""

from __future__ import annotations

import math
import numbers
import time
from dataclasses import dataclass, field

import numpy as np

from ..options import check_memory


def _square(name, a, n=None):
    try:
        a = np.asarray(a, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"`{name}` must be a numeric matrix, got {a!r}") from None
    if a.ndim == 0 and n is None:
        a = a.reshape(1, 1)
    if a.ndim != 2 or a.shape[0] != a.shape[1]:
        raise ValueError(f"`{name}` must be a square matrix, got shape {a.shape}")
    if n is not None and a.shape != (n, n):
        raise ValueError(f"`{name}` must have shape ({n}, {n}) like M, got {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"`{name}` must be finite")
    return a


class LinearSystem:
    """M ẍ + C ẋ + K x = f(t).

    Parameters
    ----------
    M : (n, n) symmetric positive definite mass matrix
    C, K : (n, n) damping and stiffness (C may hold gyroscopic, K circulatory terms)
    force : callable t -> (n,) array, or None for free vibration
    """

    def __init__(self, M, C, K, force=None):
        self.M = _square("M", M)
        n = self.n = self.M.shape[0]
        self.C = _square("C", C, n)
        self.K = _square("K", K, n)
        if not np.allclose(self.M, self.M.T, rtol=1e-12, atol=1e-14 * np.abs(self.M).max()):
            raise ValueError("`M` must be symmetric")
        import scipy.linalg as sla      # lazily: beam elements are used without scipy
        try:
            self._chol = sla.cho_factor(self.M)
        except np.linalg.LinAlgError:
            raise ValueError("`M` must be positive definite (its Cholesky factorisation "
                             "failed)") from None
        if force is not None and not callable(force):
            raise ValueError(f"`force` must be a callable of t returning shape ({n},), or None")
        self.force = force
        self.Minv = sla.cho_solve(self._chol, np.eye(n))
        Minv_C = self.Minv @ self.C
        Minv_K = self.Minv @ self.K
        self.A = np.block([[-Minv_C, -Minv_K], [np.eye(n), np.zeros((n, n))]])

    def f(self, t) -> np.ndarray:
        if self.force is None:
            return np.zeros(self.n)
        out = np.asarray(self.force(t), dtype=float)
        if out.shape != (self.n,):
            raise ValueError(f"`force(t)` must return shape ({self.n},), got {out.shape} at t = {t}")
        if not np.all(np.isfinite(out)):
            raise ValueError(f"`force(t)` must be finite, got {out} at t = {t}")
        return out

    def F(self, t) -> np.ndarray:
        """State-space forcing [M⁻¹ f(t); 0]."""
        return np.concatenate([self.Minv @ self.f(t), np.zeros(self.n)])

    def simulate(self, t_end: float, h: float, method: str = "ss-newmark", x0=None, v0=None,
                 t_start: float = 0.0) -> "LinearResult":
        """Integrate with fixed step `h` from (x0, v0) (zero by default) to `t_end`."""
        if not (isinstance(h, numbers.Real) and math.isfinite(h) and h > 0):
            raise ValueError(f"`h` must be a positive step, got {h!r}")
        if not (math.isfinite(t_end) and t_end > t_start):
            raise ValueError(f"`t_end` must be after t_start = {t_start}, got {t_end!r}")
        try:
            cls = LINEAR_METHODS[method]
        except KeyError:
            raise ValueError(f"unknown method {method!r}; valid methods: "
                             f"{', '.join(LINEAR_METHODS)}") from None
        n = self.n
        x0 = np.zeros(n) if x0 is None else np.asarray(x0, float)
        v0 = np.zeros(n) if v0 is None else np.asarray(v0, float)
        for name, a in (("x0", x0), ("v0", v0)):
            if a.shape != (n,):
                raise ValueError(f"`{name}` must have shape ({n},), got {a.shape}")
            if not np.all(np.isfinite(a)):
                raise ValueError(f"`{name}` must be finite, got {a}")
        check_memory(((t_end - t_start) / h + 1) * 2 * n * 8.0,
                     f"`h` = {h:g} over {t_end - t_start:g} s ({(t_end - t_start) / h:.3g} "
                     f"steps of {n} coordinates and velocities)", "choose a larger h")
        steps = int(round((t_end - t_start) / h))
        if not math.isclose(steps * h, t_end - t_start, rel_tol=1e-9, abs_tol=1e-12 * h):
            raise ValueError(f"`t_end − t_start` = {t_end - t_start} is not a whole number of "
                             f"steps h = {h}")
        start = time.perf_counter()
        stepper = cls(self, h)
        t = t_start + h * np.arange(steps + 1)
        X = np.empty((steps + 1, n))
        V = np.empty((steps + 1, n))
        X[0], V[0] = x0, v0
        stepper.run(t, X, V)
        wall = time.perf_counter() - start
        return LinearResult(t, X, V, method, {"steps": steps, "h": h, "wall_time": wall})


@dataclass
class LinearResult:
    """Time history of a LinearSystem: t (n,), x and v (n, dofs)."""
    t: np.ndarray
    x: np.ndarray
    v: np.ndarray
    method: str
    stats: dict = field(default_factory=dict)

    def plot(self, dofs=None, ax=None, label=None, **style):
        """Displacements over time (all DOFs, or the given indices). Returns the Figure."""
        from ..results.plots import new_axes
        fig, ax = new_axes(ax)
        dofs = range(self.x.shape[1]) if dofs is None else np.atleast_1d(dofs)
        for d in dofs:
            ax.plot(self.t, self.x[:, d], label=f"{label or self.method}: x{d + 1}", **style)
        ax.set_xlabel("time [s]")
        ax.set_ylabel("displacement")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize="small")
        return fig


# --- methods ---------------------------------------------------------------------------------
class _Method:
    """A fixed-step method: built once per (system, h), then `run` fills X, V in place."""

    def __init__(self, system: LinearSystem, h: float):
        self.sys, self.h = system, h

    def run(self, t, X, V):
        raise NotImplementedError


class _StateSpace(_Method):
    """Methods on the state q = [ẋ; x]: subclasses implement `step(t, q) -> q_next`."""

    def run(self, t, X, V):
        n = self.sys.n
        q = np.concatenate([V[0], X[0]])
        for i in range(1, len(t)):
            q = self.step(t[i - 1], q)
            V[i], X[i] = q[:n], q[n:]


def _inverse(A):
    """The step matrices here (I − h/2 A, and K + 2C/h + 4M/h² for Newmark) are factorised
    once per step size; their explicit inverse turns each step's solve into one matrix-vector
    product instead of a solve through scipy's wrapper. Both are well
    conditioned: the eigenvalues of I − h/2 A are 1 − hλ/2 with Re λ ≤ 0, so |·| ≥ 1."""
    return np.linalg.inv(A)


class StateSpaceNewmark(_StateSpace):
    """Eq. 8 with eq. 7: constant average velocity over the step (the trapezoidal rule)."""

    def __init__(self, system, h):
        super().__init__(system, h)
        N = 2 * system.n
        self.B = _inverse(np.eye(N) - 0.5 * h * system.A)        # (I − h/2 A)⁻¹
        self.BF = 0.5 * h * self.B[:, :system.n] @ system.Minv   # h/2 (I − h/2 A)⁻¹ [M⁻¹; 0]

    def run(self, t, X, V):
        # With p_n = q_n + h/2 q̇_n, eq. 8 reads q_{n+1} = B p_n + B_F f_{n+1}, and eq. 7 gives
        # p_{n+1} = q_{n+1} + h/2 q̇_{n+1} = 2 q_{n+1} − p_n: one product with B per step.
        s, h, B, BF = self.sys, self.h, self.B, self.BF
        n = s.n
        q = np.concatenate([V[0], X[0]])
        p = q + 0.5 * h * (s.A @ q + s.F(t[0]))                       # eq. 9 with forcing
        Q = np.empty((len(t), 2 * n))
        Q[0] = q
        f = s.f if s.force is not None else None
        for i in range(1, len(t)):
            q = B @ p if f is None else B @ p + BF @ f(t[i])
            p = 2.0 * q - p
            Q[i] = q
        V[1:], X[1:] = Q[1:, :n], Q[1:, n:]


class ClassicalNewmark(_Method):
    """Average-acceleration Newmark (β = 1/4, γ = 1/2) in displacement form."""

    beta, gamma = 0.25, 0.5

    def run(self, t, X, V):
        s, h, b, g = self.sys, self.h, self.beta, self.gamma
        M, C, K = s.M, s.C, s.K
        a = s.Minv @ (s.f(t[0]) - C @ V[0] - K @ X[0])
        Keff_inv = _inverse(K + g / (b * h) * C + M / (b * h * h))
        c1, c2, c3 = 1 / (b * h * h), 1 / (b * h), 1 / (2 * b) - 1
        c4, c5, c6 = g / (b * h), g / b - 1, h / 2 * (g / b - 2)
        x, v = X[0], V[0]
        for i in range(1, len(t)):
            f_eff = s.f(t[i]) + M @ (c1 * x + c2 * v + c3 * a) + C @ (c4 * x + c5 * v + c6 * a)
            x_new = Keff_inv @ f_eff
            a_new = c1 * (x_new - x) - c2 * v - c3 * a
            v = v + h * ((1 - g) * a + g * a_new)
            x, a = x_new, a_new
            X[i], V[i] = x, v


class RungeKutta4(_StateSpace):
    def step(self, t, q):
        A, F, h = self.sys.A, self.sys.F, self.h
        k1 = A @ q + F(t)
        k2 = A @ (q + 0.5 * h * k1) + F(t + 0.5 * h)
        k3 = A @ (q + 0.5 * h * k2) + F(t + 0.5 * h)
        k4 = A @ (q + h * k3) + F(t + h)
        return q + h / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)


class Exact(_StateSpace):
    """q_{n+1} = e^{Ah} q_n + ∫₀ʰ e^{A(h−s)} F(t_n + s) ds, with the forcing interpolated on
    the step by a degree-`p` polynomial at Chebyshev nodes and integrated exactly against the
    exponential: ∫₀ʰ e^{A(h−s)} (s/h)^k ds = k! h φ_{k+1}(hA), the φ-functions taken from one
    exponential of the block matrix [[hA, I, 0, …], [0, 0, I, …], …] (Al-Mohy & Higham's
    construction). Stiff modes (hλ ≪ −1, which defeat quadrature of e^{A(h−s)}) are exact;
    the only error is the interpolation of the smooth forcing, below 1e-10 for ωh ≲ 1."""

    degree = 6

    def __init__(self, system, h):
        super().__init__(system, h)
        N, n, p = 2 * system.n, system.n, self.degree
        blocks = p + 2
        Z = np.zeros((N * blocks, N * blocks))
        Z[:N, :N] = system.A * h
        for k in range(blocks - 1):
            Z[k * N:(k + 1) * N, (k + 1) * N:(k + 2) * N] = np.eye(N)
        import scipy.linalg as sla
        top = sla.expm(Z)[:N]
        self.E = top[:, :N]
        if system.force is None:
            self.W = []
            return
        phis = [top[:, (k + 1) * N:(k + 2) * N] for k in range(p + 1)]   # φ_1 … φ_{p+1}
        x = 0.5 * (1 - np.cos(np.pi * (np.arange(p + 1) + 0.5) / (p + 1)))  # Chebyshev in [0,1]
        coeff = np.linalg.inv(np.vander(x, p + 1, increasing=True))       # ℓ_j(x) = Σ c_kj x^k
        fact = np.array([math.factorial(k) for k in range(p + 1)], float)
        self.nodes = x * h
        # W_j = h Σ_k c_kj k! φ_{k+1}(hA), applied to [M⁻¹ f; 0]: keep the first n columns.
        self.W = [h * sum(coeff[k, j] * fact[k] * phis[k] for k in range(p + 1))[:, :n]
                  @ system.Minv for j in range(p + 1)]

    def step(self, t, q):
        out = self.E @ q
        for s, W in zip(self.nodes, self.W):
            out += W @ self.sys.f(t + s)
        return out


LINEAR_METHODS = {"ss-newmark": StateSpaceNewmark, "newmark": ClassicalNewmark,
                  "rk4": RungeKutta4, "exact": Exact}
