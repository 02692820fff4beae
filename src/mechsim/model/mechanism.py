"""Mechanism: the container users build (`mechsim.build` turns it into a NumericProblem)."""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass, field

import numpy as np

from .checks import ModelError, name_or_default, vector2
from .bodies import Body, Ground
from .channels import Channel, channel_names
from .drivers import Driver
from .forces import Force, RotationalSpring, Spring, Torque, load_points
from .gears import Gear
from .friction import Friction
from .stops import Stop
from .joints import Joint


class AssemblyError(ModelError):
    """The initial configuration cannot be made to satisfy the constraints."""


@dataclass
class DofReport:
    """Degrees of freedom from the rank of Φ_q (Grübler counts are wrong for special
    geometry, the rank is not)."""
    coordinates: int
    constraints: int
    rank: int
    dof: int
    redundant: int
    redundant_joints: list[str] = field(default_factory=list)
    singular_values: np.ndarray | None = None

    def __str__(self):
        s = (f"{self.coordinates} coordinates, {self.constraints} constraint equations, "
             f"rank {self.rank}: {self.dof} degree(s) of freedom")
        if self.redundant:
            s += (f"; {self.redundant} redundant constraint equation(s) among "
                  f"{', '.join(repr(j) for j in self.redundant_joints)}")
        return s


@dataclass
class AssemblyReport:
    q: np.ndarray
    v: np.ndarray
    iterations: int
    position_change: float      # max |Δq|
    velocity_change: float      # max |Δv|
    residual: float             # max |Φ| after assembly

    def __str__(self):
        return (f"assembled in {self.iterations} Newton iteration(s): max |Δq| = "
                f"{self.position_change:.3g}, max |Δv| = {self.velocity_change:.3g}, "
                f"max |Φ| = {self.residual:.3g}")


