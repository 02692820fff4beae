"""The applied loads of a NumericProblem: gravity, springs and torsion springs with dampers,
point forces and torques, and the elastic and inertial forces of flexible beams; their
potentials and the power of every channel that can do work on the mechanism besides gravity
and elastic springs (the energy balance integrates it)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..kinematics import (add_point_force, frame_point, frame_point_velocity, point,
                          point_velocity)


@dataclass(frozen=True)
class SpringData:
    name: str
    a: int | None
    b: int | None
    sa: tuple[float, float]
    sb: tuple[float, float]
    stiffness: float
    damping: float
    rest_length: float
    modal_a: np.ndarray | None = None     # (2, k) modal displacement of a point on a beam
    modal_b: np.ndarray | None = None
    # ∂(stiffness, damping, rest length)/∂k of the Parameters k they depend on: (k, triple).
    partials: tuple = ()


@dataclass(frozen=True)
class RotationalSpringData:
    """A torsion spring–damper: torque −k (θ_b − θ_a − rest) − c (ω_b − ω_a) on body b, the
    opposite on a (the start indices of their frames; None: the ground)."""
    name: str
    a: int | None
    b: int | None
    stiffness: float
    damping: float
    rest: float
    partials: tuple = ()          # ∂(stiffness, damping, rest)/∂k: (k, triple)

    def angles(self, x):
        """θ_b − θ_a (or ω_b − ω_a from velocities) over leading dimensions of x (at most
        one of a, b is the ground, whose angle is 0)."""
        b = x[..., self.b + 2] if self.b is not None else 0.0
        return b - x[..., self.a + 2] if self.a is not None else b


@dataclass(frozen=True)
class PointLoad:
    """A force (constant 2-vector or function of (t, q, v)) at body-fixed point `s`, or a
    torque."""
    name: str
    body: int
    s: tuple[float, float] | None
    value: object          # ndarray (2,), float, or callable of (t, q, v)
    is_torque: bool
    modal: np.ndarray | None = None
    reads_state: bool = False     # its function reads a joint's coordinate or the state
    partials: tuple = ()          # a constant value's ∂/∂k: (k, (∂fx, ∂fy) or (∂τ,))


class FlexibleData:
    """A flexible beam's block of coordinates, (x, y, angle, η₁ … η_k) from `start`, with its
    invariants and generated kernel (`mechsim.flexible`); `point_modes(local)` gives the
    (2, k) modal displacement of a body point."""
    __slots__ = ("name", "start", "invariants", "kernel", "parameters", "slice", "point_modes")

    def __init__(self, name, start, invariants, kernel, parameters, point_modes=None):
        self.name, self.start, self.invariants = name, start, invariants
        self.kernel, self.parameters = kernel, tuple(parameters)
        self.point_modes = point_modes
        self.slice = slice(start, start + 3 + invariants.n_modes)


def _spring_states(sp, Q, V):
    """(length, held, e, rate) of a spring between rigid bodies at the states in the rows
    of Q and V: its length, where it is not zero (a zero-length spring has no direction
    and carries no force), the unit vector e from a to b (N, 2) and the rate of extension
    (the relative velocity along e; 0 where the spring has no damping)."""
    d = frame_point(Q, sp.b, sp.sb) - frame_point(Q, sp.a, sp.sa)
    length = np.hypot(d[:, 0], d[:, 1])
    held = length != 0.0
    e = d / np.where(held, length, 1.0)[:, None]
    if not sp.damping:
        return length, held, e, 0.0
    velocity = frame_point_velocity(Q, V, sp.b, sp.sb) - frame_point_velocity(Q, V, sp.a, sp.sa)
    return length, held, e, velocity[:, 0] * e[:, 0] + velocity[:, 1] * e[:, 1]


def _add_point_forces(F, Q, start, s, f) -> None:
    """`add_point_force` for the states in the rows of Q (rigid bodies): the forces f
    (N, 2) at body point `s` into the rows of F."""
    if start is None:
        return
    th = Q[:, start + 2]
    c, sn = np.cos(th), np.sin(th)
    rx, ry = c * s[0] - sn * s[1], sn * s[0] + c * s[1]
    F[:, start] += f[:, 0]
    F[:, start + 1] += f[:, 1]
    F[:, start + 2] += rx * f[:, 1] - ry * f[:, 0]


class Loads:
    """Q(t, q, v) and the loads' energies and powers.

    Parameters
    ----------
    n : number of coordinates
    gravity : ndarray (2,)
    mass_diagonal : ndarray (n,), the rigid bodies' m on their x and y
    rigid_starts : the start indices of the rigid bodies (gravity's constant force m g)
    springs, loads, flexible, torsion : tuples of SpringData, PointLoad, FlexibleData,
        RotationalSpringData
    """

    def __init__(self, n, gravity, mass_diagonal, rigid_starts, springs=(), loads=(),
                 flexible=(), torsion=()):
        self.n = n
        self.gravity = np.asarray(gravity, float)
        self.springs, self.loads, self.flexible = tuple(springs), tuple(loads), tuple(flexible)
        self.torsion = tuple(torsion)
        # Gravity's generalized force on rigid bodies is constant: m g on their x and y.
        self.gravity_force = np.zeros(n)
        for start in rigid_starts:
            self.gravity_force[start:start + 2] = mass_diagonal[start] * self.gravity

    def forces(self, t, q, v) -> np.ndarray:
        """Generalized applied forces Q(t, q, v), shape (n,): for flexible bodies including
        the quadratic-velocity (centrifugal and Coriolis) terms of M(q)."""
        Q = self.gravity_force.copy()
        for fb in self.flexible:
            Q[fb.slice] += fb.kernel.forces(q[fb.slice], v[fb.slice], fb.parameters)
        self._add(t, q, v, Q, elastic=True)
        return Q

    @property
    def gravity_only(self) -> bool:
        """Is Q gravity's constant force alone (no beam, spring or load)?"""
        return not (self.flexible or self.springs or self.loads or self.torsion)

    @property
    def rigid_only(self) -> bool:
        """Do the loads act on rigid bodies alone, with constant values (no beam, no spring
        or load on a beam, no load given as a function)? Then `forces_at` and `powers_at`
        evaluate all states at once."""
        return not self.flexible and \
            all(sp.modal_a is None and sp.modal_b is None for sp in self.springs) and \
            all(load.modal is None and not callable(load.value) for load in self.loads)

    def forces_at(self, T, Q, V) -> np.ndarray:
        """`forces` at many states (rows), shape (N, n): all states at once where the loads
        are `rigid_only`, state by state elsewhere."""
        T = np.asarray(T, float)
        if self.gravity_only or self.rigid_only:
            F = np.broadcast_to(self.gravity_force, (len(T), self.n)).copy()
            if not self.gravity_only:
                self._add_many(np.asarray(Q, float), np.asarray(V, float), F)
            return F
        return np.array([self.forces(t, q, v) for t, q, v in zip(T, Q, V)]).reshape(
            len(T), self.n)

    def _add_many(self, Q, V, F) -> None:
        """`_add` (elastic) of `rigid_only` loads for the states in the rows of Q and V,
        into the rows of F."""
        for sp in self.springs:
            length, held, e, rate = _spring_states(sp, Q, V)
            tension = sp.stiffness * (length - sp.rest_length)
            if sp.damping:
                tension = tension + sp.damping * rate
            f = np.where(held, tension, 0.0)[:, None] * e
            _add_point_forces(F, Q, sp.a, sp.sa, f)
            _add_point_forces(F, Q, sp.b, sp.sb, -f)
        for rs in self.torsion:
            torque = -rs.stiffness * (rs.angles(Q) - rs.rest)
            if rs.damping:
                torque = torque - rs.damping * rs.angles(V)
            if rs.b is not None:
                F[:, rs.b + 2] += torque
            if rs.a is not None:
                F[:, rs.a + 2] -= torque
        for load in self.loads:
            if load.is_torque:
                F[:, load.body + 2] += load.value
            else:
                _add_point_forces(F, Q, load.body, load.s,
                                  np.broadcast_to(np.asarray(load.value, float), (len(F), 2)))

    def nonconservative_forces(self, t, q, v) -> np.ndarray:
        """The part of Q with no potential: spring damping, point forces and torques, and
        the modal damping of flexible beams."""
        Q = np.zeros(self.n)
        self._add(t, q, v, Q, elastic=False)
        for fb in self.flexible:
            modes = slice(fb.start + 3, fb.slice.stop)
            Q[modes] -= fb.invariants.damping * v[modes]
        return Q

    def _add(self, t, q, v, Q, elastic: bool):
        for sp in self.springs:
            if not elastic and not sp.damping:
                continue
            pa = point(q, sp.a, sp.sa, sp.modal_a)
            pb = point(q, sp.b, sp.sb, sp.modal_b)
            dx, dy = pb[0] - pa[0], pb[1] - pa[1]
            length = math.hypot(dx, dy)
            if length == 0.0:
                continue  # direction undefined; a zero-length spring carries no force
            ex, ey = dx / length, dy / length
            tension = sp.stiffness * (length - sp.rest_length) if elastic else 0.0
            if sp.damping:
                va = point_velocity(q, v, sp.a, sp.sa, sp.modal_a)
                vb = point_velocity(q, v, sp.b, sp.sb, sp.modal_b)
                tension += sp.damping * ((vb[0] - va[0]) * ex + (vb[1] - va[1]) * ey)
            add_point_force(Q, q, sp.a, sp.sa, tension * ex, tension * ey, sp.modal_a)
            add_point_force(Q, q, sp.b, sp.sb, -tension * ex, -tension * ey, sp.modal_b)
        for rs in self.torsion:
            if not elastic and not rs.damping:
                continue
            torque = -rs.stiffness * (rs.angles(q) - rs.rest) if elastic else 0.0
            if rs.damping:
                torque -= rs.damping * rs.angles(v)
            if rs.b is not None:
                Q[rs.b + 2] += torque
            if rs.a is not None:
                Q[rs.a + 2] -= torque
        for load in self.loads:
            value = load.value(t, q, v) if callable(load.value) else load.value
            if load.is_torque:
                Q[load.body + 2] += value
            else:
                fx, fy = value
                add_point_force(Q, q, load.body, load.s, fx, fy, load.modal)

    # --- derivatives ---------------------------------------------------------------------
    def not_differentiated(self) -> str:
        """What keeps `derivative` from differentiating Q ("" where nothing does): a
        spring or load on a flexible body, or a load whose function reads the state."""
        for sp in self.springs:
            if sp.modal_a is not None or sp.modal_b is not None:
                return f"the spring '{sp.name}' on a flexible body"
        for load in self.loads:
            if load.modal is not None:
                return f"the load '{load.name}' on a flexible body"
            if load.reads_state:
                return (f"the {'torque' if load.is_torque else 'force'} '{load.name}', "
                        "whose function reads the motion")
        return ""

    def derivative(self, t, q, v, dq, dv) -> np.ndarray:
        """∂Q/∂q dq + ∂Q/∂v dv at (t, q, v) for the directions dq, dv (n, K): exact, for
        rigid bodies and loads whose values depend on t alone (`not_differentiated`).
        Gravity's force is constant; a spring's tension and direction, a torsion spring's
        torque and every load's moment arm move with the state; a flexible beam's forces
        (quadratic-velocity, gravity, elastic, damping) by its kernel's Jacobians."""
        out = np.zeros_like(dq)
        for fb in self.flexible:
            Qq, Qv = fb.kernel.force_jacobians(q[fb.slice], v[fb.slice], fb.parameters)
            out[fb.slice] += Qq @ dq[fb.slice] + Qv @ dv[fb.slice]
        for sp in self.springs:
            pa, va, dpa, dva, ra, dra = _point_jet(q, v, dq, dv, sp.a, sp.sa)
            pb, vb, dpb, dvb, rb, drb = _point_jet(q, v, dq, dv, sp.b, sp.sb)
            d, dd = pb - pa, dpb - dpa                    # (2,), (2, K)
            length = math.hypot(d[0], d[1])
            if length == 0.0:
                continue
            e = d / length
            dl = e @ dd
            de = (dd - np.outer(e, dl)) / length
            rel, drel = vb - va, dvb - dva
            tension = sp.stiffness * (length - sp.rest_length) + sp.damping * (rel @ e)
            dtension = sp.stiffness * dl + sp.damping * (e @ drel + rel @ de)
            dF = np.outer(e, dtension) + tension * de
            _add_force_derivative(out, sp.a, ra, dra, tension * e, dF)
            _add_force_derivative(out, sp.b, rb, drb, -tension * e, -dF)
        for rs in self.torsion:
            dtorque = -rs.stiffness * rs.angles(dq.T) - rs.damping * rs.angles(dv.T)
            if rs.b is not None:
                out[rs.b + 2] += dtorque
            if rs.a is not None:
                out[rs.a + 2] -= dtorque
        for load in self.loads:
            if load.is_torque:
                continue
            value = load.value(t, q, v) if callable(load.value) else load.value
            _, _, _, _, r, dr = _point_jet(q, v, dq, dv, load.body, load.s)
            out[load.body + 2] += dr[0] * value[1] - dr[1] * value[0]
        return out

    def parameter_derivative(self, t, q, v, names) -> np.ndarray:
        """∂Q/∂k (n, K) at (t, q, v) of the springs' and torsion springs' stiffness,
        damping and rest length or angle, and of constant forces and torques, to the
        Parameters `names` (rigid bodies): the tension's (torque's) change along the
        spring's present line, a force's change at its point."""
        out = np.zeros((self.n, len(names)))
        column = {name: j for j, name in enumerate(names)}
        for load in self.loads:
            for k, d in load.partials:
                if k not in column:
                    continue
                if load.is_torque:
                    out[load.body + 2, column[k]] += d[0]
                else:
                    add_point_force(out[:, column[k]], q, load.body, load.s, d[0], d[1])
        for sp in self.springs:
            wanted = [(column[k], d) for k, d in sp.partials if k in column]
            if not wanted:
                continue
            d = np.subtract(point(q, sp.b, sp.sb), point(q, sp.a, sp.sa))
            length = math.hypot(d[0], d[1])
            if length == 0.0:
                continue
            e = d / length
            rate = np.subtract(point_velocity(q, v, sp.b, sp.sb),
                               point_velocity(q, v, sp.a, sp.sa)) @ e
            for j, (dk, dc, dl) in wanted:
                f = (dk * (length - sp.rest_length) - sp.stiffness * dl + dc * rate) * e
                col = out[:, j]
                add_point_force(col, q, sp.a, sp.sa, f[0], f[1])
                add_point_force(col, q, sp.b, sp.sb, -f[0], -f[1])
        for rs in self.torsion:
            for k, (dk, dc, drest) in rs.partials:
                if k not in column:
                    continue
                dtorque = -dk * (rs.angles(q) - rs.rest) + rs.stiffness * drest \
                    - dc * rs.angles(v)
                if rs.b is not None:
                    out[rs.b + 2, column[k]] += dtorque
                if rs.a is not None:
                    out[rs.a + 2, column[k]] -= dtorque
        return out

    # --- work ------------------------------------------------------------------------------
    @property
    def work_channels(self) -> list[str]:
        """One name per channel of `powers`: each damped spring ("spring 's' (damping)"),
        each load ("load 'F'") and each beam with modal damping ("beam 'b' (modal
        damping)")."""
        names = [f"spring '{sp.name}' (damping)" for sp in self.springs if sp.damping]
        names += [f"rotational spring '{rs.name}' (damping)" for rs in self.torsion
                  if rs.damping]
        names += [f"load '{load.name}'" for load in self.loads]
        names += [f"beam '{fb.name}' (modal damping)" for fb in self.flexible
                  if np.any(fb.invariants.damping > 0.0)]
        return names

    def powers(self, t, q, v) -> list[float]:
        """The power of each of `work_channels` at (q, v): a damper's −c ṡ² (ṡ its rate of
        extension or of relative rotation), a load's F·ṗ or τ ω, a beam's −Σ d_k η̇_k²."""
        out = []
        for sp in self.springs:
            if not sp.damping:
                continue
            pa = point(q, sp.a, sp.sa, sp.modal_a)
            pb = point(q, sp.b, sp.sb, sp.modal_b)
            d = np.subtract(pb, pa)
            length = math.hypot(d[0], d[1])
            if length == 0.0:
                out.append(0.0)
                continue
            rate = (np.subtract(point_velocity(q, v, sp.b, sp.sb, sp.modal_b),
                                point_velocity(q, v, sp.a, sp.sa, sp.modal_a)) @ d) / length
            out.append(-sp.damping * rate * rate)
        for rs in self.torsion:
            if rs.damping:
                rate = float(rs.angles(v))
                out.append(-rs.damping * rate * rate)
        for load in self.loads:
            value = load.value(t, q, v) if callable(load.value) else load.value
            if load.is_torque:
                out.append(float(value) * v[load.body + 2])
            else:
                out.append(float(np.dot(value, point_velocity(q, v, load.body, load.s,
                                                              load.modal))))
        for fb in self.flexible:
            d = fb.invariants.damping
            if np.any(d > 0.0):
                rates = v[fb.start + 3:fb.slice.stop]
                out.append(-float(np.sum(d * rates * rates)))
        return out

    def powers_at(self, T, Q, V) -> np.ndarray:
        """`powers` at many states (rows), shape (N, k): all states at once where the loads
        are `rigid_only`, state by state elsewhere."""
        T = np.asarray(T, float)
        if not self.rigid_only:
            return np.array([self.powers(t, q, v) for t, q, v in zip(T, Q, V)]).reshape(
                len(T), len(self.work_channels))
        Q, V = np.asarray(Q, float), np.asarray(V, float)
        out = []
        for sp in self.springs:
            if not sp.damping:
                continue
            _, held, _, rate = _spring_states(sp, Q, V)
            out.append(np.where(held, -sp.damping * rate * rate, 0.0))
        for rs in self.torsion:
            if rs.damping:
                rate = rs.angles(V)
                out.append(-rs.damping * rate * rate)
        for load in self.loads:
            if load.is_torque:
                out.append(load.value * V[:, load.body + 2])
            else:
                out.append(frame_point_velocity(Q, V, load.body, load.s) @
                           np.asarray(load.value, float))
        return np.column_stack(out) if out else np.zeros((len(T), 0))

    # --- energies (vectorized over leading dimensions) -------------------------------------
    def gravity_potential(self, q) -> np.ndarray:
        V = -np.einsum("...i,i->...", q, self.gravity_force)
        for fb in self.flexible:
            V = V + fb.invariants.gravity_potential(q[..., fb.slice], self.gravity)
        return V

    def spring_potential(self, q) -> np.ndarray:
        total = np.zeros(np.shape(q)[:-1])
        for sp in self.springs:
            d = frame_point(q, sp.b, sp.sb, sp.modal_b) - frame_point(q, sp.a, sp.sa, sp.modal_a)
            total = total + 0.5 * sp.stiffness * (np.linalg.norm(d, axis=-1) - sp.rest_length) ** 2
        for rs in self.torsion:
            total = total + 0.5 * rs.stiffness * (rs.angles(q) - rs.rest) ** 2
        return total

    def spring_potential_derivative(self, q, dq, names) -> np.ndarray:
        """∂(`spring_potential`)/∂k (N, K) at the states q (N, n) with sensitivities dq
        (N, n, K): k (l − l₀)(e·(ṙ_b − ṙ_a) − ∂l₀/∂k) + ½ ∂k/∂k' (l − l₀)² of each spring
        (its points' change along dq), the torsion springs' likewise; `names` the
        Parameters of the columns, for the springs' own constants (rigid bodies)."""
        column = {name: j for j, name in enumerate(names)}
        out = np.zeros(dq.shape[:1] + dq.shape[2:])
        for sp in self.springs:
            d = frame_point(q, sp.b, sp.sb) - frame_point(q, sp.a, sp.sa)
            length = np.linalg.norm(d, axis=-1)
            e = d / length[:, None]
            stretch = length - sp.rest_length
            for j in range(dq.shape[2]):
                dd = frame_point_velocity(q, dq[:, :, j], sp.b, sp.sb) - \
                    frame_point_velocity(q, dq[:, :, j], sp.a, sp.sa)
                out[:, j] += sp.stiffness * stretch * np.sum(e * dd, axis=-1)
            for name, (dk, _, drest) in sp.partials:
                if name in column:
                    out[:, column[name]] += 0.5 * dk * stretch**2 - sp.stiffness * stretch * drest
        for rs in self.torsion:
            twist = rs.angles(q) - rs.rest
            for j in range(dq.shape[2]):
                out[:, j] += rs.stiffness * twist * rs.angles(dq[:, :, j])
            for name, (dk, _, drest) in rs.partials:
                if name in column:
                    out[:, column[name]] += 0.5 * dk * twist**2 - rs.stiffness * twist * drest
        return out

    def strain_energy(self, q) -> np.ndarray:
        """Elastic energy of the flexible bodies' modes, ½ Σ ω_k² η_k²."""
        U = np.zeros(np.shape(q)[:-1])
        for fb in self.flexible:
            U = U + fb.invariants.strain(q[..., fb.slice])
        return U


def _point_jet(q, v, dq, dv, start, s):
    """A rigid body's point `s` (body-fixed) and its velocity, their changes along the
    directions dq, dv (2, K), its arm r = R s from the frame origin and r's change: for
    `Loads.derivative` (the ground: fixed)."""
    K = dq.shape[1]
    if start is None:
        zero, none = np.zeros((2, K)), np.zeros(2)
        return np.asarray(s, float), none, zero, zero, np.asarray(s, float), zero
    c, sn = math.cos(q[start + 2]), math.sin(q[start + 2])
    r = np.array([c * s[0] - sn * s[1], sn * s[0] + c * s[1]])
    turn = np.array([-r[1], r[0]])                        # ∂r/∂θ
    dth, w, dw = dq[start + 2], v[start + 2], dv[start + 2]
    dr = np.outer(turn, dth)
    p = q[start:start + 2] + r
    vel = v[start:start + 2] + w * turn
    dp = dq[start:start + 2] + dr
    dvel = dv[start:start + 2] + np.outer(turn, dw) + w * np.outer(-r, dth)
    return p, vel, dp, dvel, r, dr


def _add_force_derivative(out, start, r, dr, F, dF) -> None:
    """The change of a point force F's generalized force (`add_point_force`) for a change
    dF of the force and dr of its arm (rigid bodies)."""
    if start is None:
        return
    out[start:start + 2] += dF
    out[start + 2] += dr[0] * F[1] + r[0] * dF[1] - dr[1] * F[0] - r[1] * dF[0]
