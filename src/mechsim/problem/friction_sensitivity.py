"""Sensitivities of a motion through dry friction in joints (`mechsim.problem.friction`).

Within a piece of a run every joint keeps its mode and the motion obeys

    M q̈ + Φ_qᵀ λ = Q + Σ_j f_j g_j,    Φ_q q̈ = γ,

with each active element's own equation: a sliding joint's f_j = −σ μ(|ṡ_j|) L_j(λ)
(L_j = ρ (‖F_j‖ + preload), ρ the pin's radius or 1 for a guide, F_j the force its rows
of λ apply; a guide of length ℓ whose couple wins, 2|M_j|/ℓ + preload, M_j the moment
about the joint's point), a held joint's s̈_j = g_j q̈ + vᵀ H_j v = 0 (g_j = ∂s_j/∂q, H_j = ∂²s_j/∂q²).
Differentiated in a Parameter k along the sensitivities (q_k, v_k), with x_j = ∂f_j/∂k:

    M q̈_k + Φ_qᵀ λ_k = F + Σ_j f_j H_j q_k + Σ_j x_j g_j,    Φ_q q̈_k = g,
    sliding:  x_j = −σ (μ' σ ṡ_j,k L_j + μ L_j,k + μ_k L_j),
              L_j,k = ρ e_j·F_j,k + ρ_k (‖F_j‖ + preload) + ρ preload_k,
    held:     g_j q̈_k + (H_j q_k)·q̈ + 2 vᵀ H_j v_k + ∂³s_j[v, v, q_k] = 0,

where F, g are the right sides without friction (`MotionEquations`), ṡ_j,k = g_j v_k +
(H_j q_k)·v, e_j = F_j/‖F_j‖, e_j·F_j,k = −e_j·(Φ_qᵀ λ_k) on the body's x, y over the
joint's rows (those rows' gradients there change only across F: a pin's are constant, a
guide's normal turns at unit length), and μ_k, ρ_k, preload_k the friction's own numbers'
derivatives (Parameters). The couple's change is M_k = M_R,k − r_k × F − r × F_k with the
whole wrench's change −(Φ_qᵀ λ_k + R3_q q_k + R3_p p_k) on the body's x, y, θ (R3 = Φ_qᵀ λ
of the joint's own multipliers: the generated derivatives) and r = P − R turning with
the body. The joints'
derivatives come from their coordinates' second-order jets in dual numbers
(`mechsim.problem.geometry.joint_path_partials`). q̈_k and λ_k are affine in x (one solve
for F and one per active joint's g_j, the factor of the motion's), so x solves a small
linear system with a column per Parameter.

At a switch the state is continuous and the acceleration jumps: the switch's time moves
with k by dt_s/dk = −e_k/ė of its event function e (a sliding joint's σ ṡ, a held one's
μ_s L − |f|, both differentiated by the same linearisation, ė along the motion (v, q̈)),
and v_k⁺ = v_k⁻ + (q̈⁻ − q̈⁺) dt_s/dk (q_k continuous): `switch_jump`. A stop holding
its joint is a held element of the same kind (its force the multiplier of s̈ = 0), let go
where its push sign·f reaches zero.

Rigid bodies; a joint whose coordinate moves with a differentiated Parameter, or a
guide with a `length` whose body_b is the ground, are refused before the run
(`refusal`).
"""

from __future__ import annotations

import numpy as np

from .friction import FREE, STUCK
from .geometry import joint_curvature, joint_path_partials, joint_path_rates, joint_point

# The direction along the motion has no Parameter: a name no Parameter has.
ALONG_MOTION = "\0along the motion"


