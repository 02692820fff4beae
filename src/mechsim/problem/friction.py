"""Dry friction in joints, solved together with the reactions that load it, and the
joints that stops and sticking hold still.

A joint k with friction (`mechsim.model.friction.Friction`) receives a force f_k along its
coordinate s_k (a torque for a revolute, a force for a prismatic), the generalized force
f_k ∂s_k/∂q. The equations of motion become

    M q̈ + Φ_qᵀ λ = Q + Σ_k f_k g_k,    Φ_q q̈ = γ,    g_k = ∂s_k/∂q,

so q̈ and λ are affine in f: q̈ = a₀ + Σ a_k f_k, λ = λ₀ + Σ Λ_k f_k (one solve of the
saddle-point system for Q and one for each g_k). Each f_k is given by its joint's state:

- slipping in direction σ = ±1: f_k = −σ μ(ṡ_k) L_k(λ), L_k the joint's load (the pin's
  ‖F‖ times its radius, a guide's normal load), each a norm of the wrench its rows of λ
  apply (`mechsim.problem.geometry.joint_wrench`, linear in λ);
- stuck: whatever holds it, s̈_k = g_k q̈ + vᵀ(∂²s_k/∂q²)v = 0 (linear in f).

A stop on which a joint rests is an element of the same kind (`kind` "stop"): its force
holds the joint still while the stop pushes (`STUCK`), and it is none otherwise (`FREE`).

Newton's method on f solves all of them at once, with the exact Jacobian (the norms'
gradients); its residual is the implicit relation itself, not a lagged reaction. A
Jacobian that cannot be inverted (a stuck joint whose motion other constraints prescribe,
or friction feeding back on its own load with a gain of one or more: a friction lock)
raises `FrictionError`, which ends a run with its partial result.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from functools import cached_property

import numpy as np

from .geometry import joint_gradients, joint_path_rates, joint_wrench

# What an element is doing: sliding forwards or backwards, held at zero rate, or nothing (a
# stop its joint does not rest on; a joint's friction while its stop holds it).
FORWARD, BACKWARD, STUCK, FREE = 1, -1, 0, 2
# Newton on the friction forces stops at this relative change (round-off in a few steps).
TOLERANCE = 1e-13
MAX_ITERATIONS = 30
# Their Jacobian (a held joint's row scaled by its mobility, a sliding joint's 1 + …)
# counts as singular below this σ_min (a held joint that no force of its own moves: its row
# is round-off).
SINGULAR = 1e-9


def _responses(problem, J, gamma, q, R):
    """(q̈, λ) of the saddle-point system for each column of R (n, c): the first with the
    constraints' γ, the others (unit generalized forces) with zero; shapes (n, c), (m, c).
    One factor of Φ_q M⁻¹ Φ_qᵀ serves every column where M is a constant diagonal and the
    complement dense; else column by column."""
    C = np.zeros((len(gamma), R.shape[1]))
    C[:, 0] = gamma
    if problem.algebra.dense_complement:
        from .mass import dense
        w = problem.inverse_mass_diagonal[:, None]
        wr = w * R
        lam = dense().solve_psd((J * w.T) @ J.T, J @ wr - C)
        return wr - w * (J.T @ lam), lam
    out = [problem.accelerations(J, R[:, i], C[:, i], q) for i in range(R.shape[1])]
    return np.column_stack([a for a, _ in out]), np.column_stack([lam for _, lam in out])


def _newton(elements, active, equations):
    """The friction forces x (one per active joint) solving each joint's equation
    (`equations[i]`: (σμ, its wrench's affine map, None) for a sliding joint, x_i + σμ L = 0;
    (None, constant, row) for a held one, constant + row · x = 0), by Newton's method with
    the exact Jacobian; None where it is singular or does not converge. The residuals and
    the Jacobian are built in floats (a few joints: numpy's per-call cost would dominate)."""
    size = len(active)
    terms = []
    for k, (slide, affine, row) in zip(active, equations):
        if slide is None:
            terms.append((None, float(affine), np.asarray(row, float).tolist()))
        else:
            F0, DF, M0, DM = affine
            terms.append((float(slide), elements[k].shape, float(F0[0]), float(F0[1]),
                          DF[:, 0].tolist(), DF[:, 1].tolist(), float(M0), DM.tolist()))
    x = [0.0] * size
    for _ in range(MAX_ITERATIONS):
        r, D = [0.0] * size, []
        for i, term in enumerate(terms):
            if term[0] is None:
                _, constant, row = term
                r[i] = constant + sum(a * b for a, b in zip(row, x))
                D.append(row)
                continue
            slide, shape, fx, fy, dfx, dfy, m, dm = term
            for j, xj in enumerate(x):
                fx, fy, m = fx + xj * dfx[j], fy + xj * dfy[j], m + xj * dm[j]
            L, gx, gy, gm = _load(*shape, fx, fy, m)
            r[i] = x[i] + slide * L
            D.append([slide * (dfx[j] * gx + dfy[j] * gy + dm[j] * gm) + (j == i)
                      for j in range(size)])
        step = _solve_small(D, r)
        if step is None or not all(map(math.isfinite, step)):
            return None
        x = [a - b for a, b in zip(x, step)]
        if max(map(abs, step)) <= TOLERANCE * max(1.0, max(map(abs, x))):
            return np.array(x)
    return None


def _solve_small(D, r):
    """D⁻¹ r for a small square D (lists), None where D counts as singular: σ_min ≤
    `SINGULAR` max(1, σ_max). Sizes 1 and 2 in floats (σ of a 2 × 2 in closed form: σ₁² +
    σ₂² = ‖D‖², σ₁σ₂ = |det D|), larger ones by one SVD (the test and the solve)."""
    if len(D) == 1:
        return [r[0] / D[0][0]] if abs(D[0][0]) > SINGULAR else None
    if len(D) == 2:
        (a, b), (c, d) = D
        det = a * d - b * c
        norm2 = a * a + b * b + c * c + d * d
        largest = math.sqrt(0.5 * (norm2 + math.sqrt(max(norm2 * norm2 - 4.0 * det * det,
                                                             0.0))))
        if not abs(det) > SINGULAR * largest * max(1.0, largest):   # σ_min = |det| / σ_max
            return None
        return [(d * r[0] - b * r[1]) / det, (a * r[1] - c * r[0]) / det]
    U, singular, Vt = np.linalg.svd(np.array(D))
    if not singular[-1] > SINGULAR * max(1.0, singular[0]):
        return None
    return list(Vt.T @ ((U.T @ np.array(r)) / singular))


def _load(radius, length, preload, fx, fy, m):
    """(L, ∂L/∂F_x, ∂L/∂F_y, ∂L/∂M) of an element of `radius`, `length` (NaN where it has
    none) and `preload` under the joint force (fx, fy) and moment m, in floats: a pin's
    μ-less load r (‖F‖ + preload), a guide's ‖F‖ + preload, or 2|M|/length + preload where
    its block's couple outweighs ‖F‖ (the contact at its two ends)."""
    size = math.hypot(fx, fy)
    ux, uy = (fx / size, fy / size) if size > 0.0 else (0.0, 0.0)
    if radius == radius:
        return radius * (size + preload), radius * ux, radius * uy, 0.0
    if 2.0 * abs(m) / length > size:                    # (False where no length)
        return 2.0 * abs(m) / length + preload, 0.0, 0.0, math.copysign(2.0, m) / length
    return size + preload, ux, uy, 0.0


class FrictionError(RuntimeError):
    """The friction forces have no solution at a state (see the module docstring)."""


@dataclass(frozen=True)
class FrictionElement:
    """One joint's friction or stop: the model element (`Friction`: coefficients, radius,
    length, preload; or a `Stop`), its joint's geometry and the rows of Φ its joint owns."""
    friction: object
    geometry: object
    rows: tuple

    @property
    def name(self) -> str:
        return self.friction.name

    @property
    def kind(self) -> str:
        """"friction" or "stop"."""
        return self.friction.kind

    @property
    def shape(self) -> tuple:
        """(radius, length, preload) as floats, NaN where the element has none (`_load`)."""
        fr = self.friction
        return (math.nan if fr.radius is None else float(fr.radius),
                math.nan if fr.length is None else float(fr.length), float(fr.preload))

    def load(self, F, M):
        """(L, ∂L/∂F (2,), ∂L/∂M) of the joint force F (2,) and moment M: what μ multiplies."""
        L, gx, gy, gm = _load(*self.shape, float(F[0]), float(F[1]), float(M))
        return L, np.array([gx, gy]), gm


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

    def static_limit(self, model, k) -> float:
        """μ_s times the load of friction element k of `model`: the most it holds still."""
        return model.elements[k].friction.mu_static * self.loads[k]


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

    def modes_at(self, t) -> np.ndarray | None:
        """The modes at time t (None: each friction joint follows its rate's sign)."""
        for t_end, modes in self.schedule:
            if t <= t_end:
                return np.asarray(modes, int)
        return self.modes

    @cached_property
    def idle(self) -> bool:
        """Whether no element acts at any state: every one `FREE` (a run's piece with no
        friction and no stop holding its joint)."""
        return self.modes is not None and not self.schedule and bool(np.all(self.modes == FREE))

    @cached_property
    def frictions(self) -> list[int]:
        """The indices of the friction elements (the others are stops)."""
        return [k for k, e in enumerate(self.elements) if e.kind == "friction"]

    @property
    def channels(self) -> list[str]:
        """A work channel per friction element (a stop's hold does no work)."""
        return [f"friction '{self.elements[k].name}'" for k in self.frictions]

    def solve(self, problem, t, q, v, Q, modes=None) -> FrictionState:
        """The friction forces at the state (t, q, v) under the applied forces Q (n,)
        (`modes` overrides the model's). A joint following its rate's sign (modes None)
        at zero rate carries none, nor does a stop."""
        return self.solve_many(problem, [t], np.asarray(q, float)[None],
                               np.asarray(v, float)[None], np.asarray(Q, float)[None], modes)[0]

    def solve_many(self, problem, T, Q, V, F, modes=None) -> list[FrictionState]:
        """`solve` at the states (T[i], Q[i], V[i]) under the applied forces F[i] (rows):
        each joint's geometry (its gradient, the wrenches its multipliers apply, its path
        rates) evaluated over all of them in one pass, each state's saddle-point responses
        and Newton on its own. A state with no solution raises `FrictionError`."""
        T = np.atleast_1d(np.asarray(T, float))
        Q, V, F = np.atleast_2d(np.asarray(Q, float), np.asarray(V, float), np.asarray(F, float))
        N, n = len(T), Q.shape[1]
        K = len(self.elements)
        given = [modes if modes is not None else self.modes_at(t) for t in T]
        G = np.zeros((N, K, n))
        for k, e in enumerate(self.elements):           # a free stop needs no gradient
            moving = [i for i, m in enumerate(given)
                      if e.kind == "friction" or (m is not None and m[k] != FREE)]
            if moving:
                G[moving, k] = joint_gradients(e.geometry, Q[moving])
        rates = np.einsum("ikn,in->ik", G, V)
        chosen = [np.asarray(m, int) if m is not None else np.array(
            [int(np.sign(r)) if e.kind == "friction" and r != 0.0 else FREE
             for e, r in zip(self.elements, rates[i])]) for i, m in enumerate(given)]
        f, loads = np.zeros((N, K)), np.zeros((N, K))
        groups = {}                                     # the states of each active set
        for i, m in enumerate(chosen):
            active = tuple(k for k in range(K) if m[k] != FREE)
            if active:
                groups.setdefault(active, []).append(i)
        for active, states in groups.items():
            self._solve_group(problem, list(active), states, (T, Q, V, F, G, rates, chosen),
                              f, loads)
        return [FrictionState(f[i], loads[i], rates[i], G[i], chosen[i]) for i in range(N)]

    def _solve_group(self, problem, active, states, at, f, loads):
        """Fill f and loads (N, K) at the `states` (indices into `at`: T, Q, V, F, G,
        rates, modes) whose elements `active` act."""
        T, Q, V, F, G, rates, chosen = at
        a = len(active)
        responses = []                                  # each state's (Φ_q, q̈ (n, 1 + a), λ)
        for i in states:
            J, gamma = problem.dynamics_terms(Q[i], V[i], T[i])
            responses.append((J, *_responses(problem, J, gamma, Q[i],
                                             np.column_stack([F[i], G[i, active].T]))))
        linear = {}                     # a rubbing joint's wrench, affine in x: (F, M) per state
        for k in active:
            e = self.elements[k]
            if e.kind != "friction":
                continue
            rows = list(e.rows)
            if len(states) == 1:                    # (the right-hand side's case)
                (J, _, Lam), = responses
                lam, jacobian = Lam[rows].T, J[rows]
            else:
                lam = np.concatenate([Lam[rows].T for _, _, Lam in responses])  # (S (1+a), rows)
                jacobian = np.concatenate([np.broadcast_to(J[rows], (1 + a,) + J[rows].shape)
                                           for J, _, _ in responses])
            Fk, Mk = joint_wrench(e.geometry, np.repeat(Q[states], 1 + a, axis=0), lam,
                                  jacobian=jacobian)
            linear[k] = (Fk.reshape(len(states), 1 + a, 2), Mk.reshape(len(states), 1 + a))
        held = [k for k in active if any(chosen[i][k] == STUCK for i in states)]
        paths = {k: joint_path_rates(self.elements[k].geometry, Q[states], V[states])[2]
                 for k in held}
        W = problem.inverse_mass_diagonal
        for s, i in enumerate(states):
            _, A, _ = responses[s]
            a0, A = A[:, 0], A[:, 1:]
            equations = []
            for k in active:
                if chosen[i][k] == STUCK:
                    # s̈_k = g q̈ + vᵀ(∂²s/∂q²)v = 0, scaled by g M⁻¹ g (the joint's own
                    # mobility) so that a joint its own force cannot move shows as a zero row.
                    g = G[i, k]
                    scale = 1.0 / float(g @ (W * g))
                    equations.append((None, scale * (g @ a0 + paths[k][s]), scale * (g @ A)))
                else:
                    mu = self.elements[k].friction.coefficient(abs(rates[i, k]))
                    Fk, Mk = linear[k]
                    equations.append((chosen[i][k] * mu, (Fk[s, 0], Fk[s, 1:], Mk[s, 0],
                                                          Mk[s, 1:]), None))
            x = _newton(self.elements, active, equations)
            if x is None:
                raise FrictionError(self._why(active, chosen[i], T[i]))
            f[i, active] = x
            for k in linear:
                Fk, Mk = linear[k]
                loads[i, k] = self.elements[k].load(Fk[s, 0] + x @ Fk[s, 1:],
                                                    Mk[s, 0] + x @ Mk[s, 1:])[0]

    def _why(self, active, modes, t) -> str:
        stuck = [self.elements[k].name for k in active if modes[k] == STUCK]
        names = ", ".join(f"'{self.elements[k].name}'" for k in active)
        held = f" (holding {', '.join(stuck)} still)" if stuck else ""
        return (f"the forces of {names}{held} have no solution at t = {t:.9g}: "
                "a held joint whose motion the other joints prescribe, or friction that "
                "loads its own joint as fast as it grows (a friction lock)")
