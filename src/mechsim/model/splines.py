"""Curves given by points: the periodic cubic spline r(φ) of a cam's pitch curve, and a
driver's table (`evaluate_table`, the same layout over time, not periodic).

The spline is data, not structure: its knots and coefficients are parameters of the joint
that uses it (`coefficients`), so a cam with other points but as many of them needs no new
build. `evaluate` reads them in that layout, for numbers here and in the generated Python
code; `codegen/spline.c` is its twin for compiled models.

Layout of the parameters of a spline through k points: the k + 1 knots φ₀ < … < φ_k =
φ₀ + 2π, then the k cubic pieces' coefficients (a, b, c, d) in order, r = ((a u + b) u +
c) u + d with u = φ − φ_i on [φ_i, φ_{i+1}].
"""

from __future__ import annotations

import math
from bisect import bisect_right

import numpy as np

from .checks import ModelError, number_array

TWO_PI = 2.0 * math.pi


class PeriodicSpline:
    """The periodic cubic spline through the points (φ_i, r_i), i < k (φ increasing within
    one turn; the curve closes with C² continuity through the first point a turn on):
    scipy's `CubicSpline` with periodic ends. `owner` names the model object in errors."""

    def __init__(self, points, owner: str):
        table = number_array(points, owner, "the curve's points as rows (phi, r) of numbers")
        if table.ndim != 2 or table.shape[1] != 2 or len(table) < 4:
            raise ModelError(f"{owner}: the curve's points must be at least 4 rows (phi, r), "
                             f"got shape {table.shape}")
        if not np.all(np.isfinite(table)):
            raise ModelError(f"{owner}: the curve's points must be finite")
        phi, r = table[:, 0], table[:, 1]
        if not np.all(np.diff(phi) > 0.0) or not phi[-1] - phi[0] < TWO_PI:
            raise ModelError(f"{owner}: the points' angles must increase within one turn "
                             f"(less than 2π from the first, {phi[0]:.6g}); the curve "
                             "closes itself through the first point")
        if not np.all(r > 0.0):
            raise ModelError(f"{owner}: the curve's radii must be positive")
        self.points = table
        self.k = len(table)
        from scipy.interpolate import CubicSpline
        knots = np.append(phi, phi[0] + TWO_PI)
        spline = CubicSpline(knots, np.append(r, r[0]), bc_type="periodic")
        self.coefficients = tuple(float(x) for x in
                                  np.concatenate([knots, spline.c.T.reshape(-1)]))

    @property
    def parameter_names(self) -> tuple[str, ...]:
        return tuple(f"spline{i}" for i in range(len(self.coefficients)))

    @property
    def canonical(self) -> str:
        """What the generated equation depends on: the spline's size (its numbers are
        parameters)."""
        return f"periodic spline of {self.k} points"

    def value(self, phi: float) -> float:
        return float(evaluate(0, phi, self.k, self.coefficients))

    def jet(self, name: str, value: float) -> tuple[float, float, float]:
        """(r, r', r'') at φ = `value` (the `Expression.jet` of a curve in `name` = "phi")."""
        return tuple(float(evaluate(order, value, self.k, self.coefficients))
                     for order in range(3))


def evaluate(order, phi, k, parameters):
    """The `order`-th derivative (0 to 3) of the spline of k pieces whose parameters are
    `parameters` (the layout above: a sequence of numbers, or of arrays over many joints)
    at φ (a number or an array), φ taken round to the knots' turn."""
    p = np.asarray(parameters, float)
    knots = p[:k + 1]
    start = knots[0]
    x = start + np.mod(np.asarray(phi, float) - start, TWO_PI)
    if knots.ndim == 1:                      # one spline: φ of any shape
        coefficients = p[k + 1:].reshape(k, 4)
        i = np.sum(x[..., None] >= knots[1:k], axis=-1)
        a, b, c, d = np.moveaxis(coefficients[i], -1, 0)
        u = x - knots[i]
    else:                                    # one spline per joint (columns): φ (N,)
        coefficients = p[k + 1:].reshape((k, 4) + knots.shape[1:])
        i = np.sum(x[None] >= knots[1:k], axis=0)
        cols = np.arange(knots.shape[1])
        a, b, c, d = (coefficients[i, j, cols] for j in range(4))
        u = x - knots[i, cols]
    if order > 3:
        raise ValueError(f"a cubic spline has no derivative of order {order}")
    return _cubic(order, a, b, c, d, u)


def evaluate_table(order, t, k, parameters, first=0):
    """The `order`-th derivative of the (not periodic) cubic spline of k pieces whose
    k + 1 knots and 4 k coefficients are `parameters` from index `first` on (the layout
    above) at t (a number or an array): a driver's table
    (`mechsim.model.drivers.TableLaw`), the end pieces going on past the ends."""
    if np.ndim(t) == 0:
        # One time (a generated model's call at every stage): the knot found by bisection
        # in the parameters as given (the model's whole vector: no copy), plain floats.
        i = bisect_right(parameters, float(t), first + 1, first + k) - 1
        j = first + k + 1 + 4 * (i - first)
        a, b, c, d = (float(x) for x in parameters[j:j + 4])
        u = float(t) - float(parameters[i])
    else:
        p = np.asarray(parameters[first:first + 5 * k + 1], float)
        knots = p[:k + 1]
        x = np.asarray(t, float)
        i = np.searchsorted(knots[1:k], x, side="right")  # the interior knots at or below t
        j = k + 1 + 4 * i
        a, b, c, d = p[j], p[j + 1], p[j + 2], p[j + 3]
        u = x - knots[i]
    return _cubic(order, a, b, c, d, u)


def _cubic(order, a, b, c, d, u):
    """The `order`-th derivative of ((a u + b) u + c) u + d (0 beyond the third)."""
    if order == 0:
        return ((a * u + b) * u + c) * u + d
    if order == 1:
        return (3.0 * a * u + 2.0 * b) * u + c
    if order == 2:
        return 6.0 * a * u + 2.0 * b
    if order == 3:
        return 6.0 * a
    return np.zeros_like(u)[()]
