"""Running a mechanism with end stops (`mechsim.model.stops.Stop`) or joints with friction
(`mechsim.model.friction.Friction`): smooth motion between events, each located in time by
the run's events (`mechsim.run.loop`). An impact on a stop is resolved by Newton's restitution
law through the constrained mass matrix, and resting contact held by the stop's force,
which keeps the joint still (`mechsim.problem.friction`: the same model, no other
mechanism built) while it pushes; a joint with friction sticks or slips as
`mechsim.engineering.friction` decides. The stop's force is a reaction like any other:
the joints' forces of a resting mechanism carry what the stop does not.

Such a run is a sequence of runs of `mechsim.run.solver.simulate`, joined into one result:
the samples of the output grid and one at each event (its state before it), the impacts
in `SimulationResult.impacts` and the energy they took as a work channel "impacts" of the
energy log, so its balance stays at the solver's accuracy; the friction's switches in
`SimulationResult.friction_switches`, its work a channel of its own.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from ..model import ModelError
from ..records import Status
from ..problem.friction import BACKWARD, FORWARD, STUCK, FrictionError
from ..run.solver import output_times, simulate
from ..problem.friction_sensitivity import accelerations as _accelerations
from .friction import (MODE_NAMES, FrictionEvents, FrictionSwitch, decide, initial_modes,
                       stop_element, stop_moving)
from ..problem.geometry import joint_coordinates, joint_gradient, joint_wrench


# Impacts, holds and releases at one instant, in a row, after which the run gives up
# there (a contact that cannot be resolved) instead of switching for ever.
MAX_STILL = 50
# A joint arriving at its stop slower than this (relative to the fastest coordinate's
# rate) was pressed onto it at rest: no impact time to differentiate.
PRESSED = 1e-9


@dataclass(frozen=True)
class Impact:
    """An impact on a stop: time [s], the stop's name, the limit hit, the joint's rate
    before and after it (rad/s or m/s), the kinetic energy it took [J], whether the joint
    came to rest on the stop, the stop's impulse on body_b along the joint's coordinate
    (N·m·s or N·s) and each joint's impulsive reaction, the impulse [N·s] it gave its
    body_b ({joint name: [x, y]}, global axes; minimum-norm where redundant) and, in a run
    carrying sensitivities, the impact time's to each Parameter ({name: dt/dk})."""
    t: float
    stop: str
    limit: float
    rate_before: float
    rate_after: float
    energy_lost: float
    resting: bool
    impulse: float = 0.0
    joint_impulses: dict = field(default_factory=dict)
    time_sensitivity: dict = field(default_factory=dict)


class StopEvents:
    """The run's events (`Settings.events`): for each limit watched, its distance sign·(s −
    limit) (≥ 0 while the joint is clear of it); for each stop holding its joint, the push
    sign·f of its holding force (≥ 0 while the stop pushes)."""

    def __init__(self, problem, free, held):
        self.problem, self.free, self.held = problem, free, held

    @property
    def size(self) -> int:
        return len(self.free) + len(self.held)

    def values(self, t, q, v):
        p = self.problem
        out = [sign * (joint_coordinates(p.joints[stop.joint.name], q, v)[0][0] - limit)
               for stop, sign, limit in self.free]
        if self.held:
            forces = p.friction_state(t, q, v).forces
            out += [sign * forces[stop_element(p, stop)] for stop, sign, _ in self.held]
        return np.array(out)

    def describe(self, i) -> str:
        if i < len(self.free):
            stop, sign, limit = self.free[i]
            return f"joint '{stop.joint.name}' reached stop '{stop.name}' at {limit:g}"
        stop = self.held[i - len(self.free)][0]
        return f"stop '{stop.name}' let joint '{stop.joint.name}' go"


class Joined:
    """Several event sources as one (`Settings.events`): their values side by side."""

    def __init__(self, parts):
        self.parts = [p for p in parts if p is not None]

    def values(self, t, q, v):
        return np.concatenate([np.asarray(p.values(t, q, v), float) for p in self.parts])

    def locate(self, i):
        """(the source, its own index) of the joined index i."""
        for part in self.parts:
            if i < part.size:
                return part, i
            i -= part.size
        raise IndexError(i)

    def describe(self, i) -> str:
        part, k = self.locate(i)
        return part.describe(k)


