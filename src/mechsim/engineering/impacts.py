"""Running a mechanism with end stops (`mechsim.model.stops.Stop`): free motion between
impacts, each impact located in time by the run's events (`mechsim.run`) and resolved by
Newton's restitution law through the constrained mass matrix, and resting contact held as
a constraint (a driver holding the joint at its limit) while the stop pushes.

A run with stops is a sequence of runs of `mechsim.solver.simulate`, joined into one
result: the samples of the output grid and one at each impact (its state before the
impact), the impacts in `SimulationResult.impacts`, and the energy they took as a work
channel "impacts" of the energy log, so its balance stays at the solver's accuracy.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..model import Driver, Mechanism, ModelError
from ..solver import output_times, simulate
from .geometry import joint_coordinates


# Impacts, holds and releases at one instant, in a row, after which the run gives up
# there (a contact that cannot be resolved) instead of switching for ever.
MAX_STILL = 50


@dataclass(frozen=True)
class Impact:
    """An impact on a stop: time [s], the stop's name, the limit hit, the joint's rate
    before and after it (rad/s or m/s), the kinetic energy it took [J], and whether the
    joint came to rest on the stop."""
    t: float
    stop: str
    limit: float
    rate_before: float
    rate_after: float
    energy_lost: float
    resting: bool


class StopEvents:
    """The run's events (`Settings.events`): for each limit watched, its distance sign·(s −
    limit) (≥ 0 while the joint is clear of it); for each stop holding its joint, the push
    sign·effort of its holding driver (≥ 0 while the stop pushes)."""

    def __init__(self, problem, free, held):
        self.problem, self.free, self.held = problem, free, held

    def values(self, t, q, v):
        p = self.problem
        out = [sign * (joint_coordinates(p.joints[stop.joint.name], q, v)[0][0] - limit)
               for stop, sign, limit in self.free]
        if self.held:
            lam = p.multipliers(np.array([t]), np.asarray(q)[None], np.asarray(v)[None]).lam[0]
            out += [-sign * lam[p.rows_of(driver)[0]] for _, sign, _, driver in self.held]
        return np.array(out)

    def describe(self, i) -> str:
        if i < len(self.free):
            stop, sign, limit = self.free[i]
            return f"joint '{stop.joint.name}' reached stop '{stop.name}' at {limit:g}"
        stop = self.held[i - len(self.free)][0]
        return f"stop '{stop.name}' let joint '{stop.joint.name}' go"


def simulate_with_stops(mech, report, t_end, method=None, **options):
    """`Mechanism.simulate` for a mechanism with stops from its assembled state `report`
    (see the module docstring)."""
    from ..results.result import join
    if options.get("stream") is not None:
        raise ModelError(f"mechanism '{mech.name}': a run with stops is a sequence of runs "
                         "joined in memory; it cannot be streamed (simulate without `stream`)")
    t = float(options.pop("t_start", 0.0))
    output_step = options.pop("output_step", None)
    grid = output_times(t, t_end, output_step)
    q, v = report.q, report.v
    problem = mech.problem()
    for stop in mech.stops:
        s = joint_coordinates(problem.joints[stop.joint.name], q, v)[0][0]
        stop.check_start(s)
    held: list = []                       # (stop, sign, limit) holding their joints
    released: list = []                   # let go at the present time: not held again
    built: dict = {}
    pieces, impacts = [], []
    stalled = 0                           # switches in a row without time passing
    failure = ""
    while True:
        model, drivers = _held_model(mech, held, built)
        p = model.problem()
        free = [(stop, sign, limit) for stop in mech.stops for sign, limit in stop.limits()
                if not any(h[0] is stop and h[2] == limit for h in held)]
        clear = [f for f in free if f not in released]
        touching = _pressing(p, clear, t, q, v)
        if touching is not None and stalled >= MAX_STILL:
            failure = (f"the stops switched {stalled} times at t = {t:.9g} without the "
                       "motion going on: their contacts cannot be resolved there")
            break
        if touching is not None:
            touching = free.index(clear[touching])
            v, impact = _impact(p, *free[touching], t, q, v)   # at a limit, going into it
            impacts.append(impact)
            stalled += 1
            if impact.resting:
                held.append(free[touching])
            continue
        events = StopEvents(p, free, [(*h, d) for h, d in zip(held, drivers)])
        here = None if grid is None else np.concatenate([[t], grid[grid > t + 1e-12 *
                                                                      max(1.0, abs(t))]])
        res = simulate(p, q, v, t_start=t, t_end=t_end, method=method, output_grid=here,
                       events=events, mechanism=mech, **options)
        pieces.append(res)
        if res.event is None or not res.success:
            break
        t_was = t
        t, i, q, v = res.event
        if t > t_was:
            stalled, released = 0, []
        else:
            stalled += 1
        if stalled >= MAX_STILL:
            failure = (f"the stops switched {stalled} times at t = {t:.9g} without the "
                       f"motion going on ({events.describe(i)}): their contacts cannot be "
                       "resolved there")
            break
        if i < len(free):
            stop, sign, limit = free[i]
            v, impact = _impact(p, stop, sign, limit, t, q, v)
            impacts.append(impact)
            if impact.resting:
                held.append((stop, sign, limit))
        else:
            released.append(held.pop(i - len(free)))
    if not pieces:
        raise ModelError(f"mechanism '{mech.name}': {failure}")
    out = pieces[0]
    for rest in pieces[1:]:
        out = join(out, rest)
    out.mechanism, out.impacts = mech, impacts
    out.settings = {}                 # `extend` would run without the stops
    if failure:
        out.status, out.message = "failed", failure
    elif out.success and impacts:
        out.message += f"; {len(impacts)} impact(s) on the stops"
    _impact_work(out, impacts)
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
            if sign * float(_gradient(geometry, q) @ qdd) < 0.0:
                return k
    return None


def _gradient(geometry, q) -> np.ndarray:
    """∂s/∂q of the joint's coordinate at q, shape (n,): its rate along each unit velocity."""
    n = len(q)
    return joint_coordinates(geometry, np.repeat(np.asarray(q)[None], n, axis=0), np.eye(n))[1]


