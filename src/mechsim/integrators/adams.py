"""Variable-step, variable-order Adams–Bashforth–Moulton in PECE mode (seed 001's integrator).

Each step of order k evaluates the right-hand side twice:

    P  y_p = y_n + ∫ p_k        p_k interpolates f at t_n, …, t_{n−k+1}       (AB, order k)
    E  f_p = f(t_{n+1}, y_p)
    C  y_c = y_n + ∫ p*_{k+1}   p*  interpolates f_p, f_n, …, f_{n−k+1}     (AM, order k+1)
    E  f_c = f(t_{n+1}, y_c)

The integrals run over [t_n, t_{n+1}] on the actual (irregular) grid: the weights are the
integrals of the Lagrange basis, computed by Gauss–Legendre quadrature (exact for these
polynomials and, unlike Vandermonde solves, well conditioned for any spacing). The local
error is estimated by Milne's device ‖y_c − y_p‖ and the higher-order corrector is kept
(local extrapolation, as in Shampine–Gordon). After each accepted step the estimates at
orders k−1, k, k+1 (same f values, no extra evaluations) pick the order that allows the
largest next step; the order rises by at most one per step, so a fresh start climbs from
order 1. After a change of coordinates (a re-partition, a switch of formulation, a bridge
over a passage) the solver manager restarts warm instead: `seed_history` takes the
derivatives at the last accepted states re-expressed in the new coordinates, and the new
solver goes on at the old order. Dense output integrates the corrector's interpolant to any
point inside the step.

It is a scipy `OdeSolver`, so `solve_ivp(fun, span, y0, method=AdamsPECE)` works too.
"""

from __future__ import annotations

import numpy as np
from scipy.integrate import DenseOutput, OdeSolver

_GX, _GW = np.polynomial.legendre.leggauss(8)     # exact to degree 15 ≥ the highest order
_GX = 0.5 * (_GX + 1.0)                            # on [0, 1]
_GW = 0.5 * _GW
# The rule `integration_weights` integrates with, (points, weights) on [0, 1] (the
# compiled engine's interpolant takes the same).
QUADRATURE = (_GX, _GW)
# Weights by node pattern, shared by all solvers: the patterns of a run recur after each
# restart (a bridge, a switch) and in the next run.
_WEIGHTS: dict = {}


def integration_weights(nodes: np.ndarray, s) -> np.ndarray:
    """w_j = ∫_0^s L_j(τ) dτ for the Lagrange basis on `nodes` (in units of the step).
    `s` scalar -> shape (K,); `s` array (P,) -> shape (P, K)."""
    s = np.atleast_1d(np.asarray(s, float))
    x = (s[:, None] * _GX[None, :]).reshape(-1, 1)                 # (P·G, 1) quadrature points
    diff = x - nodes[None, :]                                      # (P·G, K)
    dn = nodes[:, None] - nodes[None, :]
    np.fill_diagonal(dn, 1.0)
    denom = np.prod(dn, axis=1)                                    # (K,)
    # L_j(x) = Π_{i≠j}(x − τ_i) / denom_j: prefix and suffix products leave factor j out.
    ones = np.ones((diff.shape[0], 1))
    left = np.cumprod(np.hstack([ones, diff[:, :-1]]), axis=1)
    right = np.cumprod(np.hstack([ones, diff[:, :0:-1]]), axis=1)[:, ::-1]
    L = (left * right / denom).reshape(s.size, _GX.size, nodes.size)
    return np.einsum("g,pgk->pk", _GW, L) * s[:, None]


def step_weights(nodes, s=1.0) -> np.ndarray:
    """`integration_weights(nodes, s)[0]` for a scalar s, cached by the pattern of the
    nodes: the controller keeps h unchanged unless a real change is called for, so on a
    steady stretch the nodes are the same integers step after step and the weights are
    computed once (for dense output on a regular grid, the fractions s recur as well);
    patterns recur after each restart too (a bridge, a switch)."""
    # Steps change by factors of two, so the nodes are dyadic up to the round-off of t:
    # snapping them to multiples of 2⁻⁴⁰ makes equal patterns hit the cache. The
    # weights are those of the snapped nodes, so a run does not depend on what earlier
    # runs left in the cache.
    snapped, key = _pattern(np.append(nodes, s))
    return _cached(_WEIGHTS, key, lambda: integration_weights(snapped[:-1], snapped[-1])[0])


# The corrector weights of every order on a node pattern (`order_weights`).
_ORDERS: dict = {}


def order_weights(nodes, first) -> np.ndarray:
    """The rows `step_weights(nodes[:k])` for k = first … len(nodes), each padded with zeros
    to len(nodes) (a matrix of one row an order), cached by the pattern of the nodes as
    `step_weights` caches its rows (the same numbers): a passage bridge estimates its error
    from the correctors of all its orders on nodes whose pattern recurs bridge after
    bridge."""
    def make():
        K = len(nodes)
        W = np.zeros((K - first + 1, K))
        for k in range(first, K + 1):
            W[k - first, :k] = step_weights(nodes[:k])
        W.flags.writeable = False
        return W
    return _cached(_ORDERS, (first, _pattern(nodes)[1]), make)