def simulate_with_stops(mech, report, t_end, method=None, sensitivities=None, **options):
    """`Mechanism.simulate` for a mechanism with stops or joints with friction from its
    assembled state `report` (see the module docstring). `sensitivities`: (a
    `MotionEquations`, ∂q0/∂k, ∂v0/∂k) carried through the pieces, across the impacts
    (`mechsim.engineering.impact_sensitivity`), the holds and the friction's switches
    (`mechsim.problem.friction_sensitivity`), unless a joint is pressed onto a stop at
    rest or a held joint is let go under loads given in time: there they end."""
    if options.get("stream") is not None:
        raise ModelError(f"mechanism '{mech.name}': a run with stops or friction is a "
                         "sequence of runs joined in memory; it cannot be streamed "
                         "(simulate without `stream`)")
    return PiecewiseRun(mech, report.q, report.v, t_end, method, options,
                        sensitivities=sensitivities).run()


class PiecewiseRun:
    """The pieces of a run with stops and friction, from one event to the next: the stops
    its joints rest on (`held`: (stop, sign, limit)), the mode of every element of the
    problem's `FrictionModel` (`modes`: each friction's and each stop's), what happened at
    each event (`impacts`, `switches`) and the pieces' results; the sensitivities carried
    (`carried`: (q_k, v_k) at the present instant, None once they end)."""

    def __init__(self, mech, q, v, t_end, method, options, contacts=None, sensitivities=None):
        self.mech, self.t_end, self.method = mech, t_end, method
        self.t = float(options.pop("t_start", 0.0))
        self.output_step = options.pop("output_step", None)
        self.grid = output_times(self.t, t_end, self.output_step)
        self.options = options
        self.q, self.v = np.asarray(q, float), np.asarray(v, float)
        self.problem = problem = mech.problem()
        for stop in mech.stops:
            stop.check_start(joint_coordinates(problem.joints[stop.joint.name], self.q,
                                               self.v)[0][0])
        self.released = []
        if contacts is None:
            self.held = []
            try:
                self.modes = initial_modes(problem, self.t, self.q, self.v)
            except FrictionError as exc:
                raise ModelError(f"mechanism '{mech.name}': at the start, {exc}") from None
        else:                                # where an earlier run left them (`contacts`)
            stops = {stop.name: stop for stop in mech.stops}
            self.held = [(stops[name], sign, limit) for name, sign, limit in contacts["held"]]
            self.modes = np.array(contacts["modes"], int)
        self.pieces, self.impacts, self.switches, self.schedule = [], [], [], []
        self.stalled, self.failure = 0, ""
        self.equations, self.carried, self.uncarried = None, None, ""
        self.holds = {}          # stop name: (t, dt/dk) of the impact that began its hold
        if sensitivities is not None:
            self.equations, self.carried = sensitivities[0], tuple(sensitivities[1:])
            if not np.all(np.isfinite(self.carried[0])):    # they ended in an earlier run
                self.carried = None
                self.uncarried = "the sensitivities ended in the run this one extends"

    def moded(self):
        """The problem with every element in its present mode."""
        return self.problem.with_friction(self.problem.friction.with_modes(self.modes))

    def piece_problem(self):
        """(the problem of the present piece, its free limits)."""
        p = self.moded()
        free = [(stop, sign, limit) for stop in self.mech.stops
                for sign, limit in stop.limits()
                if not any(h[0] is stop and h[2] == limit for h in self.held)]
        return p, free

    def remode(self, p) -> None:
        """Every element's mode anew at the present state (after an impulse or a release)."""
        self.modes = initial_modes(p, self.t, self.q, self.v,
                                   [stop_element(p, h[0]) for h in self.held])

    def contacts(self) -> dict:
        """The modes and held stops as data (JSON): where a later run goes on from."""
        return {"modes": [int(m) for m in self.modes],
                "held": [[stop.name, float(sign), float(limit)] for stop, sign, limit in
                         self.held]}

    def run(self):
        from ..threads import run_threads
        with run_threads():                   # once for all the pieces
            try:
                while self.step():
                    pass
            except FrictionError as exc:      # at an event: the run ends with what it has
                self.failure = str(exc)
        if not self.pieces:
            raise ModelError(f"mechanism '{self.mech.name}': {self.failure}")
        return self.result()

    def step(self) -> bool:
        """Resolve what happens at the present instant, or run to the next event; False
        where the run is over."""
        p, free = self.piece_problem()
        t, q, v = self.t, self.q, self.v
        clear = [f for f in free if f not in self.released]
        touching = _pressing(p, clear, t, q, v)
        if touching is not None:
            if self.stalled >= MAX_STILL:
                self.failure = (f"the stops switched {self.stalled} times at t = {t:.9g} "
                                "without the motion going on: their contacts cannot be "
                                "resolved there")
                return False
            self.stalled += 1
            self.hit(p, free[free.index(clear[touching])])
            return True
        stops = StopEvents(p, free, self.held) if self.mech.stops else None
        friction = FrictionEvents(p, self.modes) if self.mech.frictions else None
        events = Joined([stops, friction])
        here = None if self.grid is None else np.concatenate(
            [[t], self.grid[self.grid > t + 1e-12 * max(1.0, abs(t))]])
        carried = None if self.carried is None else \
            (self.equations.for_problem(p), *self.carried)
        res = simulate(p, q, v, t_start=t, t_end=self.t_end, method=self.method,
                       output_grid=here, events=events, mechanism=self.mech,
                       sensitivities=carried, **self.options)
        self.pieces.append(res)
        if carried is not None:
            self.carried = (res.sensitivities.q[-1], res.sensitivities.v[-1])
        self.schedule.append((float(res.t[-1]), self.modes.copy()))
        if res.event is None or not res.success:
            return False
        self.t, i, self.q, self.v = res.event
        if self.t > t:
            self.stalled, self.released = 0, []
        else:
            self.stalled += 1
        if self.stalled >= MAX_STILL:
            self.failure = (f"the contacts switched {self.stalled} times at t = "
                            f"{self.t:.9g} without the motion going on "
                            f"({events.describe(i)}): they cannot be resolved there")
            return False
        part, k = events.locate(i)
        if part is friction:
            self.switch(p, part.indices[k])
        elif k < len(free):
            self.hit(p, free[k])
        else:
            held = self.held.pop(k - len(free))
            self.released.append(held)
            self.remode(p)
            if self.carried is not None:
                self._carry_release(p, held)
        return True

    def hit(self, p, limit):
        """The impact on the stop limit (stop, sign, value) at the present state."""
        v_before = self.v
        self.v, impact = _impact(p, *limit, self.t, self.q, self.v)
        if impact.resting:
            self.held.append(limit)
        self.remode(p)                                # the impulse moved every joint
        if self.carried is not None:
            impact = self._carry_across(p, limit[0], impact, v_before)
        self.impacts.append(impact)

    def _carry_across(self, p, stop, impact, v_before):
        """The sensitivities carried across `impact` (its time's kept on it), where the
        joint comes to rest as a plastic impact's (e = 0); a joint pressed onto its stop
        at rest (no impact's time to differentiate) ends them here, and the result says
        so."""
        if impact.resting and not abs(impact.rate_before) > PRESSED * max(
                1.0, float(np.max(np.abs(v_before)))):
            self._end(f"where joint '{stop.joint.name}' was pressed onto stop "
                      f"'{stop.name}' at rest (not differentiated)")
            return impact
        from .impact_sensitivity import impact_jump
        after = self.moded()
        Sq, Sv, dt = impact_jump(p, self.equations, p.joints[stop.joint.name],
                                 0.0 if impact.resting else stop.restitution, self.t,
                                 self.q, v_before, self.v, *self.carried, after=after)
        self.carried = (Sq, Sv)
        if impact.resting:
            self.holds[stop.name] = (self.t, dt)
        return replace(impact, time_sensitivity={
            name: float(x) for name, x in zip(self.equations.names, dt)})

    def _carry_release(self, p, held):
        """The sensitivities carried across the stop `held` letting its joint go (where
        its push reached zero); ended where that depends on time explicitly."""
        from ..problem.friction_sensitivity import switch_jump
        stop, sign, _ = held
        after = self.moded()
        since = self.holds.pop(stop.name, None)
        if since is not None and since[0] == self.t:
            # Let go at the instant it came to rest (its push a pull at once): the
            # release moves with the impact, and the motion after it is the free one.
            a_held = _accelerations(p, self.t, self.q, self.v)
            a_free = _accelerations(after, self.t, self.q, self.v)
            self.carried = (self.carried[0],
                            self.carried[1] + np.outer(a_held - a_free, since[1]))
            return
        jump = switch_jump(self.equations.for_problem(p), self.equations.for_problem(after),
                           stop_element(p, stop), self.t, self.q, self.v, self.v,
                           *self.carried, push=sign)
        if jump is None:
            self._end(f"where stop '{stop.name}' let joint '{stop.joint.name}' go under "
                      "loads or drivers given as functions of time (not differentiated)")
            return
        self.carried = (self.carried[0], jump[0])

    def _end(self, where: str) -> None:
        """The sensitivities end at the present instant; the result says `where`."""
        self.carried = None
        self.uncarried = (f"the sensitivities end at t = {self.t:.9g}, {where}; later "
                          "samples hold NaN")

    def switch(self, p, k):
        """Friction element k's joint reached zero rate (sliding) or its limit (stuck)."""
        before, v_before = self.modes[k], self.v
        if before == STUCK:
            state = p.friction_state(self.t, self.q, self.v)
            force = state.forces[k]
            limit = state.static_limit(p.friction, k)
            after = BACKWARD if force > 0.0 else FORWARD
        else:
            after, (force, limit) = decide(p, self.modes, k, self.t, self.q, self.v)
            if after == STUCK:
                self.v = stop_moving(p, k, self.t, self.q, self.v)
        self.modes[k] = after
        switch = FrictionSwitch(float(self.t), p.friction.elements[k].name,
                                MODE_NAMES[before], MODE_NAMES[after], float(force),
                                float(limit))
        if self.carried is not None:
            switch = self._carry_switch(p, k, switch, v_before)
        self.switches.append(switch)

    def _carry_switch(self, p, k, switch, v_before):
        """The sensitivities carried across friction element k's `switch` (its time's kept
        on it: `mechsim.problem.friction_sensitivity.switch_jump`); where its event
        depends on time explicitly they end here, and the result says so."""
        from ..problem.friction_sensitivity import switch_jump
        after = self.moded()
        jump = switch_jump(self.equations.for_problem(p), self.equations.for_problem(after),
                           k, self.t, self.q, v_before, self.v, *self.carried)
        if jump is None:
            self._end(f"where friction '{switch.friction}' let its joint slip under loads "
                      "or drivers given as functions of time (not differentiated)")
            return switch
        Sv, dt = jump
        self.carried = (self.carried[0], Sv)
        return replace(switch, time_sensitivity={
            name: float(x) for name, x in zip(self.equations.names, dt)})

    def result(self):
        from ..results.join import join
        # A piece that ended where it began (a mode tried and changed at once) adds no
        # motion, only a second sample at that instant: left out, with its modes (but the
        # last, whose status ends the run).
        last = len(self.pieces) - 1
        kept = [i for i, p in enumerate(self.pieces) if p.t[-1] > p.t[0] or i == last]
        if self.equations is not None:
            self._unknown_sensitivities()
        self.schedule = [self.schedule[i] for i in kept]
        out = self.pieces[kept[0]]
        for i in kept[1:]:
            out = join(out, self.pieces[i])
        out.mechanism, out.impacts, out.friction_switches = \
            self.mech, self.impacts, self.switches
        # What `SimulationResult.extend` goes on with: the settings, every element's mode
        # and the stops the joints rest on at the end
        out.settings = dict(self.pieces[-1].settings, method=self.method,
                            output_step=self.output_step, contacts=self.contacts())
        out.continuation = extend_piecewise
        # each sample's forces, reactions and work with the modes its piece ran in
        out.problem = self.problem.with_friction(
            self.problem.friction.with_schedule(self.schedule))
        if self.equations is not None and out.sensitivities is not None:
            # q̈_k at the samples in the modes each piece ran in
            out.sensitivities.equations = self.equations.for_problem(out.problem)
        if self.failure:
            out.status, out.message = Status.FAILED, self.failure
        elif out.success and self.impacts:
            out.message += f"; {len(self.impacts)} impact(s) on the stops"
        if out.success and self.switches:
            out.message += f"; {len(self.switches)} stick-slip switch(es)"
        if self.uncarried:
            out.message += "; " + self.uncarried
        _impact_work(out, self.impacts)
        return out

    def _unknown_sensitivities(self):
        """The pieces run after the sensitivities ended hold NaN for them, so that the
        joined result's table spans all its samples."""
        from ..problem.sensitivity import MotionSensitivities
        width = self.equations.width
        for piece in self.pieces:
            if piece.sensitivities is None:
                piece.sensitivities = MotionSensitivities(
                    self.equations, piece.t, piece.q, piece.v,
                    np.full((len(piece.t), width), np.nan), lam=lambda: None,
                    accelerations=piece.accelerations)