def refusal(mech, problem, names) -> str:
    """Why the sensitivities `names` cannot be carried through `mech`'s friction ("" where
    they can): a flexible mechanism, a guide with a `length` on the ground as its body_b,
    or a friction joint's coordinate that moves with a differentiated Parameter."""
    if not mech.frictions:
        return ""
    if problem.flexible:
        return (f"sensitivities through friction '{mech.frictions[0].name}' are carried "
                "for rigid bodies only")
    for fr in mech.frictions:
        if fr.length is not None and fr.joint.body_b is mech.ground:
            return (f"sensitivities through friction '{fr.name}' with a `length` on a guide "
                    "whose body_b is the ground are not carried (make the moving body "
                    "its body_b)")
        moved = fr.joint.moved_by(names)
        if moved is not None:
            return (f"the coordinate of joint '{fr.joint.name}', where friction '{fr.name}' "
                    f"rubs, moves with Parameter '{moved}': sensitivities through it "
                    "are not carried")
    return ""


class FrictionLinearization:
    """The friction terms of `equations` (a `MotionEquations` whose problem's friction
    model has the piece's modes) at one state: `accelerations` solves the differentiated
    equations of motion with them (module docstring)."""

    def __init__(self, equations):
        self.eq = equations
        self.problem = equations.problem
        self.model = self.problem.friction

    def accelerations(self, solve, t, q, v, a, lam, J, state, Sq, Sv, F, g):
        """(q̈_k (n, K), x (A, K), δL (A, K), active, Σ ∂(f_j g_j)/∂k (n, K)):
        `solve(F, g) -> (q̈_k, λ_k)` the motion's factor; `state` the `FrictionState` at
        (t, q, v); x the friction forces' and δL the loads' changes of the active
        elements `active` (indices), the last their generalized force's."""
        model, K = self.model, Sq.shape[1]
        active = [j for j in range(len(model.elements)) if state.modes[j] != FREE]
        if not active:
            return solve(F, g)[0], np.zeros((0, K)), np.zeros((0, K)), active, \
                np.zeros_like(Sq)
        bent = np.zeros_like(Sq)
        for j in active:
            if state.forces[j] != 0.0 and not _linear(model.elements[j]):
                bent += state.forces[j] * joint_curvature(model.elements[j].geometry, q, Sq)
        ak0, lk0 = solve(F + bent, g)
        size = len(active)
        Aa, Al = solve(state.gradients[active].T, np.zeros((J.shape[0], size)))
        D, c = np.zeros((size, size)), np.zeros((size, K))
        dL0, dLx = np.zeros((size, K)), np.zeros((size, size))
        W = self.problem.inverse_mass_diagonal
        for i, j in enumerate(active):
            element = model.elements[j]
            gj = state.gradients[j]
            if _linear(element):
                rate_k, rest_k = gj @ Sv, np.zeros(K)
            else:
                rate_k, rest_k = joint_path_partials(element.geometry, q, v, a, Sq, Sv)
            if element.kind == "friction":
                dL0[i], dLx[i] = self._load(element, t, q, lam, J, lk0, Al, Sq)
            if state.modes[j] == STUCK:
                scale = 1.0 / float(gj @ (W * gj))
                D[i], c[i] = scale * (gj @ Aa), scale * (gj @ ak0 + rest_k)
                continue
            fr, sigma = element.friction, float(state.modes[j])
            mu, slope, dmu = fr.coefficient_partials(abs(state.rates[j]), self.eq.names)
            L = state.loads[j]
            D[i] = sigma * mu * dLx[i]
            D[i, i] += 1.0
            c[i] = sigma * (slope * sigma * rate_k * L + mu * dL0[i] + dmu * L)
        x = np.linalg.solve(D, -c)
        return ak0 + Aa @ x, x, dL0 + dLx @ x, active, bent + state.gradients[active].T @ x

    def _load(self, element, t, q, lam, J, lk0, Al, Sq):
        """(δL without x (K,), δL's coefficients of x (A,)) of a friction element's load."""
        fr, geometry, rows = element.friction, element.geometry, list(element.rows)
        start = geometry.start_b if geometry.start_b is not None else geometry.start_a
        frame = slice(start, start + 3)
        Jr = J[rows][:, frame]
        wrench = -(Jr.T @ lam[rows])                 # on the body's x, y, θ
        force = wrench[:2]
        size = float(np.hypot(*force))
        d0, dx = -(Jr.T @ lk0[rows]), -(Jr.T @ Al[rows])      # (3, K), (3, A)
        names = self.eq.names
        if fr.length is not None:
            # The couple about the joint's point P on body_b: M = M_R − r × F, r = P − R.
            own = np.zeros(len(lam))
            own[rows] = lam[rows]
            r3q, r3p = self.eq.module.multiplier_terms(q, own, t, self.problem.p)
            d0 = d0 - (r3q @ Sq + r3p @ self.eq.P)[frame]
            r = joint_point(geometry, q)[0] - q[start:start + 2]
            couple = wrench[2] - _cross(r, force)
            if 2.0 * abs(couple) / fr.length > size:
                turn = np.outer([-r[1], r[0]], Sq[start + 2])            # δr (2, K)
                dM0 = d0[2] - _cross(turn, force[:, None]) - _cross(r[:, None], d0[:2])
                dMx = dx[2] - _cross(r[:, None], dx[:2])
                scale = 2.0 * np.sign(couple) / fr.length
                return (scale * dM0 - 2.0 * abs(couple) / fr.length ** 2 *
                        fr.partials("length", names) + fr.partials("preload", names),
                        scale * dMx)
        unit = force / size if size > 0.0 else np.zeros(2)
        rho = 1.0 if fr.radius is None else fr.radius
        own_numbers = fr.preload * self._radius_partials(fr, names) + \
            rho * fr.partials("preload", names)
        if fr.radius is not None:
            own_numbers = own_numbers + size * self._radius_partials(fr, names)
        return rho * (unit @ d0[:2]) + own_numbers, rho * (unit @ dx[:2])

    @staticmethod
    def _radius_partials(fr, names):
        return fr.partials("radius", names) if fr.radius is not None else \
            np.zeros(len(names))