def _pattern(values):
    """(values snapped to multiples of 2⁻⁴⁰, the integers that key them)."""
    snapped = np.rint(np.asarray(values, dtype=float) * 2.0**40)
    return snapped * 2.0**-40, tuple(snapped.astype(np.int64).tolist())


def _cached(cache, key, make):
    """cache[key], made by make() where it is missing (the cache emptied past 20000)."""
    found = cache.get(key)
    if found is None:
        if len(cache) > 20000:
            cache.clear()
        found = cache[key] = make()
    return found


def error_norm(e, y_a, y_b, rtol, atol) -> float:
    """RMS of the error e scaled by atol + rtol·max(|y_a|, |y_b|): ≤ 1 meets the tolerance."""
    if not e.size:
        return 0.0
    scale = atol + rtol * np.maximum(np.abs(y_a), np.abs(y_b))
    return float(np.sqrt(np.mean((e / scale) ** 2)))


class AdamsPECE(OdeSolver):
    """Variable-step, variable-order Adams PECE (orders 1..`max_order`) with error control.

    Parameters follow scipy's solvers: fun, t0, y0, t_bound, rtol, atol, max_step,
    first_step; plus `max_order` (default 10). Exposes `order`, `n_rejected`.
    """

    max_order_limit = 12

    def __init__(self, fun, t0, y0, t_bound, max_step=np.inf, rtol=1e-6, atol=1e-8,
                 first_step=None, max_order=10, vectorized=False, **extraneous):
        super().__init__(fun, t0, y0, t_bound, vectorized, support_complex=False)
        self.max_step = float(max_step)
        self.rtol, self.atol = float(rtol), atol
        if not 1 <= int(max_order) <= self.max_order_limit:
            raise ValueError(f"`max_order` must be in 1..{self.max_order_limit}, "
                             f"got {max_order}")
        self.max_order = int(max_order)
        self.f = self.fun(self.t, self.y)
        self.ts = [self.t]          # accepted times, newest last
        self.fs = [self.f]          # their derivatives
        self.order = 1
        self.n_rejected = 0
        self.h = self._initial_step() if first_step is None else min(float(first_step), self._initial_step(loose=True))
        self.h = min(self.h, self.max_step, abs(self.t_bound - self.t))
        self._dense = None
        self._same_h = 0
        # (t, y) -> y projected onto an invariant manifold, or None where y is on it:
        # applied to an accepted corrector before its evaluation (P E C, project, E).
        self.project = None

    def _norm(self, e, y_a, y_b):
        return error_norm(e, y_a, y_b, self.rtol, self.atol)

    def _initial_step(self, loose=False):
        # Order 1 (Euler predictor, trapezoid corrector) has local error ~ h² |f'|: start small
        # and let the controller grow the step.
        scale = self.atol + self.rtol * np.abs(self.y)
        d0 = float(np.sqrt(np.mean((self.y / scale) ** 2))) if self.y.size else 0.0
        d1 = float(np.sqrt(np.mean((self.f / scale) ** 2))) if self.y.size else 0.0
        h = 1e-6 if d0 < 1e-5 or d1 < 1e-5 else 0.01 * d0 / d1
        h = min(h, 1e-2 * abs(self.t_bound - self.t) or 1e-6)
        return h if loose else h * 0.1

    def _nodes(self, count, h, include_new):
        """Nodes (in units of h, relative to t_n) of the newest `count` points."""
        t_n = self.ts[-1]
        past = (np.array(self.ts[-count:][::-1]) - t_n) / h
        return np.concatenate([[1.0], past]) if include_new else past

    def _step_impl(self):
        t, y = self.t, self.y
        h = min(self.h, self.max_step, abs(self.t_bound - t))
        while True:
            k = min(self.order, len(self.ts))
            if h < 10 * np.abs(np.nextafter(t, np.inf) - t):
                return False, self.TOO_SMALL_STEP
            F = np.array(self.fs[-k:][::-1])                        # f_n, f_{n−1}, …
            a = step_weights(self._nodes(k, h, False))
            y_p = y + h * (a @ F)
            f_p = self.fun(t + h, y_p)
            Fc = np.vstack([f_p, F])
            b = step_weights(self._nodes(k, h, True))
            y_c = y + h * (b @ Fc)
            err = self._norm(y_c - y_p, y, y_c)
            if err <= 1.0:
                break
            self.n_rejected += 1
            # Halve (quarter when far off) rather than scale freely: the node pattern then
            # recurs and the weights come from the cache.
            factor = 0.25 if not np.isfinite(err) or err > 2.0 ** (k + 2) else 0.5
            h *= factor
            self._same_h = 0
            self.order = max(1, min(self.order, k) - (1 if not np.isfinite(err) else 0))
        if self.project is not None:
            projected = self.project(t + h, y_c)
            if projected is not None:
                y_c = np.asarray(projected, float)
        f_c = self.fun(t + h, y_c)
        # The step is accepted: keep the interpolant data for dense output.
        self._dense = (t, h, y.copy(), np.vstack([f_c, F]), self._nodes(k, h, True))
        self.t, self.y, self.f = t + h, y_c, f_c
        self.ts.append(self.t)
        self.fs.append(f_c)
        del self.ts[:-(self.max_order + 2)], self.fs[:-(self.max_order + 2)]
        self._same_h += 1
        if h >= self.max_step * (1.0 - 1e-12) and err <= 0.5:
            # Held at max_step with room to spare: no order would allow a longer step, and
            # every order costs the same two evaluations, so the choice is skipped (a flexible
            # mechanism at a small max_step spends most steps here).
            self.order, factor = k, 1.0
        else:
            self.order, factor = self._choose_order(k, h, y, y_c, Fc, err)
        if factor != 1.0:
            self._same_h = 0
        self.h = h * factor
        return True, None

    def seed_history(self, ts, fs, order: int, h: float):
        """Continue a run from here as if these derivatives had been integrated: `ts`, `fs`
        the earlier times (oldest first) and y' there in this solver's coordinates. The
        order is at most what the history supports, and the next step is `h` (capped by
        max_step). Used after a change of coordinates (a new partition, a switch of
        formulation): the history is re-expressed in the new coordinates, so the start
        need not climb from order 1 again."""
        ts = [float(t) for t in ts]
        if any(b <= a for a, b in zip(ts, ts[1:] + [self.t])):
            raise ValueError("seed_history: the times must increase up to the present one")
        self.ts = ts + [self.t]
        self.fs = [np.asarray(f, float) for f in fs] + [self.f]
        del self.ts[:-(self.max_order + 2)], self.fs[:-(self.max_order + 2)]
        self.order = max(1, min(int(order), self.max_order, len(self.ts)))
        self.h = min(float(h), self.max_step, abs(self.t_bound - self.t))
        self._same_h = 0

    def correct(self, y):
        """Replace the current state by a corrected one (e.g. projected onto the constraint
        manifold) and keep the history: the newest derivative is re-evaluated there."""
        self.y = np.array(y, float)
        self.f = self.fun(self.t, self.y)
        self.fs[-1] = self.f
        if self._dense is not None:
            t, h, y_old, F, nodes = self._dense
            F = F.copy()
            F[0] = self.f
            self._dense = (t, h, y_old, F, nodes)

    def _choose_order(self, k, h, y, y_c, Fc, err_k):
        """Order and step factor for the next step.

        Error estimates at orders k−1, k, k+1 (same f values, no new evaluations) pick the
        order that allows the largest step; the order rises by at most one, only after k+1
        steps at the same h (before that the estimate at k+1 is unreliable), and a step that
        changes the order keeps h. Steps change by halving or doubling only, so node
        patterns recur and their weights are cached; this costs a few more steps than free
        scaling and removes most weight computations and rejections."""
        best_order, best = k, (0.9 * err_k ** (-1.0 / (k + 1)) if err_k > 0 else 5.0)
        n_hist = len(self.ts) - 1                    # past points before t_{n+1}
        for j in (k - 1, k + 1):
            if j < 1 or j > self.max_order or j > n_hist:
                continue
            if j > k and self._same_h < k + 1:
                continue
            F = Fc[1:j + 1] if j <= k else None
            if F is None:                              # need one more past derivative
                F = np.array(self.fs[-(j + 1):-1][::-1])
            past = (np.array(self.ts[-(j + 1):-1][::-1]) - self.ts[-2]) / h
            yp = y + h * (step_weights(past) @ F)
            yc = y + h * (step_weights(np.concatenate([[1.0], past])) @ np.vstack([Fc[0], F]))
            e = self._norm(yc - yp, y, yc)
            factor = 0.9 * e ** (-1.0 / (j + 1)) if e > 0 else 5.0
            if factor > 1.1 * best:
                best_order, best = j, factor
        if best_order != k:
            return best_order, 1.0
        if best >= 2.0:
            return k, 2.0
        if best < 1.0:
            return k, 0.5
        return k, 1.0

    def _dense_output_impl(self):
        t, h, y, F, nodes = self._dense
        return _AdamsDense(t, t + h, y, h, F, nodes, step_weights)


class _AdamsDense(DenseOutput):
    def __init__(self, t_old, t, y_old, h, F, nodes, weights):
        super().__init__(t_old, t)
        self.y_old, self.hh, self.F, self.nodes = y_old, h, F, nodes
        self.weights = weights

    def _call_impl(self, t):
        s = (np.atleast_1d(t) - self.t_old) / self.hh
        if s.size > 1:             # several samples in one step: one quadrature for all
            w = integration_weights(np.asarray(self.nodes, float), s)      # (P, K)
        else:                      # one: its fraction may recur (a regular output grid)
            w = np.array([self.weights(self.nodes, sk) for sk in s])
        out = self.y_old[None, :] + self.hh * (w @ self.F)          # (P, n)
        return out[0] if np.ndim(t) == 0 else out.T