def extend_piecewise(result, t_end, overrides):
    """`SimulationResult.extend` of a run with stops or friction: the run goes on from its
    last state with the modes and held stops it ended with, joined into one result."""
    from ..results.join import join
    from ..problem.sensitivity import MotionSensitivities
    settings = {**result.settings, **overrides}
    contacts, method = settings.pop("contacts"), settings.pop("method", None)
    table = result.sensitivities
    carried = (table.equations, table.q[-1], table.v[-1]) \
        if isinstance(table, MotionSensitivities) else None
    rest = PiecewiseRun(result.mechanism, result.q[-1], result.v[-1], t_end, method,
                        dict(settings, t_start=float(result.t[-1])), contacts,
                        sensitivities=carried).run()
    out = join(result, rest)
    out.mechanism, out.settings = result.mechanism, rest.settings
    out.continuation = extend_piecewise
    out.impacts = result.impacts + rest.impacts
    out.friction_switches = result.friction_switches + rest.friction_switches
    friction = result.problem.friction
    out.problem = result.problem.with_friction(
        friction.with_schedule(friction.schedule + rest.problem.friction.schedule))
    _impact_work(out, out.impacts)
    return out


def _pressing(problem, free, t, q, v):
    """The index of a limit in `free` the joint sits at (within 1e-9) while moving into
    it, or at rest and accelerated into it; else None."""
    qdd = None
    for k, (stop, sign, limit) in enumerate(free):
        geometry = problem.joints[stop.joint.name]
        s, rate = (x[0] for x in joint_coordinates(geometry, q, v))
        if abs(s - limit) > 1e-9 * max(1.0, abs(limit)):
            continue
        if sign * rate < -1e-12:
            return k
        if sign * rate <= 1e-12:
            if qdd is None:
                _, J, _, gamma = problem.terms(q, v, t)
                qdd = problem.accelerations(J, problem.forces(t, q, v), gamma, q)[0]
            if sign * float(joint_gradient(geometry, q) @ qdd) < 0.0:
                return k
    return None


