"""The same mechanisms in MuJoCo and Exudyn, for `mechsim bench peers`: work against
precision beside mechsim's, each peer modelled as its own documentation recommends (the
`peers` extra: pip install '.[peers]').

- MuJoCo: the bodies in a kinematic tree of hinges about z (a spanning tree of the pins
  from the ground), the pins that close loops as `connect` equalities, stiff (solimp
  0.9999, solref time constant 2 dt, as its documentation advises for hard equality
  constraints), contacts off; integrators "implicitfast" and "RK4" at fixed steps.
- Exudyn: rigid 2D bodies on `NodeRigidBody2D` nodes, `ObjectJointRevolute2D` pins, gravity
  as `LoadMassProportional`, its default implicit generalized-α solver (spectral radius
  0.8) at fixed steps, with its sparse linear solver above 1000 coordinates (as it
  advises there).

Each run traces one body point, sampled every `output_step`; its error is measured as the
bench measures mechsim's (`mechsim.app.bench.Problem.point_error`). Times are the integration
alone (model building excluded for all three tools).

Beside them, on the parallelogram-family problems (a crank angle whose exact motion is one
equation, M_eff θ̈ = −K cos θ), scipy's DOP853 on that equation at rtol 1e-2 … 1e-12
("exact 1-DOF DOP853"; its row's `step` is the rtol): what the same motion costs without
constraints, the floor a mechanism simulator is measured against.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class PeerRow:
    problem: str
    tool: str            # "mujoco implicitfast", "mujoco RK4", "exudyn"
    step: float          # the fixed step [s] (the rtol for "exact 1-DOF DOP853")
    error: float
    wall_time: float


def spanning_tree(mech):
    """({id(body): (parent body, pin)}, bodies in tree order, the pins that close loops)."""
    parent, order, rest = {id(mech.ground): None}, [], list(mech.joints)
    grew = True
    while grew:
        grew = False
        for j in list(rest):
            for a, b in ((j.body_a, j.body_b), (j.body_b, j.body_a)):
                if id(a) in parent and id(b) not in parent:
                    parent[id(b)] = (a, j)
                    order.append(b)
                    rest.remove(j)
                    grew = True
                    break
    return parent, order, rest


def _check(mech):
    kinds = {j.kind for j in mech.joints}
    if kinds - {"revolute"} or any(len(b.coordinate_names) != 3 for b in mech.bodies):
        raise ValueError(f"peers: mechanism '{mech.name}' has joints or bodies the peer "
                         "models here do not cover (revolute joints and rigid bodies only)")


def mujoco_xml(mech, dt, integrator, trace) -> str:
    """The MJCF of `mech` (see the module docstring), with a site "trace" at `trace` =
    (body name, local point)."""
    _check(mech)
    parent, order, closing = spanning_tree(mech)
    children: dict = {}
    for b in order:
        children.setdefault(id(parent[id(b)][0]), []).append(b)

    def pose(b):
        if b is mech.ground:
            return np.zeros(2), 0.0
        return np.asarray(b.position, float), float(b.angle)

    def local(b, point):
        p, th = pose(b)
        c, s = math.cos(th), math.sin(th)
        d = np.asarray(point, float) - p
        return float(c * d[0] + s * d[1]), float(-s * d[0] + c * d[1])

    def body(b):
        up, pin = parent[id(b)]
        x, y = local(up, pose(b)[0])
        ax, ay = local(b, pin.at)
        site = ""
        if b.name == trace[0]:
            site = f'<site name="trace" pos="{float(trace[1][0])!r} {float(trace[1][1])!r} 0"/>'
        inner = "".join(body(c) for c in children.get(id(b), []))
        inertia = float(b.inertia)
        return (f'<body name="b{id(b)}" pos="{x!r} {y!r} 0" '
                f'euler="0 0 {pose(b)[1] - pose(up)[1]!r}">'
                f'<inertial pos="0 0 0" mass="{float(b.mass)!r}" '
                f'diaginertia="{inertia!r} {inertia!r} {inertia!r}"/>'
                f'<joint name="j{id(pin)}" type="hinge" axis="0 0 1" pos="{ax!r} {ay!r} 0"/>'
                f'{site}{inner}</body>')

    def named(b):
        return "world" if b is mech.ground else f"b{id(b)}"

    loops = "".join(f'<connect body1="{named(j.body_a)}" body2="{named(j.body_b)}" '
                    f'anchor="{local(j.body_a, j.at)[0]!r} {local(j.body_a, j.at)[1]!r} 0"/>'
                    for j in closing)
    g = [float(x) for x in mech.gravity]
    tree = "".join(body(c) for c in children.get(id(mech.ground), []))
    return (f'<mujoco><compiler angle="radian"/>'
            f'<option timestep="{dt!r}" integrator="{integrator}" gravity="{g[0]!r} {g[1]!r} 0">'
            f'<flag contact="disable"/></option>'
            f'<default><equality solimp="0.9999 0.9999 0.001" solref="{2 * dt!r} 1"/></default>'
            f'<worldbody>{tree}</worldbody><equality>{loops}</equality></mujoco>')


def mujoco_run(mech, t_end, dt, output_step, trace, integrator="implicitfast"):
    """(wall time [s], times, traced point (N, 2)) of `mech` in MuJoCo from its initial
    state (the hinges' rates the bodies' relative angular velocities)."""
    import mujoco
    model = mujoco.MjModel.from_xml_string(mujoco_xml(mech, dt, integrator, trace))
    data = mujoco.MjData(model)
    parent, order, _ = spanning_tree(mech)
    for b in order:
        up, pin = parent[id(b)]
        below = 0.0 if up is mech.ground else up.angular_velocity
        data.qvel[model.joint(f"j{id(pin)}").dofadr[0]] = b.angular_velocity - below
    mujoco.mj_forward(model, data)
    site = model.site("trace").id
    every = max(1, int(round(output_step / dt)))
    steps = int(round(t_end / dt))
    out = [data.site_xpos[site][:2].copy()]
    start = time.perf_counter()
    for k in range(1, steps + 1):
        mujoco.mj_step(model, data)
        if k % every == 0:
            out.append(data.site_xpos[site][:2].copy())
    wall = time.perf_counter() - start
    return wall, np.arange(len(out)) * every * dt, np.array(out)


# Exudyn advises its sparse solver (EigenSparse) for systems of more coordinates than
# this (its warning; a planar body has 3, a pin 2 algebraic ones).
EXUDYN_SPARSE_ABOVE = 1000


def exudyn_run(mech, t_end, h, output_step, trace, spectral_radius=0.8):
    """(wall time [s], times, traced point (N, 2)) of `mech` in Exudyn (see the module
    docstring)."""
    import exudyn
    from exudyn import itemInterface as ei
    _check(mech)
    sc = exudyn.SystemContainer()
    mbs = sc.AddSystem()
    number = {id(mech.ground): mbs.AddObject(ei.ObjectGround())}
    gravity = [float(mech.gravity[0]), float(mech.gravity[1]), 0.0]
    for b in mech.bodies:
        node = mbs.AddNode(ei.NodeRigidBody2D(
            referenceCoordinates=[float(b.position[0]), float(b.position[1]), float(b.angle)],
            initialVelocities=[float(b.velocity[0]), float(b.velocity[1]),
                               float(b.angular_velocity)]))
        number[id(b)] = mbs.AddObject(ei.ObjectRigidBody2D(
            physicsMass=float(b.mass), physicsInertia=float(b.inertia), nodeNumber=node))
        mbs.AddLoad(ei.LoadMassProportional(
            markerNumber=mbs.AddMarker(ei.MarkerBodyMass(bodyNumber=number[id(b)])),
            loadVector=gravity))
    for j in mech.joints:
        markers = []
        for b in (j.body_a, j.body_b):
            p = np.asarray(j.at, float) if b is mech.ground else b.local_point(j.at)
            markers.append(mbs.AddMarker(ei.MarkerBodyPosition(
                bodyNumber=number[id(b)], localPosition=[float(p[0]), float(p[1]), 0.0])))
        mbs.AddObject(ei.ObjectJointRevolute2D(markerNumbers=markers))
    body, point = trace
    sensor = mbs.AddSensor(ei.SensorBody(
        bodyNumber=number[id(mech.body(body))], localPosition=[float(point[0]),
                                                               float(point[1]), 0.0],
        outputVariableType=exudyn.OutputVariableType.Position, storeInternal=True))
    mbs.Assemble()
    s = exudyn.SimulationSettings()
    s.timeIntegration.endTime = float(t_end)
    s.timeIntegration.numberOfSteps = int(round(t_end / h))
    s.timeIntegration.generalizedAlpha.spectralRadius = spectral_radius
    s.timeIntegration.verboseMode = 0
    s.solutionSettings.writeSolutionToFile = False
    s.solutionSettings.sensorsWritePeriod = float(output_step)
    s.displayComputationTime = s.displayStatistics = False
    if 3 * len(mech.bodies) + 2 * len(mech.joints) > EXUDYN_SPARSE_ABOVE:
        # Its own advice for a large system (it warns above this many coordinates).
        s.linearSolver.solverType = exudyn.LinearSolverType.EigenSparse
    start = time.perf_counter()
    mbs.SolveDynamic(s)
    wall = time.perf_counter() - start
    data = mbs.GetSensorStoredData(sensor)
    return wall, data[:, 0], data[:, 1:3]


STEPS = {"mujoco implicitfast": (1e-2, 2e-3, 1e-3, 2e-4, 1e-4),
         "mujoco RK4": (1e-2, 2e-3, 1e-3, 2e-4, 1e-4),
         "exudyn": (1e-2, 2e-3, 1e-3, 2e-4)}
# Long chains (40 windows and more, 20 s): without the peers' finest steps, which take
# minutes there and are far more accurate than mechsim's runs need to be compared at.
CHAIN_STEPS = {"mujoco implicitfast": (1e-2, 2e-3, 1e-3, 2e-4),
               "mujoco RK4": (1e-2, 2e-3, 1e-3, 2e-4),
               "exudyn": (1e-2, 2e-3, 1e-3)}


# The tolerances of scipy's DOP853 on a parallelogram's exact 1-DOF equation.
EXACT_RTOLS = tuple(10.0 ** -e for e in range(2, 13))


def exact_run(problem, rtol, output_step):
    """(wall time, t, the traced crank tip's path) of scipy's DOP853 on the problem's exact
    1-DOF equation at `rtol` (`mechsim.examples.parallelogram_exact`: atol rtol/1000),
    sampled every `output_step`."""
    from .. import examples
    t = np.linspace(0.0, problem.t_end, int(round(problem.t_end / output_step)) + 1)
    start = time.perf_counter()
    theta, _ = examples.parallelogram_exact(t, problem.theta0, problem.omega0,
                                            n=problem.windows, rtol=rtol)
    wall = time.perf_counter() - start
    return wall, t, np.column_stack([np.cos(theta), np.sin(theta)])


# The fewest runs of the floor at each rtol (the rounds' and then more in the last).
MIN_FLOOR_RUNS = 3


class Floor:
    """scipy's DOP853 on a problem's exact 1-DOF equation at each of `EXACT_RTOLS`, timed
    in the rounds of mechsim's own runs (`mechsim.app.bench.run`'s `beside`): the floor
    mechsim's runs are measured against is then timed minutes apart from them no more
    than they are from each other (a machine's speed drifts over minutes, and a scipy
    integration in Python and a run in the compiled engine need not drift alike). Each
    (problem, rtol) keeps its shortest of at least `MIN_FLOOR_RUNS` runs."""

    def __init__(self):
        self.best = {}                    # (problem, rtol) -> (wall, error)

    def __call__(self, name, round_, rounds) -> None:
        from .bench import PROBLEMS
        problem = PROBLEMS[name]
        if problem.reference is not None or problem.exact is not None:
            return                                      # no exact 1-DOF equation
        runs = 1 + (max(MIN_FLOOR_RUNS - rounds, 0) if round_ == rounds - 1 else 0)
        for rtol in EXACT_RTOLS:
            for _ in range(runs):
                wall, t, xy = exact_run(problem, rtol, problem.t_end / 1000)
                best = self.best.get((name, rtol))
                if best is None or wall < best[0]:
                    self.best[(name, rtol)] = (wall, problem.point_error(t, xy))

    def rows(self, name) -> list[PeerRow]:
        return [PeerRow(name, "exact 1-DOF DOP853", rtol, *reversed(self.best[(name, rtol)]))
                for rtol in EXACT_RTOLS if (name, rtol) in self.best]


def run(problems, repeat: int = 1, steps=None, floor=None) -> list[PeerRow]:
    """Rows of every peer at every step of `steps` (default `STEPS`, `CHAIN_STEPS` for a
    chain of 40 windows or more) on each problem of `mechsim.app.bench.PROBLEMS` named,
    each run's shortest wall time of `repeat`; on a problem with an exact 1-DOF equation,
    scipy's DOP853 on it at each of `EXACT_RTOLS`: `floor`'s (a `Floor` timed in the rounds
    of mechsim's runs), or a `Floor` timed here in `repeat` rounds."""
    from .bench import PROBLEMS
    rows, own = [], floor is None
    floor = Floor() if own else floor
    for name in problems:
        problem = PROBLEMS[name]
        trace = problem.traced
        output_step = problem.t_end / 1000
        chosen = steps or (CHAIN_STEPS if problem.windows >= 40 else STEPS)
        for tool, hs in chosen.items():
            for h in hs:
                best, err = math.inf, math.nan
                for _ in range(repeat):
                    mech = problem.build()
                    if tool == "exudyn":
                        wall, t, xy = exudyn_run(mech, problem.t_end, h, output_step, trace)
                    else:
                        wall, t, xy = mujoco_run(mech, problem.t_end, h, output_step, trace,
                                                 tool.split()[1])
                    best = min(best, wall)
                    err = problem.point_error(t, xy)
                rows.append(PeerRow(name, tool, h, err, best))
        for round_ in range(repeat if own else 0):
            floor(name, round_, repeat)
        rows += floor.rows(name)
    return rows


def format_row(r: PeerRow) -> str:
    step = "rtol" if r.tool.startswith("exact") else "h   "
    return (f"{r.problem:16s} {r.tool:20s} {step} {r.step:7.0e}  error {r.error:9.2e}  "
            f"wall {r.wall_time:7.3f} s")


def compare(mechsim_rows, rows: list[PeerRow]) -> list[str]:
    """For each peer run, mechsim's cheapest run (any method) at least as accurate, and
    the ratio of their times (below 1: mechsim is faster)."""
    from .bench import cheapest_within
    out = []
    for r in rows:
        best = cheapest_within(mechsim_rows, r.error).get(r.problem, {})
        if not best or not math.isfinite(r.error):
            out.append(f"{format_row(r)}   mechsim: no run as accurate")
            continue
        m = min(best.values(), key=lambda row: row.wall_time)
        out.append(f"{format_row(r)}   mechsim {m.method} rtol {m.rtol:.0e}: "
                   f"{m.wall_time:.3f} s, error {m.error:.2e} → {m.wall_time / r.wall_time:.2f}×")
    return out


def reference_time(rows: list[PeerRow], problem: str, error: float) -> float | None:
    """The time scipy's DOP853 on `problem`'s exact 1-DOF equation takes to reach `error`:
    its work–precision curve (the runs at `EXACT_RTOLS`, each at the time of the fastest
    run at least as accurate: the reference's best) interpolated log-log between the two
    runs bracketing `error`; None outside the curve's range of errors."""
    curve = sorted(((r.error, r.wall_time) for r in rows
                    if r.problem == problem and r.tool == "exact 1-DOF DOP853"
                    and math.isfinite(r.error) and r.error > 0.0))
    points, fastest = [], math.inf
    for err, wall in curve:                   # from the most accurate run on
        fastest = min(fastest, wall)
        points.append((err, fastest))
    points.reverse()
    for (e0, t0), (e1, t1) in zip(points, points[1:]):
        if e1 <= error <= e0:
            if e0 == e1:
                return t0
            w = math.log(e0 / error) / math.log(e0 / e1)
            return math.exp((1.0 - w) * math.log(t0) + w * math.log(t1))
    return None


def against_reference(mechsim_rows, rows: list[PeerRow]) -> list[str]:
    """For each of mechsim's successful runs on a problem with an exact 1-DOF equation,
    what scipy's DOP853 on that equation takes for the same error (`reference_time`) and
    the ratio of mechsim's time to it: mechsim at each of its tolerances against the
    floor at the error it reached there."""
    out = []
    for r in mechsim_rows:
        if r.status != "success":
            continue
        floor = reference_time(rows, r.problem, r.error)
        if floor is None:
            continue
        out.append(f"{r.problem:16s} mechsim {r.method:10s} rtol {r.rtol:7.0e}  error "
                   f"{r.error:9.2e}  wall {r.wall_time:7.3f} s   exact 1-DOF DOP853 at that "
                   f"error: {floor:.4f} s → {r.wall_time / floor:.2f}×")
    return out


def write(mechsim_rows, rows: list[PeerRow], out_dir) -> list:
    """The peers' rows as peers.csv and, per problem, a work–precision plot of every tool
    (peers_<problem>.png) in `out_dir`."""
    from pathlib import Path

    from .bench import write_csv
    from ..files import save_figure
    from ..results.plots import new_figure
    out_dir = Path(out_dir)
    written = [write_csv(rows, out_dir / "peers.csv",
                         ["problem", "tool", "step", "error", "wall_time"])]
    for problem in dict.fromkeys(r.problem for r in rows):
        fig = new_figure((6.4, 4.6))
        ax = fig.add_subplot()
        lines = {}
        for r in mechsim_rows:
            if r.problem == problem and r.status == "success":
                lines.setdefault(f"mechsim {r.method}", []).append((r.error, r.wall_time))
        for r in rows:
            if r.problem == problem:
                lines.setdefault(r.tool, []).append((r.error, r.wall_time))
        for label, pts in lines.items():
            pts = sorted(pts)
            ax.loglog([p[0] for p in pts], [p[1] for p in pts], "o-" if "mechsim" in label
                      else "s--", label=label)
        ax.set_xlabel("error [m]")
        ax.set_ylabel("wall time [s]")
        ax.set_title(f"{problem}: work against precision")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize="small")
        written.append(save_figure(fig, out_dir / f"peers_{problem}.png"))
    return written