def _held_model(mech, held, built):
    """(the mechanism with a driver holding each joint of `held` at its limit, those
    drivers), made once per set of held stops."""
    if not held:
        return mech, []
    key = tuple((id(stop), limit) for stop, _, limit in held)
    if key not in built:
        other = Mechanism(mech.name, gravity=mech.gravity)
        other.ground = mech.ground                    # the joints' ground
        drivers = [Driver(stop.joint, repr(float(limit - stop.joint.initial_coordinate())),
                          name=f"held by {stop.name}") for stop, _, limit in held]
        for item in mech.bodies + mech.joints + mech.drivers + mech.gears + mech.loads + \
                drivers:
            other.add(item)
        built[key] = (other, [d.name for d in drivers])
    return built[key]


def _impact(problem, stop, sign, limit, t, q, v):
    """(velocities after the impact, `Impact`): Newton's law on the joint's rate through
    the constrained mass matrix (`NumericProblem.project_velocities` with the joint's
    gradient as an extra row), or the rate brought to 0 where the joint comes to rest."""
    gradient = _gradient(problem.joints[stop.joint.name], q)
    before = float(gradient @ v)
    after = -stop.restitution * before
    resting = stop.restitution == 0.0 or abs(after) < stop.rest_speed
    target = 0.0 if resting else after
    v_after = problem.project_velocities(q, v, t, extra=(gradient[None], np.array([target])))
    lost = problem.kinetic_energy(q, v) - problem.kinetic_energy(q, v_after)
    if not np.all(np.isfinite(v_after)):
        raise ModelError(f"stop '{stop.name}': the impact at t = {t:.9g} has no solution "
                         "(the joint cannot move without the others)")
    return v_after, Impact(float(t), stop.name, float(limit), before, float(gradient @ v_after),
                           float(lost), resting)


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