def _impact(problem, stop, sign, limit, t, q, v):
    """(velocities after the impact, `Impact`): Newton's law on the joint's rate through
    the constrained mass matrix (`NumericProblem.project_velocities` with the joint's
    gradient as an extra row), or the rate brought to 0 where the joint comes to rest."""
    gradient = joint_gradient(problem.joints[stop.joint.name], q)
    before = float(gradient @ v)
    after = -stop.restitution * before
    resting = stop.restitution == 0.0 or abs(after) < stop.rest_speed
    target = 0.0 if resting else after
    v_after = problem.project_velocities(q, v, t, extra=(gradient[None], np.array([target])))
    lost = problem.kinetic_energy(q, v) - problem.kinetic_energy(q, v_after)
    if not np.all(np.isfinite(v_after)):
        raise ModelError(f"stop '{stop.name}': the impact at t = {t:.9g} has no solution "
                         "(the joint cannot move without the others)")
    impulse, joints = _impulses(problem, t, q, v_after - v, gradient)
    return v_after, Impact(float(t), stop.name, float(limit), before, float(gradient @ v_after),
                           float(lost), resting, impulse, joints)


def _impulses(problem, t, q, dv, gradient):
    """(the stop's impulse ν along the joint's coordinate, {joint: its impulse on body_b})
    of the velocity jump dv: M dv = −Φ_qᵀ Λ + g ν (least squares, minimum norm), the
    joints' impulses their wrench of Λ (`joint_wrench`)."""
    A = np.column_stack([-problem.phi_q(q, t).T, gradient])
    x = np.linalg.lstsq(A, problem.mass(q) @ dv, rcond=None)[0]
    joints = {}
    for name, g in problem.joints.items():
        rows = problem.rows_of(name)
        force, _ = joint_wrench(g, q[None], x[rows][None])
        joints[name] = [float(force[0, 0]), float(force[0, 1])]
    return float(x[-1]), joints


def _impact_work(res, impacts) -> None:
    """The energy the impacts took, as a work channel "impacts" of `res.energy`: minus
    their sum up to each sample (a sample at an impact's time is its state before it)."""
    if not impacts:
        return
    from ..results.result import EnergyLog
    energy = res.energy
    times = np.array([i.t for i in impacts])
    lost = np.array([i.energy_lost for i in impacts])
    taken = -np.array([lost[times < tk].sum() for tk in res.t])
    work_by = np.column_stack([energy.work_by if energy.work_by is not None else
                               np.zeros((len(res.t), 0)), taken])
    res.__dict__["energy"] = EnergyLog(
        energy.kinetic, energy.potential, energy.strain, work_by=work_by,
        channels=tuple(energy.channels) + ("impacts",),
        includes=energy.includes + "; the kinetic energy the impacts on the stops took")
