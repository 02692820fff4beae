"""Singular configurations of Φ_q, measured directly.

The measure is s = σ_min / σ_max of the mass-scaled Jacobian J̃ = Φ_q M^{-1/2} (over its m
rows, so a mechanism whose rank drops reads 0), with its rate ṡ from the singular vectors:
σ̇ = uᵀ J̃̇ v, J̃̇ by one extra Jacobian along the velocity. Unlike the paper's symptoms
(frequent re-partitioning, energy fluctuation, collapsing steps) it sees a singularity coming
before any harm is done, and it names the joints involved: the rows that carry the left
singular vector of σ_min.

A passage is recorded while s < `enter` until s > `leave`. Large steps can jump over the
whole band, so the monitor also models s over each step by the cubic Hermite interpolant of
(s, ṡ) at its ends; a modelled minimum below `enter` is checked on the integrator's dense
output and recorded as a passage inside the step.

For the seed's parallelogram s falls below 0.02 about 0.03 s before each passage (its
minimum, 7e-5, at the second passage), so `enter = 0.02`, `leave = 0.04` (hysteresis).
"""

from __future__ import annotations

import numpy as np

from ..results import SingularPassage


class SingularityMonitor:
    def __init__(self, problem, enter: float = 0.02, leave: float = 0.04):
        if not 0.0 < enter < leave:
            raise ValueError(f"singularity thresholds need 0 < enter < leave, got {enter}, {leave}")
        self.problem = problem
        self.enter, self.leave = enter, leave
        self.scale = 1.0 / np.sqrt(problem.mass_diagonal)
        self.passages: list[SingularPassage] = []
        self._open = None            # [t_start, t_min, s_min, joints] while inside
        self.last, self.rate = 1.0, 0.0
        self._prev = None            # (t, s, ṡ) at the previous observation

    def measure(self, q, t, v=None):
        """(s, ṡ, left singular vector of σ_min); ṡ = 0 when v is None."""
        J = self.problem.phi_q(q, t) * self.scale
        m = J.shape[0]
        if m == 0:
            return 1.0, 0.0, np.zeros(0)
        U, sig, Vt = np.linalg.svd(J, full_matrices=False)
        k = m - 1
        if k >= sig.size or sig[0] <= 0.0:
            return 0.0, 0.0, U[:, -1]
        s = float(sig[k] / sig[0])
        rate = 0.0
        if v is not None:
            speed = float(np.max(np.abs(v)))
            if speed > 0.0:
                eps = 1e-7 / speed
                dJ = (self.problem.phi_q(q + eps * v, t + eps) * self.scale - J) / eps
                d_min = U[:, k] @ dJ @ Vt[k]
                d_max = U[:, 0] @ dJ @ Vt[0]
                rate = float((d_min * sig[0] - sig[k] * d_max) / sig[0] ** 2)
        return s, rate, U[:, k]

    def joints_of(self, u) -> tuple[str, ...]:
        owners = self.problem.constraint_owners
        big = np.flatnonzero(np.abs(u) > 0.2 * np.max(np.abs(u), initial=0.0))
        return tuple(dict.fromkeys(owners[i] for i in big))

    def predicted_within(self, h: float) -> bool:
        """Will s fall below `enter` within the next `h` seconds at its present rate?"""
        return self.last < self.enter or (self.rate < 0.0 and self.last + self.rate * h < self.enter)

    def observe(self, t, q, v=None, state_at=None) -> float:
        """Take the state at an accepted step. `state_at(t) -> (q, v)` evaluates the step's
        dense output, used to confirm a minimum hidden inside the step."""
        s, rate, u = self.measure(q, t, v)
        prev, self._prev = self._prev, (t, s, rate)
        self.last, self.rate = s, rate
        if self._open is None and prev is not None and s >= self.enter and state_at is not None:
            self._hidden_minimum(prev, (t, s, rate), state_at)
        if self._open is None and s < self.enter:
            self._open = [t, t, s, self.joints_of(u)]
        elif self._open is not None:
            if s < self._open[2]:
                self._open[1:4] = [t, s, self.joints_of(u)]
            if s > self.leave:
                self.close(t)
        return s

    def _hidden_minimum(self, a, b, state_at):
        t0, s0, d0 = a
        t1, s1, d1 = b
        h = t1 - t0
        if not (h > 0.0 and d0 < 0.0 < d1):
            return
        x = np.linspace(0.0, 1.0, 41)
        h00, h10 = 2 * x**3 - 3 * x**2 + 1, x**3 - 2 * x**2 + x
        h01, h11 = -2 * x**3 + 3 * x**2, x**3 - x**2
        model = h00 * s0 + h10 * h * d0 + h01 * s1 + h11 * h * d1
        i = int(np.argmin(model))
        if model[i] >= self.enter:
            return
        tm = t0 + x[i] * h
        qm, _ = state_at(tm)
        sm, _, um = self.measure(qm, tm)
        if sm < self.enter:
            below = x[model < self.enter]
            self.passages.append(SingularPassage(t0 + below[0] * h, t0 + below[-1] * h, sm,
                                                 self.joints_of(um), tm))

    @property
    def inside(self) -> bool:
        return self._open is not None

    def close(self, t):
        if self._open is not None:
            t0, tmin, smin, joints = self._open
            self.passages.append(SingularPassage(t0, t, smin, joints, tmin))
            self._open = None
