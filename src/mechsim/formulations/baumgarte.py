"""Index-1 augmented formulation with Baumgarte stabilisation (the classic baseline).

    [M  Φ_qᵀ] [q̈]   [Q                          ]
    [Φ_q  0 ] [λ] = [γ − 2α(Φ_q q̇ + Φ_t) − β² Φ]

The state is y = [q; v]. Baumgarte's feedback damps constraint drift but does not remove it;
with `projection=True` (default) positions and velocities are projected back onto the
constraint manifold after any step that leaves ‖Φ‖∞ above `projection_tol` (a restart of the
integrator, so it is done only when needed rather than every step).
"""

from __future__ import annotations

import numpy as np

from .base import Formulation


class Baumgarte(Formulation):
    name = "baumgarte"
    default_integrator = "DOP853"
    options = {"alpha": 5.0, "beta": 5.0, "projection": True, "projection_tol": None}

    def __init__(self, problem, rtol, atol, **options):
        super().__init__(problem, rtol, atol, **options)
        if self.projection_tol is None:
            # One step's own error is of order rtol; a threshold below it would restart the
            # integrator after every step (multistep methods then never leave their start-up).
            self.projection_tol = max(10.0 * rtol, 100.0 * atol)
        self.n = problem.n

    def initial_state(self, t, q, v):
        return np.concatenate([q, v])

    def state(self, t, y):
        return y[:self.n], y[self.n:]

    def rhs(self, t, y):
        prob, n = self.problem, self.n
        q, v = y[:n], y[n:]
        prob.counters.rhs += 1
        phi, J, phi_t, gamma = prob.terms(q, v, t)
        c = gamma - 2.0 * self.alpha * (J @ v + phi_t) - self.beta**2 * phi
        qdd, _ = prob.accelerations(J, prob.forces(t, q, v), c)
        return np.concatenate([v, qdd])

    def after_step(self, t, y):
        if not self.projection:
            return None
        prob, n = self.problem, self.n
        q, v = y[:n], y[n:]
        phi = prob.phi(q, t)
        if phi.size == 0 or np.max(np.abs(phi)) <= self.projection_tol:
            return None
        q, _, _ = prob.project_positions(q, t, tol=0.01 * self.projection_tol)
        v = prob.project_velocities(q, v, t)
        return np.concatenate([q, v])
