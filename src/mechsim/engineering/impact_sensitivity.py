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


def impact_jump(problem, equations, geometry, restitution, t, q, v_before, v_after,
                Sq, Sv):
    """(q_k⁺, v_k⁺, dt_e/dk) across the impact at t (module docstring): `geometry` the
    stop's joint, `restitution` e (0 where the joint came to rest), v_before/v_after the
    velocities on either side and (Sq, Sv) the sensitivities before it, each (n, K)."""
    n = problem.n
    module, P, p = equations.module, equations.P, problem.p
    M = problem.mass_diagonal
    Mk = equations.forces.Mk                                 # ∂M/∂k, (n, K)
    J = sparse.dense(problem.phi_q(q, t)).reshape(-1, n)
    G = joint_gradient(geometry, q)
    H = _hessian(geometry, q)
    A = np.vstack([J, G[None]])
    m = J.shape[0]
    eta = np.linalg.lstsq(A.T, M * (v_before - v_after), rcond=None)[0]
    mu, nu = eta[:m], eta[m]
    r1q, r1p = module.sensitivity_terms(q, v_after, np.zeros(n), t, p)[1:3]
    r3q, r3p = module.multiplier_terms(q, mu, t, p) if m else \
        (np.zeros((n, n)), np.zeros((n, len(p))))
    _, gamma = problem.dynamics_terms(q, v_after, t)
    a_before = _accelerations(problem, t, q, v_before)
    a_after = _accelerations(problem, t, q, v_after)
    saddle = np.block([[np.diag(M), A.T], [A, np.zeros((m + 1, m + 1))]])

    def solve(top, mid, bottom):
        rhs = np.vstack([top, mid, bottom])
        return np.linalg.lstsq(saddle, rhs, rcond=None)[0][:n]

    e = restitution
    # in the parameters' directions (q_k⁻, v_k⁻, p_k)
    HSq = H @ Sq
    Lk = solve(M[:, None] * Sv + Mk * (v_before - v_after)[:, None] - r3q @ Sq - r3p @ P
               - nu * HSq,
               -(r1q @ Sq + r1p @ P),
               (-e * (G @ Sv + v_before @ HSq) - v_after @ HSq)[None])
    # along the motion before the impact (v⁻, q̈⁻, 1)
    Hv = H @ v_before
    Lt = solve((M * a_before - r3q @ v_before - nu * Hv)[:, None],
               (np.asarray(gamma, float) - r1q @ (v_before - v_after))[:, None],
               np.array([[-e * (G @ a_before + v_before @ Hv) - v_after @ Hv]]))[:, 0]
    dt = -(G @ Sq) / float(G @ v_before)
    return (Sq + np.outer(v_before - v_after, dt), Lk + np.outer(Lt - a_after, dt), dt)


def _accelerations(problem, t, q, v):
    _, J, _, gamma = problem.terms(q, v, t)
    return problem.accelerations(J, problem.forces(t, q, v), gamma, q)[0]
