"""Warner and Newton shooting, Floquet multipliers."""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from typing import Callable

import numpy as np

from ..threads import in_run_threads


@dataclass
class ShootingResult:
    converged: bool
    x0: np.ndarray
    iterations: int
    residual: float                  # max |g| at x0
    message: str
    floquet_multipliers: np.ndarray | None = None
    history: list = field(default_factory=list)   # (iteration, max|g|)
    mode: tuple | None = None        # (n, m) impacts per period, for problems that have modes
    flow: Callable | None = field(default=None, repr=False, compare=False)
    neutral: int = 0                 # multipliers at 1 from the problem's symmetries

    @cached_property
    def trajectory(self):
        """The motion over one period from x0 (the problem's `flow(x0)`), computed on first
        use: a run that only wants x0 does not pay for the sampled period."""
        return None if self.flow is None else self.flow()

    @property
    def stable(self) -> bool | None:
        """All Floquet multipliers inside the unit circle, but for the `neutral` ones
        that a symmetry of the problem fixes at 1 (None if not computed)."""
        if self.floquet_multipliers is None:
            return None
        return bool(np.all(np.abs(self.significant_multipliers) < 1.0))

    @property
    def significant_multipliers(self) -> np.ndarray | None:
        """The Floquet multipliers without the `neutral` ones nearest 1."""
        mu = self.floquet_multipliers
        if mu is None or not self.neutral:
            return mu
        keep = np.ones(mu.size, bool)
        keep[np.argsort(np.abs(mu - 1.0), kind="stable")[:self.neutral]] = False
        return mu[keep]


def central_jacobian(end, u, rel_step=1e-6):
    """∂end/∂u by central differences of `end(u) -> ndarray` (a flow's final state: valid
    across events as long as the perturbed flows meet the same sequence of events — the
    saltation is then included)."""
    u = np.asarray(u, float)
    columns = []
    for j in range(u.size):
        d = rel_step * max(1.0, abs(u[j]))
        up, um = u.copy(), u.copy()
        up[j] += d
        um[j] -= d
        columns.append((end(up) - end(um)) / (2 * d))
    return np.column_stack(columns)


def monodromy(problem, u, rel_step=1e-6):
    """∂x(T)/∂u by central differences of the problem's period map (its flow's end)."""
    return central_jacobian(problem.period_map, u, rel_step)


def _residual_or_none(problem, x):
    """g(x), or None where the flow from x fails (chatter, an event the problem cannot
    resolve, a non-finite state): a bad iterate, not the end of the search."""
    try:
        g = problem.residual(x)
    except (ValueError, ArithmeticError, RuntimeError):
        return None
    return g if np.all(np.isfinite(g)) else None


def _warner(problem, guess, tol, max_iter, scale, guesses, max_halvings=30, **_):
    """Seed 002, appendix, steps 1–7. Where the flow from a new guess fails, the guess is
    moved halfway back towards the best vector until a flow succeeds (at most
    `max_halvings` times), as Newton's steps are damped."""
    n = problem.n
    X = (np.array(guesses, float) if guesses is not None
         else np.array([guess * scale**k for k in range(n + 1)]))         # step 1
    if X.shape != (n + 1, n):
        raise ValueError(f"Warner's algorithm needs {n + 1} guess vectors of length {n}, "
                         f"got shape {X.shape}")
    G = []
    for k, x in enumerate(X):                                             # step 2
        g = _residual_or_none(problem, x)
        if g is None:
            return x, np.full(n, np.inf), 0, [], (f"the flow from guess vector {k} fails; "
                                                   "give other guesses")
        G.append(g)
    G = np.array(G)
    history = []
    best = int(np.argmin(np.max(np.abs(G), axis=1)))
    x, g = X[best], G[best]
    for it in range(1, max_iter + 1):
        Q = np.hstack([np.ones((n + 1, 1)), G])                            # step 3
        b = np.zeros(n + 1)
        b[0] = 1.0
        try:
            c = np.linalg.solve(Q.T, b)                                    # cᵀ = bᵀ Q⁻¹
        except np.linalg.LinAlgError:
            return x, g, it, history, "Q became singular (guess vectors degenerate)"
        x = c @ X                                                          # step 4
        if not np.all(np.isfinite(x)):
            return X[best], G[best], it, history, "the new guess is not finite"
        g = _residual_or_none(problem, x)
        for _ in range(max_halvings):
            if g is not None:
                break
            x = 0.5 * (x + X[best])
            g = _residual_or_none(problem, x)
        if g is None:
            return X[best], G[best], it, history, ("the flow fails from every guess between "
                                                   "the new one and the best so far")
        history.append((it, float(np.max(np.abs(g)))))
        if np.max(np.abs(g)) < tol:                                        # step 7
            return x, g, it, history, "converged"
        worst = int(np.argmax(np.sum(G**2, axis=1)))                       # step 5
        X[worst], G[worst] = x, g                                          # step 6
        best = int(np.argmin(np.max(np.abs(G), axis=1)))
    return X[best], G[best], max_iter, history, f"no convergence within {max_iter} iterations"


def _forward_jacobian(problem, u, g, rel_step=1e-6):
    """∂g/∂u by forward differences reusing g = g(u): n flows. (For the oscillators
    g = x(0) − x(T) and ∂g/∂u = I − Φ; for the impact pair x(0) is not u itself.)"""
    u = np.asarray(u, float)
    J = np.empty((g.size, u.size))
    for j in range(u.size):
        d = rel_step * max(1.0, abs(u[j]))
        up = u.copy()
        up[j] += d
        J[:, j] = (problem.residual(up) - g) / d
    return J