class Mechanism:
    """A planar mechanism: bodies, joints, drivers and loads.

    >>> import mechsim as ms
    >>> mech = ms.Mechanism("pendulum", gravity=(0.0, -9.81))
    >>> rod = mech.add(ms.RigidBody.rod("rod", (0, 0), (1, 0), mass=1.0))
    >>> _ = mech.add(ms.Revolute(mech.ground, rod, at=(0, 0)))
    >>> mech.dof().dof
    1
    """

    def __init__(self, name: str = "mechanism", gravity=(0.0, -9.81)):
        self.name = name_or_default(name, "mechanism", "mechanism")
        self.gravity = vector2(gravity, "gravity", f"mechanism '{name}'")
        self.ground = Ground()
        self.bodies: list[Body] = []          # moving bodies, in coordinate order
        self.joints: list[Joint] = []
        self.drivers: list[Driver] = []
        self.gears: list[Gear] = []          # gear pairs between joints' coordinates
        self.stops: list[Stop] = []          # end stops on joints' coordinates
        self.frictions: list[Friction] = []  # dry friction in joints
        self.loads: list = []                 # springs, rotational springs, forces, torques
        self.channels: list[Channel] = []    # the user's recorded quantities
        self.speeds: dict[str, float] = {}   # joint name -> its prescribed initial rate
        self._problem = None
        self._build = None                    # the build asked for by `problem(build=)`
        self._assembled: AssemblyReport | None = None
        self._state = None               # (q, v) set by `set_state`: where assembly starts
        self._lookup = None                   # see `_names`

    # --- building ----------------------------------------------------------------------------
    def add(self, item):
        """Add a body, joint, driver, gear, stop, friction, spring, rotational spring, force,
        torque or channel; returns it. A channel's expression is checked against the bodies and joints added
        before it; it changes no equation (nothing is rebuilt for it)."""
        owner = f"mechanism '{self.name}'"
        if isinstance(item, Channel):
            if any(c.name == item.name for c in self.channels):
                raise ModelError(f"{owner}: a channel named '{item.name}' exists already")
            item.parsed(channel_names(self))
            self.channels.append(item)
            return item
        if isinstance(item, Body):
            if isinstance(item, Ground):
                raise ModelError(f"{owner}: the ground exists already as `mechanism.ground`")
            if item.name in self._names()[0]:
                raise ModelError(f"{owner}: a body named '{item.name}' exists already")
            self.bodies.append(item)
            self._noted(item)
        elif isinstance(item, Joint):
            self._check_names(item)
            for body in (item.body_a, item.body_b):
                self._check_member(body, f"{item.kind} joint '{item.name}'")
            self.joints.append(item)
            self._noted(item)
        elif isinstance(item, Driver):
            self._check_joint(item, "driver")
            if any(d.joint is item.joint for d in self.drivers):
                raise ModelError(f"driver '{item.name}': joint '{item.joint.name}' is driven already")
            self._check_names(item)
            self.drivers.append(item)
            self._noted(item)
        elif isinstance(item, Stop):
            self._check_joint(item, "stop")
            if any(d.joint is item.joint for d in self.drivers):
                raise ModelError(f"stop '{item.name}': joint '{item.joint.name}' is driven; "
                                 "a driven joint goes where its law says")
            self.stops.append(item)             # its holding force is part of the problem
        elif isinstance(item, Friction):
            self._check_joint(item, "friction")
            if any(f.joint is item.joint for f in self.frictions):
                raise ModelError(f"friction '{item.name}': joint '{item.joint.name}' has "
                                 "friction already")
            self.frictions.append(item)
        elif isinstance(item, Gear):
            for joint in item.joints:
                if not any(j is joint for j in self.joints):
                    raise ModelError(f"gear '{item.name}': joint '{joint.name}' is not in "
                                     f"{owner}; add the joint first")
            self._check_names(item)
            self.gears.append(item)
            self._noted(item)
        elif isinstance(item, (Spring, Force, Torque, RotationalSpring)):
            for body in item.bodies:
                self._check_member(body, f"'{item.name}'")
            joint = getattr(item, "joint", None)
            if joint is not None and not any(j is joint for j in self.joints):
                raise ModelError(f"'{item.name}': joint '{joint.name}' is not in {owner}; "
                                 "add the joint first")
            for body, at in load_points(item):
                body.attachment_values(body.local_point(at), f"'{item.name}'")
            self.loads.append(item)
        else:
            raise ModelError(f"{owner}: cannot add {item!r}; expected a body, joint, driver, "
                             "gear, stop, friction, spring, rotational spring, force, torque "
                             "or channel")
        self._problem = None
        self._assembled = None
        self._state = None
        return item

    def _check_joint(self, item, what: str) -> None:
        """ModelError where the joint `item` acts on is not in this mechanism."""
        if not any(j is item.joint for j in self.joints):
            raise ModelError(f"{what} '{item.name}': joint '{item.joint.name}' is not in "
                             f"mechanism '{self.name}'; add the joint first")

    def _all_bodies(self):
        return [self.ground] + self.bodies

    def _lookup_key(self):
        """What tells whether the lists changed since `_names` looked: their lengths and
        last items."""
        return tuple((len(x), id(x[-1]) if x else None)
                     for x in (self.bodies, self.joints, self.drivers, self.gears))

    def _names(self):
        """(body names, ids of the bodies, joint and driver names), kept current by `add`
        and rebuilt where the lists were changed otherwise: building a mechanism costs
        O(n), not a scan of every earlier item per item."""
        key = self._lookup_key()
        if self._lookup is None or self._lookup[0] != key:
            bodies = self._all_bodies()
            self._lookup = (key, {b.name for b in bodies}, {id(b) for b in bodies},
                            {x.name for x in self.constraint_items})
        return self._lookup[1:]

    def _noted(self, item):
        """Add the item just appended to the lookup of `_names` (current before it)."""
        _, names, ids, joint_names = self._lookup
        if isinstance(item, Body):
            names.add(item.name)
            ids.add(id(item))
        else:
            joint_names.add(item.name)
        self._lookup = (self._lookup_key(), names, ids, joint_names)

    def _check_member(self, body, who):
        if id(body) not in self._names()[1]:
            raise ModelError(f"{who}: body '{body.name}' is not in mechanism '{self.name}'; "
                             "add the body first")

    def _check_names(self, item):
        if item.name in self._names()[2]:
            raise ModelError(f"a joint, driver or gear named '{item.name}' exists already; "
                             "give it a `name=`")

    def body(self, name: str) -> Body:
        for b in self._all_bodies():
            if b.name == name:
                return b
        raise KeyError(f"mechanism '{self.name}' has no body '{name}'; bodies: "
                       f"{', '.join(b.name for b in self._all_bodies())}")

    def joint(self, name: str) -> Joint:
        for j in self.joints:
            if j.name == name:
                return j
        raise KeyError(f"mechanism '{self.name}' has no joint '{name}'; joints: "
                       f"{', '.join(j.name for j in self.joints) or '(none)'}")

    # --- coordinates ---------------------------------------------------------------------------
    @property
    def coordinate_names(self) -> list[str]:
        return [f"{b.name}.{c}" for b in self.bodies for c in b.coordinate_names]

    def initial_coordinates(self) -> np.ndarray:
        return np.concatenate([b.initial_coordinates for b in self.bodies]) if self.bodies \
            else np.zeros(0)

    def initial_velocities(self) -> np.ndarray:
        return np.concatenate([b.initial_velocities for b in self.bodies]) if self.bodies \
            else np.zeros(0)

    # --- the numeric problem -----------------------------------------------------------------
    def structure(self) -> dict:
        """What the generated code depends on (not parameter values, not names): the cache
        key. Bodies and joints are referred to by position."""
        index = {id(self.ground): -1, **{id(b): i for i, b in enumerate(self.bodies)},
                 **{id(j): k for k, j in enumerate(self.joints)}}
        return {"bodies": [(type(b).__name__, list(b.coordinate_names)) for b in self.bodies],
                "constraints": [list(item.structure(lambda x: index[id(x)]))
                                for item in self.constraint_items]}

    @property
    def constraint_items(self) -> list:
        """Everything that writes rows of Φ, in row order: joints, drivers, gears."""
        return self.joints + self.drivers + self.gears

    def problem(self, build: str | None = None):
        """The NumericProblem of this mechanism, built once (`mechsim.build`). `build`:
        "fused" (one generated model for the whole mechanism, compiled where small),
        "assembled" (from joint-type kernels: no sympy run for a new structure), or
        "auto" (the fused model where the cache has it, else the assembled one); None:
        `$MECHSIM_BUILD`, else "auto". Asking for another build than the one made
        rebuilds."""
        from ..build import build_mode, build_problem
        mode = None if build is None else build_mode(build)
        if self._problem is None or (mode is not None and mode != self._build):
            if not self.bodies:
                raise ModelError(f"mechanism '{self.name}' has no moving bodies")
            self._build = mode or build_mode()
            self._problem, self.from_cache = build_problem(self, self._build)
            import warnings
            for text in self.placement_warnings():
                warnings.warn(f"mechsim: mechanism '{self.name}': {text}", stacklevel=2)
        return self._problem

    # --- analysis ----------------------------------------------------------------------------
    def dof(self, t: float = 0.0) -> DofReport:
        """Degrees of freedom from the rank of Φ_q at the (assembled, if available) initial
        configuration; names the joints whose equations are redundant."""
        prob = self.problem()
        q = self._assembled.q if self._assembled is not None else self.initial_coordinates()
        J = prob.phi_q(q, t)
        m, n = J.shape
        if m == 0:
            return DofReport(n, 0, 0, n, 0, [], np.zeros(0))
        U, s, _ = np.linalg.svd(J)
        tol = max(m, n) * np.finfo(float).eps * 1e3 * (s[0] if s.size else 1.0)
        rank = int(np.sum(s > tol))
        involved = []
        if rank < m:
            left_null = U[:, rank:]          # combinations of rows that vanish: redundancy
            weight = np.linalg.norm(left_null, axis=1)
            for i in np.flatnonzero(weight > 1e-8):
                if prob.constraint_owners[i] not in involved:
                    involved.append(prob.constraint_owners[i])
        return DofReport(n, m, rank, n - rank, m - rank, involved, s)

    def compilation(self):
        """Whether compiled C serves this mechanism's runs: a `Compilation` with `kernels`
        (its generated functions run as C), `engine` (compiled evaluations of the rigid
        formulations) and the `reason` where neither does (no compiler and the compiler's
        error, `MECHSIM_NO_COMPILE`, flexible bodies, …). Builds what is missing."""
        from ..codegen.compiled import compilation
        return compilation(self.problem())

    def assemble(self, t: float = 0.0, tol: float = 1e-10, max_iter: int = 50) -> AssemblyReport:
        """Make the initial state consistent: positions by Newton with the smallest change
        (kinetic metric), then velocities by projection in the mass metric. Consistent input is
        kept exactly. Raises AssemblyError naming the joint with the largest residual, or a
        driver whose law (or its rate or acceleration) is undefined at t."""
        for name, value, rule in (("tol", tol, "a positive number"),
                                  ("max_iter", max_iter, "a whole number ≥ 1")):
            ok = (isinstance(value, numbers.Real) and not isinstance(value, bool) and
                  value > 0 and math.isfinite(value) and
                  (name == "tol" or float(value).is_integer()))
            if not ok:
                raise ValueError(f"assemble: `{name}` must be {rule}, got {value!r:.40}")
        for driver in self.drivers:
            try:
                jet = driver.law.jet("t", float(t))
            except (ArithmeticError, ValueError) as exc:
                jet = (exc,)
            if not all(isinstance(x, float) and math.isfinite(x) for x in jet):
                why = f" ({jet[0]})" if isinstance(jet[0], Exception) else ""
                raise AssemblyError(
                    f"mechanism '{self.name}': driver '{driver.name}' prescribes "
                    f"{driver.expression}, whose value, rate or acceleration is not defined "
                    f"at t = {float(t):g}, where the run starts{why}; start the run where it "
                    "is (t_start) or change the law")
        prob = self.problem()
        q0, v0 = self._state if self._state is not None else \
            (self.initial_coordinates(), self.initial_velocities())
        q, iterations, err = prob.project_positions(q0, t, tol=tol, max_iter=max_iter)
        if not err <= tol:
            raise AssemblyError(
                f"mechanism '{self.name}' cannot be assembled: after {iterations} Newton "
                f"iterations the largest residual is {prob.worst_constraint(prob.phi(q, t))}. "
                "Check that joint's points and the link lengths it implies.")
        v = self._velocities(prob, q, v0, t, tol)
        self._assembled = AssemblyReport(
            q, v, iterations, float(np.max(np.abs(q - q0), initial=0.0)),
            float(np.max(np.abs(v - v0), initial=0.0)),
            float(np.max(np.abs(prob.phi(q, t)), initial=0.0)))
        return self._assembled

    def _velocities(self, prob, q, v0, t, tol):
        """Consistent velocities nearest the given ones (mass metric) with the joint rates
        of `set_speed`; a warning where a velocity the user gave (non-zero) had to change."""
        extra = None
        if self.speeds:
            from ..engineering.geometry import joint_gradient
            G = np.array([joint_gradient(prob.joints[name], q) for name in self.speeds])
            extra = (G, np.array(list(self.speeds.values())))
        J = prob.phi_q(q, t)
        rows = [J @ v0 + prob.phi_t(q, t)] + ([extra[0] @ v0 - extra[1]] if extra else [])
        vscale = max(1.0, float(np.max(np.abs(v0))) if v0.size else 1.0,
                     *(abs(r) for r in self.speeds.values()))
        v = v0 if np.max(np.abs(np.concatenate(rows)), initial=0.0) <= tol * vscale \
            else prob.project_velocities(q, v0, t, extra)
        r_after = np.max(np.abs(prob.phi_q(q, t) @ v + prob.phi_t(q, t)), initial=0.0)
        missed = np.abs(extra[0] @ v - extra[1]) if extra is not None else np.zeros(1)
        if extra is not None and max(r_after, np.max(missed)) > 1e-8 * vscale:
            name = list(self.speeds)[int(np.argmax(missed))]
            raise AssemblyError(f"mechanism '{self.name}': the joint rates of set_speed "
                                f"cannot all hold with the constraints and drivers (joint "
                                f"'{name}' off by {np.max(missed):.3g}, the constraints by "
                                f"{r_after:.3g}); the mechanism has fewer degrees of "
                                "freedom than rates set")
        if r_after > 1e-8 * vscale:
            raise AssemblyError(f"mechanism '{self.name}': no velocity satisfies the "
                                f"constraints (residual {r_after:.3g}); check the drivers")
        given = np.flatnonzero(v0 != 0.0)
        change = np.abs(v - v0)[given]
        if change.size and np.max(change) > 1e-6 * vscale:
            import warnings
            k = given[int(np.argmax(change))]
            warnings.warn(
                f"mechsim: assembling mechanism '{self.name}' changed the initial velocity "
                f"'{prob.coordinate_names[k]}' from {v0[k]:.6g} to {v[k]:.6g}: the velocities "
                "given do not satisfy the joints, and the nearest ones that do were taken. "
                "Give the speeds of joints instead (Mechanism.set_speed(joint, rate)).",
                stacklevel=3)
        return v

    def placement_warnings(self) -> list[str]:
        """What is likely a mistake in how the mechanism is put together, though it can be
        simulated: a body joined to nothing (it moves freely: a joint left out?), and a
        pin whose point (global `at`) lies farther from each of its moving bodies than
        the mechanism's own size (the largest distance between two bodies' frames, or the
        largest body: √(12 I/m), a rod's length; a beam's length) — a point typed wrong.
        Checked where there are two moving bodies or more. `Mechanism.problem` warns of
        each once."""
        out = []
        joined = {id(b) for item in self.joints + self.loads
                  for b in (getattr(item, "body_a", None), getattr(item, "body_b", None),
                            getattr(item, "body", None)) if b is not None}
        for body in self.bodies:
            if id(body) not in joined:
                out.append(f"body '{body.name}' is joined to nothing: it moves freely (a "
                           "joint left out?)")
        if len(self.bodies) < 2:
            return out
        frames = np.array([b.position for b in self.bodies])
        apart = float(np.max(np.hypot(*(frames[:, None, :] - frames[None, :, :]).transpose(
            2, 0, 1))))
        sizes = [float(getattr(b, "length", 0.0)) or
                 math.sqrt(12.0 * b.inertia / b.mass) for b in self.bodies]
        size = max(apart, *sizes)
        for joint in self.joints:
            # A pin's point is on its bodies; a slider's only places its axis, anywhere.
            at = getattr(joint, "at", None) if joint.kind == "revolute" else None
            moving = [b for b in (joint.body_a, joint.body_b) if b.coordinate_names]
            if at is None or not moving:
                continue
            far = [float(np.hypot(*(at - b.position))) for b in moving]
            if min(far) > size:
                where = " and ".join(f"{d:.3g} m from body '{b.name}'"
                                     for d, b in zip(far, moving))
                out.append(f"joint '{joint.name}' is at ({at[0]:.4g}, {at[1]:.4g}), {where}: "
                           f"farther than the mechanism's own size ({size:.3g} m); check its "
                           "`at` (a global point in the initial configuration)")
        return out

    def set_speed(self, joint, rate: float) -> None:
        """Start the joint's coordinate (relative angle of a revolute, slide of a prismatic)
        at `rate` [rad/s or m/s]: assembly then finds the velocities of every body that move
        it so (nearest the bodies' given velocities in the mass metric), instead of
        re-projecting body velocities that do not fit the joints. A driven joint's rate is
        its driver's."""
        owner = f"mechanism '{self.name}': set_speed"
        joint = self.joint(joint) if isinstance(joint, str) else joint
        if not any(j is joint for j in self.joints):
            raise ModelError(f"{owner}: {joint!r} is not a joint of this mechanism")
        if type(joint).coordinate is Joint.coordinate:
            raise ModelError(f"{owner}: a {joint.kind} joint has no rate to set")
        if any(d.joint is joint for d in self.drivers):
            raise ModelError(f"{owner}: joint '{joint.name}' is driven; its driver sets its rate")
        from .checks import scalar
        self.speeds[joint.name] = scalar(rate, "rate", f"{owner}({joint.name!r})")
        self._assembled = None

    def save(self, path):
        """Write the mechanism as a scene (`mechsim.scene`'s schema; JSON where `path` ends
        in .json, else TOML): bodies, joints, drivers, springs, constant forces and torques,
        joint speeds, every number exact; `mechsim.load_mechanism(path)` builds it again. A
        ModelError names what a scene cannot hold (a load given as a function, a beam that
        starts deformed). A state set by `set_state` is not part of the model. Returns the
        path."""
        from .scene_save import scene_data, write_scene
        return write_scene(scene_data(self), path)

    def set_state(self, q, v=None, t: float = 0.0) -> AssemblyReport:
        """Start later simulations from the consistent state (q, v) (v default zeros),
        such as an equilibrium's `eq.q`, instead of the assembled initial configuration;
        a `set_speed` after it starts the joint turning from that state. Raises ModelError
        if (q, v) does not satisfy the constraints; adding to the mechanism forgets the
        state."""
        from ..solver import check_initial_state
        prob = self.problem()
        v = np.zeros(prob.n) if v is None else v
        try:
            q, v = check_initial_state(prob, q, v, t)
        except ValueError as exc:
            raise ModelError(f"mechanism '{self.name}': set_state: {exc}") from None
        self._state = (q, v)
        self._assembled = AssemblyReport(q, v, 0, 0.0, 0.0,
                                         float(np.max(np.abs(prob.phi(q, t)), initial=0.0)))
        return self._assembled

    # --- engineering analysis ----------------------------------------------------------------
    def equilibrium(self, t: float = 0.0):
        """The static equilibrium nearest the assembled state under gravity, springs and
        constant loads, with the drivers held where their laws put them at t: an
        `Equilibrium` (`mechsim.engineering.equilibrium`) with `q`, `converged`, `stable`
        (the reduced stiffness positive definite), the stiffness itself and the reactions
        there (`eq.joint_force(joint)`). `mech.set_state(eq.q)` starts simulations there."""
        from ..engineering.equilibrium import equilibrium
        return equilibrium(self, t)

    def linearize(self, q=None, v=None, t: float = 0.0):
        """The linearized equations of motion about the consistent state (q, v) at t, in the
        independent coordinates: a `Linearization` with M, C, K, A, natural frequencies,
        damping ratios and mode shapes in all coordinates. q=None: the static equilibrium
        found from the assembled state (`equilibrium`); v=None: at rest, but for what the
        drivers move (the consistent velocity of least kinetic energy)."""
        from ..engineering.linearize import linearize
        prob = self.problem()
        if q is None:
            eq = self.equilibrium(t)
            q = eq.q if eq.converged else self.assemble(t=t).q
        if v is None:
            v = prob.project_velocities(np.asarray(q, float), np.zeros(prob.n), t) \
                if prob.m else np.zeros(prob.n)
        from ..solver import check_initial_state
        try:
            q, v = check_initial_state(prob, q, v, t)
        except ValueError as exc:
            raise ModelError(f"mechanism '{self.name}': linearize: {exc}") from None
        return linearize(prob, q, v, t)

    def kinematics(self, t_end: float | None = None, output_step: float | None = None,
                   t_start: float = 0.0, over=None):
        """Kinematic analysis of a fully driven mechanism (0 degrees of freedom): its
        positions, velocities and accelerations solved from the constraints at t_start,
        t_start + output_step, …, t_end (no integration), or over a driver's range with
        `over=(driver, values)` (the times where its law reaches each change of its
        joint's coordinate, e.g. `(motor, np.radians(np.arange(0, 361)))`), as a
        `SimulationResult` whose `driver_effort`, `joint_force` and `cycle_figures()` give
        the inverse dynamics: the efforts the drivers need and the loads on the joints. See
        `mechsim.engineering.driven`."""
        from ..engineering.driven import kinematic_analysis
        if over is None and isinstance(t_end, numbers.Real):
            self.check_tables(t_start, t_end)
        return kinematic_analysis(self, t_end, output_step, t_start, over=over)

    def check_tables(self, t_start, t_end) -> None:
        """ModelError naming the first driver given by a table (`TableLaw`) whose times do
        not cover [t_start, t_end]: its law is data, not defined beyond them."""
        for d in self.drivers:
            domain = getattr(d.law, "domain", None)
            if domain is None or t_end is None:
                continue
            lo, hi = domain
            slack = 1e-12 * max(1.0, abs(lo), abs(hi))
            if float(t_start) < lo - slack or float(t_end) > hi + slack:
                raise ModelError(f"driver '{d.name}' is given by {d.expression}; the run "
                                 f"asks for [{float(t_start):g}, {float(t_end):g}] s: give "
                                 "a table that covers it, or a shorter run")

    # --- simulation --------------------------------------------------------------------------
    def simulate(self, t_end: float, method: str | None = None, **options):
        """Simulate from the assembled initial state to `t_end`; see `mechsim.solver.simulate`
        for the options. Returns a SimulationResult (partial, with a status, on failure)."""
        from ..solver import check_simulate_arguments, simulate
        check_simulate_arguments(len(self.coordinate_names), t_end, method, options)
        self.check_tables(options.get("t_start", 0.0), t_end)
        report = self._assembled or self.assemble(t=options.get("t_start", 0.0))
        if self.stops or self.frictions:
            from ..engineering.impacts import simulate_with_stops
            return simulate_with_stops(self, report, t_end, method, **options)
        return simulate(self.problem(), report.q, report.v, t_end=t_end, method=method,
                        mechanism=self, **options)

    def steady_state(self, period: float, guess=None, method: str = "newton",
                     tol: float = 1e-8, max_iter: int = 30, t0: float = 0.0,
                     **simulate_options):
        """The periodic steady state of period `period` (e.g. 2π/ω of a driver or a
        forcing), found by shooting on the independent coordinates and velocities without
        simulating the transient. Returns a `ShootingResult`; `result.trajectory.result` is
        the SimulationResult over one period. `guess` defaults to the assembled state."""
        from ..shooting import solve
        from ..shooting.mechanism import MechanismPeriodicProblem
        problem = MechanismPeriodicProblem(self, period, t0, **simulate_options)
        start = problem.guess0 if guess is None else guess
        return solve(problem, start, method=method, tol=tol, max_iter=max_iter)

    def __repr__(self):
        return (f"Mechanism({self.name!r}: {len(self.bodies)} bodies, {len(self.joints)} joints, "
                f"{len(self.drivers)} drivers, {len(self.loads)} loads)")
