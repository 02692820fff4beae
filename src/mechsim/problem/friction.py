"""Dry friction in joints, solved together with the reactions that load it.

A joint k with friction (`mechsim.model.friction.Friction`) receives a force f_k along its
coordinate s_k (a torque for a revolute, a force for a prismatic), the generalized force
f_k ∂s_k/∂q. The equations of motion become

    M q̈ + Φ_qᵀ λ = Q + Σ_k f_k g_k,    Φ_q q̈ = γ,    g_k = ∂s_k/∂q,

so q̈ and λ are affine in f: q̈ = a₀ + Σ a_k f_k, λ = λ₀ + Σ Λ_k f_k (one solve of the
saddle-point system for Q and one for each g_k). Each f_k is given by its joint's state:

- slipping in direction σ = ±1: f_k = −σ μ(ṡ_k) L_k(λ), L_k the joint's load (the pin's
  ‖F‖ times its radius, a guide's normal load), each a norm of the wrench its rows of λ
  apply (`mechsim.engineering.geometry.joint_wrench`, linear in λ);
- stuck: whatever holds it, s̈_k = g_k q̈ + vᵀ(∂²s_k/∂q²)v = 0 (linear in f).

Newton's method on f solves all of them at once, with the exact Jacobian (the norms'
gradients); its residual is the implicit relation itself, not a lagged reaction. A
Jacobian that cannot be inverted (a stuck joint whose motion other constraints prescribe,
or friction feeding back on its own load with a gain of one or more: a friction lock)
raises `FrictionError`, which ends a run with its partial result.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..engineering.geometry import joint_gradient, joint_path_rates, joint_wrench

# What an element is doing: sliding forwards or backwards, or held at zero rate.
FORWARD, BACKWARD, STUCK = 1, -1, 0
# Newton on the friction forces stops at this relative change (round-off in a few steps).
TOLERANCE = 1e-13
MAX_ITERATIONS = 30


class FrictionError(RuntimeError):
    """The friction forces have no solution at a state (see the module docstring)."""


@dataclass(frozen=True)
class FrictionElement:
    """One joint's friction: the model element (`Friction`: coefficients, radius, length,
    preload), its joint's geometry and the rows of Φ its joint owns."""
    friction: object
    geometry: object
    rows: tuple

    @property
    def name(self) -> str:
        return self.friction.name

    def load(self, F, M):
        """(L, ∂L/∂F (2,), ∂L/∂M) of the joint force F (2,) and moment M: what μ multiplies."""
        fr = self.friction
        size = float(np.hypot(F[0], F[1]))
        unit = F / size if size > 0.0 else np.zeros(2)
        if fr.radius is not None:                          # a pin: μ r (‖F‖ + preload)
            return fr.radius * (size + fr.preload), fr.radius * unit, 0.0
        if fr.length is not None and 2.0 * abs(M) / fr.length > size:
            return 2.0 * abs(M) / fr.length + fr.preload, np.zeros(2), \
                2.0 * np.sign(M) / fr.length
        return size + fr.preload, unit, 0.0


@dataclass(frozen=True)
class FrictionState:
    """The solution at one state: the forces f (K,) along each joint's coordinate, their
    loads L (K,) (f = −σ μ L while slipping), the joints' rates ṡ (K,), the directions
    g_k = ∂s_k/∂q (K, n) and the modes used (K,)."""
    forces: np.ndarray
    loads: np.ndarray
    rates: np.ndarray
    gradients: np.ndarray
    modes: np.ndarray

    def generalized(self) -> np.ndarray:
        """Σ f_k g_k, shape (n,)."""
        return self.forces @ self.gradients


