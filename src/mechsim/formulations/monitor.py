"""Singular configurations of Φ_q, measured directly.

The measure is s = σ_min / σ_max of the mass-scaled Jacobian Φ_q M^{-1/2} (over its m rows,
so a mechanism whose rank drops reads 0). Unlike the paper's symptoms (frequent
re-partitioning, energy fluctuation, collapsing steps) it sees a singularity coming before
any harm is done, and it names the joints involved: the rows that carry the left singular
vector of σ_min.

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
        self.last = 1.0

    def measure(self, q, t) -> tuple[float, np.ndarray]:
        """(s, left singular vector of σ_min)."""
        J = self.problem.phi_q(q, t) * self.scale
        if J.shape[0] == 0:
            return 1.0, np.zeros(0)
        U, s, _ = np.linalg.svd(J, full_matrices=False)
        k = J.shape[0] - 1
        smin = s[k] if k < s.size else 0.0
        return (float(smin / s[0]) if s[0] > 0 else 0.0), U[:, min(k, U.shape[1] - 1)]

    def joints_of(self, u) -> tuple[str, ...]:
        owners = self.problem.constraint_owners
        big = np.flatnonzero(np.abs(u) > 0.2 * np.max(np.abs(u), initial=0.0))
        return tuple(dict.fromkeys(owners[i] for i in big))

    def observe(self, t, q) -> float:
        s, u = self.measure(q, t)
        self.last = s
        if self._open is None and s < self.enter:
            self._open = [t, t, s, self.joints_of(u)]
        elif self._open is not None:
            if s < self._open[2]:
                self._open[1:4] = [t, s, self.joints_of(u)]
            if s > self.leave:
                self.close(t)
        return s

    @property
    def inside(self) -> bool:
        return self._open is not None

    def close(self, t):
        if self._open is not None:
            t0, tmin, smin, joints = self._open
            self.passages.append(SingularPassage(t0, t, smin, joints, tmin))
            self._open = None