def _newton_step(J, g, singular):
    """−J⁺g: the minimum-norm step where J is singular along a symmetry of the problem
    (`singular_jacobian`: the impact pair may be shifted as a whole, a family of periodic
    solutions) or turns out singular, else the plain solve (a third of the cost)."""
    if not singular and J.shape[0] == J.shape[1]:
        try:
            return -np.linalg.solve(J, g)
        except np.linalg.LinAlgError:
            pass
    return -np.linalg.lstsq(J, g, rcond=1e-10)[0]


def _newton(problem, guess, tol, max_iter, max_halvings=30, xtol=None, **_):
    """Quasi-Newton shooting: the Jacobian ∂g/∂u by forward differences (n flows), then
    Broyden's rank-one updates (no extra flow) while they keep converging; a fresh Jacobian
    when a step had to be damped or reduced ‖g‖ by less than half. A problem that knows its
    monodromy (`residual_jacobian(u) -> (g, J)` or None) gives the exact Jacobian with each
    flow instead. Steps are halved until ‖g‖ decreases.

    With `xtol` and the exact Jacobian, the iteration also stops where the full Newton step
    predicts the next iterate within xtol of the solution (max norm): with contraction
    Θ = ‖Δu‖/‖Δu_prev‖ < 1/2 that error is about Θ‖Δu‖/(1 − Θ). The next iterate is
    returned without a flow of its own (the residual reported is the last one evaluated)."""
    u = np.array(guess, float)
    exact = getattr(problem, "residual_jacobian", None)
    prev_step = None

    def evaluate(x):
        """(g, J) with the exact J when the problem has it (one flow), else (g, None)."""
        if exact is not None:
            out = exact(x)
            if out is not None:
                return out
        return problem.residual(x), None

    g, J = evaluate(u)
    J_exact = J is not None
    history = []
    for it in range(1, max_iter + 1):
        if J is None:
            J = _forward_jacobian(problem, u, g)
        du = _newton_step(J, g, getattr(problem, "singular_jacobian", True))
        size = float(np.max(np.abs(du)))
        if xtol is not None and J_exact and prev_step is not None and size < 0.5 * prev_step:
            theta = size / prev_step
            if theta * size / (1.0 - theta) <= xtol:
                return u + du, g, it, history, (f"converged: the Newton step predicts x0 "
                                                f"within xtol = {xtol:g}")
        lam, norm = 1.0, np.linalg.norm(g)
        for _ in range(max_halvings):
            try:
                g_new, J_new = evaluate(u + lam * du)
            except ValueError:
                g_new, J_new = np.full_like(g, np.inf), None
            if np.linalg.norm(g_new) < norm or lam < 1e-6:
                break
            lam *= 0.5
        step = lam * du
        prev_step = size if lam == 1.0 else None
        good = lam == 1.0 and np.linalg.norm(g_new) < 0.5 * norm
        J_exact = J_new is not None
        if J_new is not None:
            J = J_new
        elif good and np.all(np.isfinite(g_new)):
            J = J + np.outer(g_new - g - J @ step, step) / (step @ step)      # Broyden
        else:
            J = None
        u, g = u + step, g_new
        history.append((it, float(np.max(np.abs(g)))))
        if np.max(np.abs(g)) < tol:
            return u, g, it, history, "converged"
    return u, g, max_iter, history, f"no convergence within {max_iter} iterations"


SHOOTING_METHODS = {"warner": _warner, "newton": _newton}


@in_run_threads
def solve(problem, guess, method: str = "warner", tol: float = 1e-6, max_iter: int = 50,
          scale: float = 1.01, guesses=None, floquet: bool = True,
          max_halvings: int = 30, xtol: float | None = None) -> ShootingResult:
    """Find u with g(u) = 0 for a periodic `problem` (see `mechsim.shooting.oscillators`).

    Parameters
    ----------
    guess : the unknowns' starting values (for "warner", the other n guess vectors are
        `guess · scale^k`, as in the paper's tables, unless `guesses` gives all n+1)
    tol : stop when max abs(g) < tol (the paper's eq. 8: 1e-6)
    max_halvings : "newton" halves a step at most this often looking for a smaller ‖g‖
        (fewer makes hopeless starts fail sooner, e.g. in a regime map); "warner" halves a
        new guess back towards the best one at most this often where its flow fails
    xtol : "newton" with the exact monodromy also stops where its step predicts the
        unknowns within xtol (max norm) of the solution, without a flow at the last
        iterate (quadratic convergence makes that prediction conservative)
    floquet : compute the Floquet multipliers at the solution: eigenvalues of the state
        monodromy (`problem.floquet_matrix(u)` where the unknowns are not the state, else
        ∂x(T)/∂x(0) by finite differences)
    """
    if method not in SHOOTING_METHODS:
        raise ValueError(f"unknown method {method!r}; valid methods: "
                         f"{', '.join(SHOOTING_METHODS)}")
    if not tol > 0:
        raise ValueError(f"`tol` must be positive, got {tol!r}")
    guess = problem.check(guess)
    if xtol is not None and not xtol > 0:
        raise ValueError(f"`xtol` must be positive, got {xtol!r}")
    x, g, its, history, message = SHOOTING_METHODS[method](
        problem, guess, tol, max_iter, scale=scale, guesses=guesses, max_halvings=max_halvings,
        xtol=xtol)
    converged = message.startswith("converged")
    mults = None
    if floquet and converged:
        state_map = problem.floquet_matrix(x) if hasattr(problem, "floquet_matrix") \
            else monodromy(problem, x)
        mults = np.linalg.eigvals(state_map)
    mode = problem.mode(x) if hasattr(problem, "mode") else None
    return ShootingResult(converged, np.asarray(x), its, float(np.max(np.abs(g))), message,
                          mults, history, mode, flow=lambda: problem.flow(x),
                          neutral=getattr(problem, "neutral_multipliers", 0))