@dataclass(frozen=True)
class FrictionModel:
    """The friction elements of a problem and what each is doing. `modes`: None where each
    slides the way its joint moves (no force at zero rate: a kinematic analysis, a state
    without a history); else an array (K,) of `FORWARD`, `BACKWARD`, `STUCK` for a run's
    piece; `schedule`: ((t_end, modes), …) of a run's pieces in order, where a state at
    time t takes the first piece that ends at or after t (a result joined from them)."""
    elements: tuple
    modes: np.ndarray | None = None
    schedule: tuple = ()

    def with_modes(self, modes) -> "FrictionModel":
        return replace(self, modes=None if modes is None else np.array(modes, int), schedule=())

    def with_schedule(self, schedule) -> "FrictionModel":
        return replace(self, modes=None, schedule=tuple(schedule))

    def modes_at(self, t, rates) -> np.ndarray:
        for t_end, modes in self.schedule:
            if t <= t_end:
                return np.asarray(modes, int)
        if self.modes is not None:
            return self.modes
        return np.sign(rates).astype(int)

    @property
    def channels(self) -> list[str]:
        return [f"friction '{e.name}'" for e in self.elements]

    def solve(self, problem, t, q, v, Q, modes=None) -> FrictionState:
        """The friction forces at the state (t, q, v) under the applied forces Q (n,)
        (`modes` overrides the model's). A joint following its rate's sign (modes None)
        at zero rate carries none."""
        K = len(self.elements)
        G = np.array([joint_gradient(e.geometry, q) for e in self.elements])
        rates = G @ v
        explicit = modes is not None or self.modes is not None or bool(self.schedule)
        if modes is None:
            modes = self.modes_at(t, rates)
        active = [k for k in range(K) if explicit or modes[k] != 0]
        f = np.zeros(K)
        loads = np.zeros(K)
        if not active:
            return FrictionState(f, loads, rates, G, np.asarray(modes, int))
        J, gamma = problem.dynamics_terms(q, v, t)
        a0, lam0 = problem.accelerations(J, Q, gamma, q)
        zero = np.zeros_like(gamma)
        A, Lam = [], []
        for k in active:
            a, lam = problem.accelerations(J, G[k], zero, q)
            A.append(a)
            Lam.append(lam)
        A, Lam = np.array(A).T, np.array(Lam).T                  # (n, a), (m, a)
        linear = {}
        for k in active:
            e = self.elements[k]
            rows = list(e.rows)
            lam = np.column_stack([lam0[rows], Lam[rows]]).T      # (1 + a, rows)
            F, M = joint_wrench(e.geometry, np.repeat(q[None], len(lam), axis=0), lam)
            linear[k] = (F[0], F[1:], M[0], M[1:])
        held = {k: joint_path_rates(self.elements[k].geometry, q, v)[2][0]
                for k in active if modes[k] == STUCK}
        x = np.zeros(len(active))
        for _ in range(MAX_ITERATIONS):
            r = np.empty(len(active))
            D = np.zeros((len(active), len(active)))
            for i, k in enumerate(active):
                if modes[k] == STUCK:
                    r[i] = G[k] @ (a0 + A @ x) + held[k]
                    D[i] = G[k] @ A
                    continue
                F0, DF, M0, DM = linear[k]
                L, dF, dM = self.elements[k].load(F0 + x @ DF, M0 + x @ DM)
                mu = self.elements[k].friction.coefficient(abs(rates[k]))
                r[i] = x[i] + modes[k] * mu * L
                D[i] = modes[k] * mu * (DF @ dF + DM * dM)
                D[i, i] += 1.0
                loads[k] = L
            try:
                step = np.linalg.solve(D, r)
            except np.linalg.LinAlgError:
                step = None
            if step is None or not np.all(np.isfinite(step)) or \
                    np.linalg.cond(D) > 1e12:
                raise FrictionError(self._why(active, modes, t))
            x = x - step
            if np.max(np.abs(step)) <= TOLERANCE * max(1.0, np.max(np.abs(x))):
                break
        else:
            raise FrictionError(self._why(active, modes, t))
        for i, k in enumerate(active):
            f[k] = x[i]
            if modes[k] == STUCK:
                F0, DF, M0, DM = linear[k]
                loads[k] = self.elements[k].load(F0 + x @ DF, M0 + x @ DM)[0]
        return FrictionState(f, loads, rates, G, np.asarray(modes, int))

    def _why(self, active, modes, t) -> str:
        stuck = [self.elements[k].name for k in active if modes[k] == STUCK]
        names = ", ".join(f"'{self.elements[k].name}'" for k in active)
        held = f" (holding {', '.join(stuck)} still)" if stuck else ""
        return (f"the friction forces of {names}{held} have no solution at t = {t:.9g}: "
                "a held joint whose motion the other joints prescribe, or friction that "
                "loads its own joint as fast as it grows (a friction lock)")
