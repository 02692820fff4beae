"""The work of non-conservative forces and drivers, integrated with the motion.

The energy balance E(t) − E(t₀) − W(t) measures the solver only if W is exact to well below
the integrator's error. A quadrature over the output samples measures their spacing instead
(a damped spring-mass at rtol 1e-10: 3.8e-4 with the default output, 5.5e-9 sampled every
millisecond). So W is integrated step by step along each accepted step's interpolant (the
integrator's dense output, or a passage bridge's polynomial), which carries the step's
accuracy: the power of every channel is sampled at Chebyshev points of the step, its
Chebyshev interpolant integrated exactly, and the step is halved where the interpolant's
last coefficients say its integral is not resolved to a tenth of rtol of the run's peak
power times the step's half-length. The work at an output sample inside a step comes from
the same interpolant. The test is on W, not on the power: a neglected term c T_k of the
power moves W anywhere in the piece by at most |c| max |∫₋₁ˣ T_k| of the half-length
(0.118 for k = 9), so a power resolved only to that bound is not halved again.
"""

from __future__ import annotations

import numpy as np
from numpy.polynomial import chebyshev as cheb

# Chebyshev points per piece (degree + 1) and the most halvings of one step. A step left
# unresolved at that depth (the power is not smooth there: a singular configuration, where
# the drivers' λ grows without bound) takes the next step in one piece, until a step is
# resolved again: no stretch of steps costs more than 9 evaluations each.
POINTS = 9
MAX_HALVINGS = 3

_NODES = cheb.chebpts1(POINTS)            # on [−1, 1]
_TO_COEFFICIENTS = np.linalg.inv(cheb.chebvander(_NODES, POINTS - 1))
# Values at the nodes -> the Chebyshev coefficients of the interpolant's integral from −1,
# and its integral over [−1, 1] (Fejér's first rule).
_INTEGRAL = cheb.chebint(_TO_COEFFICIENTS, lbnd=-1.0)
_WEIGHTS = cheb.chebval(1.0, _INTEGRAL)
# The most a neglected term T_POINTS of unit coefficient moves the integral from −1 to any
# x in [−1, 1]: max |T_{k+1}/2(k+1) − T_{k−1}/2(k−1) − its value at −1|, k = POINTS.
_SPREAD = float(np.max(np.abs(cheb.chebval(
    np.linspace(-1.0, 1.0, 4001), cheb.chebint(np.eye(POINTS + 1)[POINTS], lbnd=-1.0)))))


class WorkIntegral:
    """W(t) of each of `channels`, from t₀, along the steps of a run.

    `rates(T, Q, V)` is the power of every channel at consistent states (rows; shape
    (N, k));
    `add(a, b, states, times)` integrates over the accepted step [a, b] whose interpolant
    gives `states(ts) -> (Q, V)` (rows: the times `ts`), and returns W at each of `times`
    in (a, b] (the output samples the step recorded). A step whose states or powers cannot
    be evaluated stops the integral: `failure` says where, and later samples have none.
    """

    def __init__(self, channels, rates, tolerance: float, energy: float, span: float):
        """`tolerance`: the resolution asked of each piece, relative to the run's peak
        power (or to the mechanism's energy spread over the run, where that is larger: a
        run starting at rest); `Tolerances.work`."""
        self.channels = list(channels)
        self.rates = rates
        self.tolerance = tolerance
        self.total = np.zeros(len(self.channels))
        self.energy, self.span = energy, span
        self.peak = 0.0                 # the largest |power| seen
        self.evaluations = 0
        self.unresolved = 0             # pieces accepted at the halving limit
        self._halvings = MAX_HALVINGS     # allowed in the next step
        self.failure = ""

    def add(self, a: float, b: float, states, times=()) -> np.ndarray | None:
        """W at `times` (sorted, in (a, b]; shape (len(times), k)) after integrating the
        step [a, b]; None once the integral has failed."""
        if self.failure:
            return None
        if not b > a:                     # a step of no length (a run ending where it began)
            return np.tile(self.total, (len(times), 1))
        unresolved = self.unresolved
        try:
            out = self._piece(a, b, states, np.asarray(times, float), self._halvings)
            self._halvings = 0 if self.unresolved > unresolved else MAX_HALVINGS
            return out
        except (ArithmeticError, ValueError, np.linalg.LinAlgError, RuntimeError) as exc:
            self.failure = (f"the work could not be integrated over the step "
                            f"[{a:.9g}, {b:.9g}] ({type(exc).__name__}: {exc})")
            return None

    def _piece(self, a, b, states, times, halvings):
        ts = 0.5 * (a + b) + 0.5 * (b - a) * _NODES
        Q, V = states(ts)
        P = np.asarray(self.rates(ts, Q, V), float).reshape(len(ts), len(self.channels))
        self.evaluations += len(ts)
        if not np.all(np.isfinite(P)):
            raise ArithmeticError("a non-finite power inside the step")
        self.peak = max(self.peak, float(np.max(np.abs(P), initial=0.0)))
        resolved = (_SPREAD * _tail(P)
                    <= self.tolerance * max(self.peak, self.energy / self.span))
        if not resolved and halvings > 0 and b - a > 1e-12 * max(abs(a), abs(b)):
            mid = 0.5 * (a + b)
            left = times <= mid
            first = self._piece(a, mid, states, times[left], halvings - 1)
            return np.vstack([first, self._piece(mid, b, states, times[~left], halvings - 1)])
        self.unresolved += not resolved
        half = 0.5 * (b - a)
        x = (2.0 * times - (a + b)) / (b - a)
        out = self.total + half * (cheb.chebvander(x, POINTS) @ _INTEGRAL) @ P
        self.total = self.total + half * (_WEIGHTS @ P)
        return out


def _tail(P) -> float:
    """The size of the Chebyshev coefficients beyond the interpolant of the values P at
    the nodes (rows): the last coefficient, or the one before it taken one step further
    down the decay it shows (c²_{N−2}/c_{N−4}), whichever is larger, so that a power
    whose last coefficient vanishes by symmetry is not taken as resolved."""
    c = np.abs(_TO_COEFFICIENTS[[-1, -2, -4]] @ P)
    if not c.size:
        return 0.0
    with np.errstate(divide="ignore", invalid="ignore"):
        decay = np.where(c[2] > 0.0, c[1] * c[1] / c[2], c[1])
    return float(max(np.max(c[0]), np.max(np.minimum(decay, c[1]))))