def switch_jump(before, after, k, t, q, v_before, v_after, Sq, Sv, push=None):
    """(v_k⁺, dt_s/dk (K,)) across element k's switch at t from the modes of `before` to
    those of `after` (each a `MotionEquations` of the piece's problem): its time's
    sensitivity from its event function (module docstring) and the saltation of v_k.
    `push`: for a stop letting its joint go, the sign of its push (the event sign·f = 0).
    None where a held joint's event depends on time explicitly (a driver, a load given
    as a function), which is not differentiated."""
    problem = before.problem
    element = problem.friction.elements[k]
    a_before = accelerations(problem, t, q, v_before)
    a_after = accelerations(after.problem, t, q, v_after)
    state = problem.friction_state(t, q, v_before)
    if state.modes[k] == STUCK:
        if problem.rheonomic_rows or any(callable(x.value) for x in problem.load_model.loads):
            return None

        def event(equations, dq, dv):
            x, dL, active, _ = equations.friction_partials(t, q, v_before, dq, dv)
            i = active.index(k)
            if push is not None:
                return push * x[i]
            fr = element.friction
            return fr.static_partials(equations.names) * state.loads[k] + \
                fr.mu_static * dL[i] - np.sign(state.forces[k]) * x[i]
        change = event(before, Sq, Sv)
        rate = event(before.along_motion(), v_before[:, None], a_before[:, None])[0]
    else:
        sigma = float(state.modes[k])
        change = sigma * joint_path_partials(element.geometry, q, v_before, a_before, Sq,
                                             Sv)[0]
        rate = sigma * (state.gradients[k] @ a_before +
                        joint_path_rates(element.geometry, q, v_before)[2][0])
    dt = -change / rate
    return Sv + np.outer(a_before - a_after, dt), dt


def accelerations(problem, t, q, v):
    """q̈ of `problem` (its joints' friction and stops in its modes) at (t, q, v)."""
    J, gamma = problem.dynamics_terms(q, v, t)
    return problem.accelerations(J, problem.forces(t, q, v), gamma, q)[0]


def _linear(element) -> bool:
    """Is the element's joint coordinate linear in q (a revolute's θ_b − θ_a of rigid
    bodies: no curvature, no third derivatives)?"""
    return element.geometry.joint.kind == "revolute"


def _cross(a, b):
    """a × b of 2-vectors (along the first axis)."""
    return a[0] * b[1] - a[1] * b[0]
