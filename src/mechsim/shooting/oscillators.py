"""Periodically forced oscillators for shooting (seed 002), with event-exact nonsmooth flows.

A periodic problem is anything with::

    period : float
    n : number of unknowns
    initial_state(u) -> full state at t = 0 from the unknowns u
    flow(u) -> Trajectory over one period (t, x, and the events it met)
    residual(u) -> g(u), zero at a periodic steady state

so users can shoot their own problems by writing these. Optional: `residual_jacobian(u) ->
(g, ∂g/∂u)` from one flow (exact Newton, e.g. with a closed-form monodromy), and
`singular_jacobian = True` where the solutions come in a continuous family (Newton then
takes minimum-norm steps).

Units as in the paper: mm and s for the single-degree-of-freedom problems (g = 9800 mm/s²).
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass, field

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

_RTOL, _ATOL = 1e-12, 1e-14


@dataclass
class Trajectory:
    """One period of motion: t (k,), x (k, n_state); `events` lists (t, kind)."""
    t: np.ndarray
    x: np.ndarray
    events: list = field(default_factory=list)


class PeriodicProblem:
    period: float
    n: int
    # The residual's Jacobian is singular at the solutions (a continuous family of them,
    # e.g. the impact pair shifted as a whole): Newton then takes minimum-norm steps.
    singular_jacobian = False
    # Floquet multipliers fixed at 1 by a continuous symmetry of the motion (not by its
    # stability): `ShootingResult.stable` judges the others.
    neutral_multipliers = 0
    flows = 0                           # motions computed (one period or a t_span each)

    def initial_state(self, u) -> np.ndarray:
        return np.asarray(u, float)

    def flow(self, u) -> Trajectory:
        raise NotImplementedError

    def period_map(self, u) -> np.ndarray:
        """x(T) from x(0) = u: one period of motion, end state only (the Poincaré map that
        shooting zeroes and a brute-force simulation iterates)."""
        return self.flow(u).x[-1]

    def residual(self, u) -> np.ndarray:
        """g(u) = x(0) − x(T) (eq. 3)."""
        return self.check(u) - self.period_map(u)

    def check(self, u) -> np.ndarray:
        u = np.asarray(u, float)
        if u.shape != (self.n,):
            raise ValueError(f"{type(self).__name__}: the guess must have {self.n} unknowns, "
                             f"got shape {u.shape}")
        if not np.all(np.isfinite(u)):
            raise ValueError(f"{type(self).__name__}: the guess must be finite, got {u}")
        return u


def _positive(owner, **values):
    for k, v in values.items():
        if not (isinstance(v, numbers.Real) and math.isfinite(v) and v > 0):
            raise ValueError(f"{owner}: `{k}` must be positive, got {v!r}")


class LinearOscillator(PeriodicProblem):
    """ẍ + 2ζω_n ẋ + ω_n² x = δ_st ω_n² cos ωt (eq. 4); unknowns (x(0), ẋ(0))."""

    n = 2

    def __init__(self, zeta, omega_n, delta_st, omega):
        _positive(type(self).__name__, omega_n=omega_n, delta_st=delta_st, omega=omega)
        if not zeta >= 0:
            raise ValueError(f"{type(self).__name__}: `zeta` must be non-negative, got {zeta!r}")
        self.zeta, self.omega_n, self.delta_st, self.omega = zeta, omega_n, delta_st, omega
        self.period = 2 * math.pi / omega

    def rhs(self, t, y, friction=0.0):
        x, v = y
        wn = self.omega_n
        return [v, -2 * self.zeta * wn * v - wn**2 * x + self.delta_st * wn**2
                * math.cos(self.omega * t) - friction]

    @property
    def closed_form(self) -> bool:
        """Underdamped: slip phases are evaluated in closed form (else integrated)."""
        return self.zeta < 1.0

    def _segment(self, t0, x0, v0, friction=0.0):
        """The motion from (x0, v0) at t0 under the constant extra force −`friction`, in
        closed form (ζ < 1): returns state(t) -> (x, v) arrays for array t, and the state
        transition matrix ∂(x, v)(t)/∂(x0, v0) as a function of t."""
        wn, z, w = self.omega_n, self.zeta, self.omega
        F = self.delta_st * wn**2
        den = (wn**2 - w**2) ** 2 + (2 * z * wn * w) ** 2
        a, b = F * (wn**2 - w**2) / den, F * 2 * z * wn * w / den
        xs = -friction / wn**2
        sig, wd = z * wn, wn * math.sqrt(1.0 - z * z)
        xp0 = a * math.cos(w * t0) + b * math.sin(w * t0) + xs
        vp0 = -a * w * math.sin(w * t0) + b * w * math.cos(w * t0)
        c1 = x0 - xp0
        c2 = (v0 - vp0 + sig * c1) / wd

        def state(t):
            t = np.asarray(t, float)
            tau = t - t0
            e, c, sn = np.exp(-sig * tau), np.cos(wd * tau), np.sin(wd * tau)
            x = a * np.cos(w * t) + b * np.sin(w * t) + xs + e * (c1 * c + c2 * sn)
            v = (-a * w * np.sin(w * t) + b * w * np.cos(w * t)
                 + e * ((-sig * c1 + wd * c2) * c + (-sig * c2 - wd * c1) * sn))
            return x, v

        def entries(t):
            """The transition matrix at t as a row-major 4-tuple of floats."""
            tau = t - t0
            e, c, sn = math.exp(-sig * tau), math.cos(wd * tau), math.sin(wd * tau)
            return (e * (c + sig / wd * sn), e * sn / wd, -e * (wn * wn / wd) * sn,
                    e * (c - sig / wd * sn))

        def transition(t):
            return np.array(entries(t)).reshape(2, 2)
        transition.entries = entries

        def velocity(t):
            """ẋ at a scalar t (plain math: the root finder calls it ~20 times a stop)."""
            tau = t - t0
            e, c, sn = math.exp(-sig * tau), math.cos(wd * tau), math.sin(wd * tau)
            return (-a * w * math.sin(w * t) + b * w * math.cos(w * t)
                    + e * ((-sig * c1 + wd * c2) * c + (-sig * c2 - wd * c1) * sn))

        def position(t):
            """x at a scalar t."""
            tau = t - t0
            e = math.exp(-sig * tau)
            return (a * math.cos(w * t) + b * math.sin(w * t) + xs
                    + e * (c1 * math.cos(wd * tau) + c2 * math.sin(wd * tau)))
        state.velocity, state.position = velocity, position
        return state, transition

    def flow(self, u, t_span=None, samples=200):
        return self.flow_with_monodromy(u, t_span, samples)[0]

    def _cached_flow(self, u):
        """The one-period flow (end points only) and monodromy of u."""
        return self._remembered(u, lambda: self.flow_with_monodromy(u, samples=3))

    def _remembered(self, u, compute):
        """compute(), remembered for the latest u: Newton asks for (g, J), then the Floquet
        multipliers and the trajectory at the same point."""
        out = self._recalled(u)
        if out is None:
            out = compute()
            self._last = (np.asarray(u, float).tobytes(), out)
        return out

    def _recalled(self, u):
        """What `_remembered` holds for u, or None."""
        last = getattr(self, "_last", None)
        return last[1] if last is not None and last[0] == np.asarray(u, float).tobytes() \
            else None

    def flow_with_monodromy(self, u, t_span=None, samples=200):
        """(Trajectory, ∂x(t_end)/∂x(t_start)) — exact: the motion is known in closed form."""
        u = self.check(u)
        t0, t1 = t_span or (0.0, self.period)
        self.flows += 1
        if not self.closed_form:
            s = solve_ivp(self.rhs, (t0, t1), u, method="DOP853", rtol=_RTOL, atol=_ATOL,
                          dense_output=True)
            if not s.success:
                raise ValueError(f"{type(self).__name__}: the flow failed: {s.message}")
            tt = np.linspace(t0, t1, samples)
            x = s.sol(tt).T
            x[0], x[-1] = u, s.y[:, -1]
            return Trajectory(tt, x), None
        state, transition = self._segment(t0, float(u[0]), float(u[1]))
        tt = np.linspace(t0, t1, samples)
        x = np.column_stack(state(tt))
        x[0] = u
        return Trajectory(tt, x), transition(t1)

    def residual_jacobian(self, u):
        """(g, ∂g/∂u) from one flow: g = u − x(T), ∂g/∂u = I − M with the exact monodromy."""
        traj, M = self._cached_flow(u)
        if M is None:
            return None
        return traj.x[0] - traj.x[-1], np.eye(2) - M

    def floquet_matrix(self, u):
        M = self._cached_flow(u)[1]
        if M is None:
            from .solve import monodromy
            return monodromy(self, u)
        return M

    def steady_amplitude(self) -> float:
        r = self.omega / self.omega_n
        return self.delta_st / math.hypot(1 - r**2, 2 * self.zeta * r)


class CoulombOscillator(LinearOscillator):
    """Eq. 10: ẍ + 2ζω_n ẋ + ω_n² x + sign(ẋ) μ g = δ_st ω_n² cos ωt, with true sticking.

    At ẋ = 0 the mass sticks while abs(x − δ_st cos ωt) < μ g / ω_n² (eq. 13) and leaves in the
    direction of the net force (eq. 12). Slip phases are linear with constant friction, so
    for ζ < 1 they are evaluated in closed form and each stop ẋ = 0 is the root of a
    closed-form function (brentq to round-off); stick phases are exact — x is constant — and
    their end is a root as well. The monodromy comes with the flow (`flow_with_monodromy`),
    so Newton shooting needs one flow per iteration.
    """

    def __init__(self, zeta, omega_n, delta_st, omega, mu, g=9800.0):
        super().__init__(zeta, omega_n, delta_st, omega)
        if not mu >= 0:
            raise ValueError(f"CoulombOscillator: `mu` must be non-negative, got {mu!r}")
        _positive("CoulombOscillator", g=g)
        self.mu, self.g = mu, g
        self.limit = mu * g / omega_n**2              # half-width of the stick band (eq. 13)

    def _excess(self, t, x):
        return x - self.delta_st * math.cos(self.omega * t)

    def _slip_direction(self, t, x):
        """+1 / −1 to leave a stop at (t, x), 0 to stay stuck (eqs. 12–13)."""
        e = self._excess(t, x)
        if e < -self.limit:
            return 1
        if e > self.limit:
            return -1
        return 0

    def flow(self, u, t_span=None, samples=400):
        if t_span is None:
            motion = self._cached_motion(u)             # Newton's last iterate: no new events
            return self._sampled(u, motion[0], motion[1], samples)
        return self.flow_with_monodromy(u, t_span, samples)[0]

    def _cached_flow(self, u):
        _, events, M, end = self._cached_motion(u)
        return Trajectory(np.array([0.0, self.period]), np.vstack([u, end]), events), M

    def residual_jacobian(self, u):
        _, _, M, end = self._cached_motion(u)
        return None if M is None else (np.asarray(u, float) - end, np.eye(2) - M)

    def period_map(self, u):
        """x(T): Newton's latest flow when u is its iterate, else a flow without the
        monodromy (what Warner's residual and a brute-force simulation need)."""
        motion = self._recalled(u)
        return (motion if motion is not None else self._motion(u, monodromy=False))[3]

    def _cached_motion(self, u):
        """`_motion` over one period, remembered for the latest u."""
        return self._remembered(u, lambda: self._motion(u))

    def flow_with_monodromy(self, u, t_span=None, samples=400):
        """(Trajectory, M): the motion over one period (or `t_span`) and its monodromy
        M = ∂x(t_end)/∂x(t_start), the product of the slip phases' transition matrices
        (closed form) and the saltation matrices at the stops, diag(1, a⁺/a⁻) (a± the
        acceleration just after and before; a⁺ = 0 when the mass sticks). Stick phases
        map (δx, 0) to itself; leaving a stop the net force is zero, so no saltation. M is
        None where it is undefined (ζ ≥ 1 integrates numerically; a grazing stop)."""
        pieces, events, M, _ = self._motion(u, t_span)
        return self._sampled(u, pieces, events, samples), M

    def _sampled(self, u, pieces, events, samples):
        """The trajectory through `pieces` (t_a, t_b, state(t) -> (x, v), stops), with
        about `samples` points per period (20 per stick phase)."""
        ts, xs = [pieces[0][0]], [np.asarray(u, float)]
        for ta, tb, state, stops in pieces:
            n = 20 if stops is None else max(3, int(samples * (tb - ta) / self.period))
            tt = np.linspace(ta, tb, n)[1:]
            part = np.empty((tt.size, 2))
            part[:, 0], part[:, 1] = state(tt)
            if stops:
                part[-1, 1] = 0.0                       # ẋ reached 0: exactly zero there
            ts.append(tt)
            xs.append(part)
        return Trajectory(np.hstack(ts), np.vstack(xs), events)

    def _motion(self, u, t_span=None, monodromy=True):
        """The stick and slip phases over `t_span` (one period by default): (pieces, events,
        M, end state); see `flow_with_monodromy` (M is None without `monodromy`). Each slip
        phase keeps its closed-form state, so the trajectory is sampled afterwards at any
        density without finding the events again."""
        u = self.check(u)
        t, t_end = t_span or (0.0, self.period)
        x, v = float(u[0]), float(u[1])
        pieces, events = [], []
        # The monodromy as a row-major 4-tuple (2 × 2 products in plain floats).
        M = (1.0, 0.0, 0.0, 1.0) if self.closed_form and monodromy else None
        self.flows += 1
        guard = 0
        while t < t_end - 1e-15 * max(1.0, t_end):
            guard += 1
            if guard > 10000:
                raise ValueError("CoulombOscillator: more than 10000 stick/slip changes in one "
                                 "period; the motion is not resolvable")
            if v == 0.0:
                d = self._slip_direction(t, x)
                if d == 0:                                   # stuck: x constant, exact
                    t_leave = self._stick_end(t, x, t_end)
                    pieces.append((t, t_leave, lambda tt, x=x: (x, 0.0), None))
                    events.append((t, "stick"))
                    if M is not None:
                        M = (M[0], M[1], 0.0, 0.0)           # diag(1, 0) M
                    t = t_leave
                    if t >= t_end:
                        break
                    events.append((t, "slip"))
                    d = self._slip_direction(t, x) or (1 if self._excess(t, x) < 0 else -1)
            else:
                d = 1 if v > 0 else -1
            friction = d * self.mu * self.g
            if self.closed_form:
                t_new, x, v, state, stopped, T = self._closed_slip(t, x, v, d, friction, t_end,
                                                                   M is not None)
                if M is not None:
                    t11, t12, t21, t22 = T
                    M = (t11 * M[0] + t12 * M[2], t11 * M[1] + t12 * M[3],
                         t21 * M[0] + t22 * M[2], t21 * M[1] + t22 * M[3])
            else:
                t_new, x, v, state, stopped = self._integrated_slip(t, x, v, d, friction, t_end)
            pieces.append((t, t_new, state, stopped))
            t = t_new
            if stopped:                                      # ẋ reached 0: exactly zero now
                v = 0.0
                events.append((t, "stop"))
                if M is not None:
                    a_before = self._acceleration(t, x, friction)
                    after = self._slip_direction(t, x)
                    a_after = 0.0 if after == 0 else self._acceleration(
                        t, x, after * self.mu * self.g)
                    if abs(a_before) > 1e-9 * self.g:
                        r = a_after / a_before               # diag(1, a⁺/a⁻) M
                        M = (M[0], M[1], r * M[2], r * M[3])
                    else:
                        M = None
        return pieces, events, None if M is None else np.array(M).reshape(2, 2), \
            np.array([x, v])

    def _acceleration(self, t, x, friction):
        """ẍ at rest (ẋ = 0) under the friction force `friction` (signed)."""
        return self.delta_st * self.omega_n**2 * math.cos(self.omega * t) \
            - self.omega_n**2 * x - friction

    def _closed_slip(self, t, x, v, d, friction, t_end, transition=True):
        """Slip in direction d from (t, x, v) until ẋ = 0 or t_end, in closed form: the
        first stop is bracketed on a grid of 128 points per forcing or damped-oscillation
        period, whichever is shorter, and refined by brentq. The phase's transition matrix
        comes last, as a row-major 4-tuple (None unless `transition`)."""
        state, phase_transition = self._segment(t, x, v, friction)
        shortest = min(self.period, 2 * math.pi / self.omega_n)
        n = max(8, int(math.ceil(128 * (t_end - t) / shortest)))
        grid = np.linspace(t, t_end, n + 1)
        dv = d * state(grid)[1]
        # From rest d·ẋ starts at 0 and rises: look for its first return to 0 after t.
        idx = np.flatnonzero(dv[1:] <= 0.0)
        stopped = idx.size > 0
        if stopped:
            k = idx[0] + 1
            lo = grid[k - 1] if k > 1 else t + 1e-9 * (grid[1] - t)
            f = lambda tt: d * state.velocity(tt)             # noqa: E731
            if f(lo) <= 0.0:
                lo = t + 1e-12 * (grid[1] - t)
            t_new = brentq(f, lo, grid[k], xtol=1e-15, rtol=4 * np.finfo(float).eps)
        else:
            t_new = t_end
        return t_new, state.position(t_new), state.velocity(t_new), state, stopped, \
            (phase_transition.entries(t_new) if transition else None)

    def _integrated_slip(self, t, x, v, d, friction, t_end):
        """The same for ζ ≥ 1, with scipy's event location on the dense output."""
        stop = lambda tt, y: y[1]                              # noqa: E731
        stop.terminal, stop.direction = True, -d
        s = solve_ivp(lambda tt, y: self.rhs(tt, y, friction), (t, t_end), [x, v],
                      method="DOP853", rtol=_RTOL, atol=_ATOL, events=stop, dense_output=True)
        if not s.success:
            raise ValueError(f"CoulombOscillator: the flow failed at t = {t}: {s.message}")
        return s.t[-1], float(s.y[0, -1]), float(s.y[1, -1]), lambda tt: tuple(s.sol(tt)), \
            s.status == 1

    def _stick_end(self, t0, x, t_end):
        """First time after t0 at which abs(x − δ cos ωt) reaches μg/ω_n² (or t_end)."""
        f = lambda tt: abs(self._excess(tt, x)) - self.limit
        grid = np.linspace(t0, t_end, 257)
        vals = np.abs(x - self.delta_st * np.cos(self.omega * grid)) - self.limit
        for k in np.flatnonzero((vals[:-1] < 0) & (vals[1:] >= 0)):
            a, b = grid[k], grid[k + 1]
            if f(a) < 0 <= f(b):                     # the scalar f brentq sees agrees
                root = brentq(f, a, b, xtol=1e-15, rtol=4 * np.finfo(float).eps)
                # At the root the net force is exactly zero; leave a hair (1e-13 T) later,
                # where it points the way out, so round-off cannot turn ẋ back and re-stick.
                return min(root + 1e-13 * self.period, t_end)
        return t_end


def equivalent_damping_amplitude(osc: CoulombOscillator) -> float:
    """Steady amplitude by equivalent viscous damping for continuous motion (Den Hartog):
    c_eq ω = 4 μ g / (π X) added to the linear resonance curve, solved for X."""
    wn, w, d = osc.omega_n, osc.omega, osc.delta_st
    F = d * wn**2
    fric = 4 * osc.mu * osc.g / math.pi
    # |(ω_n² − ω²) X| and (2ζω_n ω X + fric) add in quadrature to F.
    a = (wn**2 - w**2) ** 2 + (2 * osc.zeta * wn * w) ** 2
    b = 2 * (2 * osc.zeta * wn * w) * fric
    c = fric**2 - F**2
    disc = b * b - 4 * a * c
    return (-b + math.sqrt(disc)) / (2 * a) if disc >= 0 and a > 0 else math.nan


# Grid points of an impact pair's impact scan evaluated at a time (of 4000 a period).
_SCAN_CHUNK = 250


class ImpactPair(PeriodicProblem):
    """Seed 002, Fig. 5: m1 forced, m1 ẍ1 = −m1 ω² A cos(ωt + φ); m2 moves freely between two
    walls of m1 at clearance r and impacts when abs(x1 − x2) = r, with restitution e (eq. 17).

    Unknowns u = (x1(0), ẋ1(0), ẋ2(0), φ) with x2(0) = x1(0) (eq. 19); the residual is the
    4-vector x(0) − x(T) of (x1, ẋ1, x2, ẋ2) (eq. 18). Between impacts the motion is known in
    closed form, so impacts are roots of a closed-form function (brentq, to round-off).
    Units lb·s²/in and in (the paper's Table 3).
    """

    n = 4
    singular_jacobian = True          # x1(0) is free: the pair may be shifted as a whole
    # Shifting both masses, or giving both the same extra velocity, moves the whole motion
    # along without changing it relative to m1: a double multiplier 1 (a Jordan block).
    neutral_multipliers = 2

    def __init__(self, m1, m2, clearance, amplitude, omega, restitution):
        _positive("ImpactPair", m1=m1, m2=m2, clearance=clearance, amplitude=amplitude,
                  omega=omega)
        if not 0.0 <= restitution <= 1.0:
            raise ValueError(f"ImpactPair: `restitution` must be in [0, 1], got {restitution!r}")
        self.m1, self.m2, self.r = m1, m2, clearance
        self.A, self.omega, self.e = amplitude, omega, restitution
        self.u = m2 / m1
        self.period = 2 * math.pi / omega

    def initial_state(self, u):
        x1, v1, v2, phi = self.check(u)
        return np.array([x1, v1, x1, v2])

    def _segment(self, t0, s, phi):
        """Closed-form motion from state s = (x1, v1, x2, v2) at t0."""
        A, w = self.A, self.omega
        c1 = s[1] + A * w * math.sin(w * t0 + phi)
        c0 = s[0] - A * math.cos(w * t0 + phi) - c1 * t0

        def at(t):
            t = np.asarray(t, float)
            x1 = A * np.cos(w * t + phi) + c0 + c1 * t
            v1 = -A * w * np.sin(w * t + phi) + c1
            x2 = s[2] + s[3] * (t - t0)
            return np.stack([x1, v1, x2, np.full_like(t, s[3])], axis=-1)
        return at

    def flow(self, u, t_span=None, samples=400):
        u = self.check(u)
        return self.state_flow(self.initial_state(u), float(u[3]), t_span, samples)

    def floquet_matrix(self, u, rel_step=1e-6) -> np.ndarray:
        """∂y(T)/∂y(0) of the state y = (x1, ẋ1, x2, ẋ2) at the fixed phase φ of `u`
        (central differences; the perturbed flows meet the same impacts, so the saltation
        at each impact is included). Its eigenvalues are the Floquet multipliers. (The
        shooting Jacobian ∂y(T)/∂u is not a state-to-state map: u holds φ instead of x2.)"""
        from .solve import central_jacobian
        u = self.check(u)
        phi = float(u[3])
        return central_jacobian(lambda y: self.state_flow(y, phi).x[-1],
                                self.initial_state(u), rel_step)

    def state_flow(self, y0, phi, t_span=None, samples=400) -> Trajectory:
        """The motion from any state y0 = (x1, ẋ1, x2, ẋ2) at phase φ (abs(x1 − x2) ≤ r)."""
        t, t_end = t_span or (0.0, self.period)
        s = np.array(y0, float)
        ts, xs, events = [np.array([t])], [s[None, :].copy()], []
        self.flows += 1
        dt = self.period / 4000
        A, w = self.A, self.omega
        for _ in range(10000):
            seg = self._segment(t, s, phi)
            # x1 − x2 in closed form: scalar math for brentq (~50 calls per impact), numpy's
            # cos for the scan's grid.
            c1 = s[1] + A * w * math.sin(w * t + phi)
            c0 = s[0] - A * math.cos(w * t + phi) - c1 * t
            def d(tt, cos=math.cos, c0=c0, c1=c1, t0=t, x2=s[2], v2=s[3]):
                return A * cos(w * tt + phi) + c0 + c1 * tt - x2 - v2 * (tt - t0)
            # Scan the relative displacement on a grid of step T/4000 for the first crossing
            # of either wall from inside (right after an impact d sits on the wall and moves
            # in), in chunks growing from `_SCAN_CHUNK` points: the next impact is usually
            # near, and each chunk costs mostly numpy's per-call overhead.
            hit, wall = None, 0
            full = np.append(np.arange(t, t_end, dt), t_end)
            last = full.size - 1
            k0, size = 0, _SCAN_CHUNK
            while hit is None and k0 < last:
                k1 = min(k0 + size, last)
                grid = full[k0:k1 + 1]
                D = d(grid, np.cos)
                inside = np.abs(D) < self.r
                k = np.flatnonzero(inside[:-1] > inside[1:])
                if k.size:
                    k = k[0]
                    wall = 1 if D[k + 1] > 0 else -1
                    hit = brentq(lambda tt: wall * d(tt) - self.r, grid[k], grid[k + 1],
                                 xtol=1e-15, rtol=4 * np.finfo(float).eps)
                k0, size = k1, 2 * size
            end = hit if hit is not None else t_end
            tt = np.linspace(t, end, max(3, int(samples * (end - t) / self.period)))
            part = seg(tt[1:])
            ts.append(tt[1:])
            xs.append(part)
            if hit is None:
                break
            _, v1, x2, v2 = seg(hit).tolist()
            uu, e = self.u, self.e
            s = np.array([x2 + wall * self.r,                   # exactly on the wall
                          (1 - uu * e) / (1 + uu) * v1 + (uu + uu * e) / (1 + uu) * v2,  # eq. 17
                          x2, (1 + e) / (1 + uu) * v1 + (uu - e) / (1 + uu) * v2])
            part[-1] = s
            events.append((hit, "impact+" if wall > 0 else "impact-"))
            t = hit
        else:
            raise ValueError("ImpactPair: more than 10000 impacts in one period (chatter)")
        return Trajectory(np.concatenate(ts), np.concatenate(xs), events)

    def residual(self, u):
        traj = self.flow(u)
        return traj.x[0] - traj.x[-1]

    def mode(self, u) -> tuple[int, int]:
        """(n, m): impacts on the one wall, then on the other, in one period."""
        ev = [k for _, k in self.flow(u).events]
        return (ev.count("impact+"), ev.count("impact-"))
