"""The sensitivities of a motion across an impact on a stop (`mechsim.engineering.impacts`).

An impact at t_e, where the stop's distance g = ±(s(q) − limit) reaches zero, maps the
state y⁻ = (q, v⁻) to y⁺ = (q, v⁺ = h(q, v⁻, t; p)), Newton's law through the constrained
mass matrix:

    M v⁺ + Φ_qᵀ μ + Gᵀ ν = M v⁻,    Φ_q v⁺ + Φ_t = 0,    G v⁺ = −e G v⁻

(G = ∂s/∂q; e = 0 where the joint comes to rest). The impact's time moves with a design
parameter k, dt_e/dk = −G q_k⁻ / (G v⁻), and a sensitivity at a fixed time after it
is

    S⁺ = h_y S⁻ + h_k + (h_y f⁻ + h_t − f⁺) dt_e/dk

(the saltation of the sensitivities; f = ẏ = (v, q̈) on each side). q⁺ = q⁻ gives q_k⁺ =
q_k⁻ + (v⁻ − v⁺) dt_e/dk; v_k⁺ comes from the impact's equations differentiated in the
direction (q_k⁻, v_k⁻, p_k) and along the motion (v⁻, q̈⁻, 1), one saddle-point system
with the multipliers (μ, ν) of the impact held: R1 = Φ_q v + Φ_t and R3 = Φ_qᵀ μ
differentiated by the model's generated derivatives (`mechsim.symbolic.sensitivity`), the
stop joint's coordinate to second order by its jets, and along the motion R1's time
derivative from γ: Φ_qt v⁺ + Φ_tt = −γ(q, v⁺, t) − R1_q(v⁺) v⁺. Rigid bodies (a constant,
diagonal M, whose derivative in k is the masses'); the stop's joint coordinate must not
depend on the differentiated Parameters (the facade refuses it otherwise).
"""

from __future__ import annotations

import numpy as np

from ..linalg import sparse
from ..problem.geometry import joint_gradient, joint_path_rates


def _hessian(geometry, q) -> np.ndarray:
    """∂²s/∂q² of the joint's coordinate at q (n, n), from its jets' quadratic forms:
    H_ii = e_iᵀ H e_i, H_ij = ((e_i + e_j)ᵀ H (e_i + e_j) − H_ii − H_jj) / 2."""
    n = q.size
    i, j = np.triu_indices(n)
    X = np.zeros((i.size, n))
    X[np.arange(i.size), i] = 1.0
    X[np.arange(i.size), j] = 1.0
    form = joint_path_rates(geometry, np.broadcast_to(q, X.shape), X)[2]
    diagonal = form[i == j]
    H = np.zeros((n, n))
    H[i, j] = 0.5 * (form - diagonal[i] - diagonal[j])
    H[i, j] = np.where(i == j, diagonal[i], H[i, j])
    return H + np.triu(H, 1).T


class VelocityProjection:
    """The velocities v⁺ nearest v⁻ in the mass metric with Φ_q v⁺ + Φ_t = 0 and, for each
    joint row (geometry, e), G v⁺ = −e G v⁻ (an impact's Newton law) or, with e = 0 and
    a constant target, the joint's rate held (`Mechanism.set_speed`), linearised at the
    state (t, q, v⁻ → v⁺): `partials` in the parameters' directions, `along_motion` along
    the motion before it (module docstring). Rigid bodies: M constant and diagonal."""

    def __init__(self, problem, equations, joints, t, q, v_before, v_after):
        n, self.n = problem.n, problem.n
        self.problem, self.t, self.q = problem, t, q
        self.v_before, self.v_after = v_before, v_after
        self.module, self.P, self.p = equations.module, equations.P, problem.p
        self.M, self.Mk = problem.mass_diagonal, equations.forces.Mk     # M, ∂M/∂k (n, K)
        self.e = np.array([e for _, e in joints], float)
        J = sparse.dense(problem.phi_q(q, t)).reshape(-1, n)
        self.G = np.array([joint_gradient(g, q) for g, _ in joints]).reshape(-1, n)
        self.H = [_hessian(g, q) for g, _ in joints]
        A = np.vstack([J, self.G])
        m, k = J.shape[0], self.G.shape[0]
        eta = np.linalg.lstsq(A.T, self.M * (v_before - v_after), rcond=None)[0]
        mu, self.nu = eta[:m], eta[m:]
        self.r1q, self.r1p = self.module.sensitivity_terms(q, v_after, np.zeros(n), t,
                                                           self.p)[1:3]
        self.r3q, self.r3p = self.module.multiplier_terms(q, mu, t, self.p) if m else \
            (np.zeros((n, n)), np.zeros((n, len(self.p))))
        self.saddle = np.block([[np.diag(self.M), A.T], [A, np.zeros((m + k, m + k))]])

    def _solve(self, dq, dv, top, mid):
        """v⁺'s change for the changes dq, dv (of q, v⁻), given the M rows' and Φ rows'
        other terms (`top`, `mid`), the joint rows' from dq and dv."""
        HS = [H @ dq for H in self.H]
        top = top - sum(nu * HSj for nu, HSj in zip(self.nu, HS))
        bottom = np.array([-e * (G @ dv + self.v_before @ HSj) - self.v_after @ HSj
                           for e, G, HSj in zip(self.e, self.G, HS)]).reshape(-1, dq.shape[1])
        rhs = np.vstack([top, mid, bottom])
        return np.linalg.lstsq(self.saddle, rhs, rcond=None)[0][:self.n]

    def partials(self, Sq, Sv):
        """∂v⁺/∂k (n, K) for the sensitivities (Sq, Sv) of q and v⁻."""
        top = self.M[:, None] * Sv + self.Mk * (self.v_before - self.v_after)[:, None] \
            - self.r3q @ Sq - self.r3p @ self.P
        return self._solve(Sq, Sv, top, -(self.r1q @ Sq + self.r1p @ self.P))

    def along_motion(self, a_before):
        """d v⁺/dt along the motion before (v⁻, q̈⁻, 1); R1's time derivative from γ."""
        _, gamma = self.problem.dynamics_terms(self.q, self.v_after, self.t)
        vb, va = self.v_before, self.v_after
        return self._solve(vb[:, None], a_before[:, None],
                           (self.M * a_before - self.r3q @ vb)[:, None],
                           (np.asarray(gamma, float) - self.r1q @ (vb - va))[:, None])[:, 0]


def impact_jump(problem, equations, geometry, restitution, t, q, v_before, v_after,
                Sq, Sv, after=None):
    """(q_k⁺, v_k⁺, dt_e/dk) across the impact at t (module docstring): `geometry` the
    stop's joint, `restitution` e (0 where the joint came to rest), v_before/v_after the
    velocities on either side and (Sq, Sv) the sensitivities before it, each (n, K).
    `after`: the problem after the impact where it differs (its joints' friction in the
    modes the impulse left them), else `problem`."""
    law = VelocityProjection(problem, equations, [(geometry, restitution)], t, q, v_before,
                             v_after)
    a_before = _accelerations(problem, t, q, v_before)
    a_after = _accelerations(problem if after is None else after, t, q, v_after)
    G = law.G[0]
    dt = -(G @ Sq) / float(G @ v_before)
    return (Sq + np.outer(v_before - v_after, dt),
            law.partials(Sq, Sv) + np.outer(law.along_motion(a_before) - a_after, dt), dt)


def _accelerations(problem, t, q, v):
    _, J, _, gamma = problem.terms(q, v, t)
    return problem.accelerations(J, problem.forces(t, q, v), gamma, q)[0]
