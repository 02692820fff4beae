"""Index-1 augmented formulation with Baumgarte stabilisation (the classic baseline).

    [M  Φ_qᵀ] [q̈]   [Q                          ]
    [Φ_q  0 ] [λ] = [γ − 2α(Φ_q q̇ + Φ_t) − β² Φ]

Baumgarte's feedback damps constraint drift but does not remove it; the projection of
`FullCoordinates` removes what is left. At a singular configuration the augmented matrix is
singular: this formulation may stall or jump branch there (the reason for "projection" and
"hybrid").
"""

from __future__ import annotations

from ..options import Option
from .full import FullCoordinates


class Baumgarte(FullCoordinates):
    name = "baumgarte"
    default_integrator = "DOP853"
    options = {**FullCoordinates.options, "alpha": Option.real(5.0, low=0.0),
               "beta": Option.real(5.0, low=0.0)}

    def accelerations(self, t, q, v):
        prob = self.problem
        phi, J, phi_t, gamma = prob.terms(q, v, t)
        c = gamma - 2.0 * self.alpha * (J @ v + phi_t) - self.beta**2 * phi
        return prob.accelerations(J, prob.forces(t, q, v), c, q)[0]
