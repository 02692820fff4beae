"""The builder: a declarative `Mechanism` turned into the `NumericProblem` the solvers run.

The model (`mechsim.model`) says what the user built; this module compiles it: the
constraint equations through sympy and the generated-code cache (`mechsim.codegen`), the
parameter values in the order of the generated symbols, the rows' names and owners, the
springs', loads' and beams' numeric data, and the polylines an export draws.
"""

from __future__ import annotations

import math

import numpy as np

from ..model import (Driver, FlexibleBeam, Force, LoadError, ModelError, RigidBody,
                    RotationalSpring, Spring)
from ..model.forces import load_points
from ..model.checks import call_user
from ..model.parameters import gradient, parameter_names, value_of
from ..problem import FlexibleData, NumericProblem, PointLoad, RotationalSpringData, SpringData


def body_starts(mech) -> dict:
    """Each body's name -> the index of its first coordinate in q (None: the ground)."""
    starts, k = {mech.ground.name: None}, 0
    for b in mech.bodies:
        starts[b.name] = k
        k += len(b.coordinate_names)
    return starts


BUILDS = ("auto", "fused", "assembled")
# Up to this many coordinates a rigid mechanism is the compiled engine's customer: the
# engine's object starts compiling as soon as its fused model is built
# (`_prepare_engine`).
ENGINE_AT_ONCE = 20


def build_mode(build: str | None = None) -> str:
    """The build asked for: `build`, else `$MECHSIM_BUILD`, else "auto" (see
    `constraint_model`); a ModelError names anything else."""
    import os
    mode = build if build is not None else (os.environ.get("MECHSIM_BUILD") or "auto")
    if mode not in BUILDS:
        source = "`build`" if build is not None else "MECHSIM_BUILD"
        raise ModelError(f"{source} must be one of {', '.join(BUILDS)}; got {mode!r:.40}")
    return mode


def constraint_model(mech, items, build: str = "auto"):
    """(the model of `mech`'s constraint equations, whether no sympy ran for it).

    - "fused": one generated module for the whole mechanism (`mechsim.codegen`), with the
      compiled evaluations of small rigid ones: the fastest per evaluation. It is written
      from the joint types' kernels and the drivers' laws (`mechsim.assembly.unrolled`):
      no sympy (but for a kernel not yet cached), and the assembled model's numbers to
      the last bit; a large one's C twins cost a compile (~10 s at 243 coordinates).
    - "assembled": the system assembled from joint-type kernels (`mechsim.assembly`): a
      new structure of known joint types costs milliseconds at any size.
    - "auto": the fused model where the cache has it; else, below
      `compiled.C_MIN_COORDINATES` coordinates (a Python module and, for the compiled
      engine's customers, a small compile), the fused model built at once (as "fused");
      else the assembled one, with the fused model built in a background process for the
      runs after (`mechsim.build.background`). Either build gives the same numbers, so a
      mechanism's runs are alike to the last bit whichever serves them.
    """
    from . import background
    from ..codegen import cached_model, load_model
    from ..codegen.compiled import C_MIN_COORDINATES

    structure = mech.structure()
    if build != "assembled":
        model = cached_model(structure)
        if model is not None:
            return model, True
        if build == "fused" or len(mech.coordinate_names) < C_MIN_COORDINATES:
            _prepare_engine(mech, items)
            return load_model(structure, lambda: background.fused_source(mech.bodies, items,
                                                                         structure))
    from ..assembly import AssembledModel
    model = AssembledModel(mech.bodies, items)
    if build == "auto":
        background.start(mech.bodies, items, structure)
    return model, model.from_cache


def _prepare_engine(mech, items) -> None:
    """Before a small rigid mechanism's fused model is built (at most `ENGINE_AT_ONCE`
    coordinates: the compiled engine's customers): the engine it will link starts
    compiling beside the build, which may run sympy for a new joint type
    (`mechsim.codegen.engine.prepare`)."""
    from ..codegen import engine
    from ..codegen.cache import store
    if items and len(mech.coordinate_names) <= ENGINE_AT_ONCE and \
            not any(isinstance(body, FlexibleBeam) for body in mech.bodies):
        engine.prepare(store())


def build_problem(mech, build: str | None = None) -> tuple[NumericProblem, bool]:
    """(the NumericProblem of `mech`, whether its model came without a sympy run);
    `build`: "auto", "fused" or "assembled" (`constraint_model`; None: `build_mode()`)."""
    items = mech.constraint_items
    mass = mass_diagonal(mech)            # a point mass that can turn refused before a build
    mode = build_mode(build)
    if any(getattr(d, "evaluated", False) for d in mech.drivers):
        mode = "assembled"                # a function is evaluated, never generated
    model, from_cache = constraint_model(mech, items, mode)
    starts = body_starts(mech)
    exact = [x for item in items for x in item.parameter_values()] + \
        [x for item in items for x in getattr(item, "exact_law_constants", ())]
    params = [value_of(x) for x in exact]
    # ∂p/∂(each Parameter the geometry depends on), exact (`mechsim.model.parameters`).
    named = parameter_names(exact)
    partials = dict(zip(named, gradient(exact, named).T))
    masses = [x for b in mech.bodies for x in (
        (b.exact_mass, b.exact_mass, b.exact_inertia) if isinstance(b, RigidBody)
        else (0.0,) * len(b.coordinate_names))]
    named = parameter_names(masses)
    mass_partials = dict(zip(named, gradient(masses, named).T))
    names, owners, kinds = [], [], []
    for item in items:
        for label in item.equation_labels:
            names.append(f"{item.name}.{label}")
            owners.append(item.name)
            kinds.append("driver" if isinstance(item, Driver) else
                         "gear" if item.kind == "gear" else "joint")
    joints = joint_geometry(mech, starts)
    springs, loads, torsion = _load_data(mech, starts, joints)
    problem = NumericProblem(model, params, mass, mech.gravity, starts, mech.coordinate_names,
                             names, owners, springs, loads, title=mech.name,
                             constraint_kinds=kinds, flexible=_flexible_data(mech, starts),
                             drawing=drawing(mech, starts),
                             driver_laws=[(d.name, d.law) for d in mech.drivers],
                             joints=joints, torsion=torsion,
                             driver_joints={d.name: d.joint.name for d in mech.drivers},
                             gear_signs={g.name: 1.0 if getattr(g, "internal", False) else -1.0
                                         for g in mech.gears},
                             friction=_friction_model(mech, joints, owners),
                             parameter_partials=partials, mass_partials=mass_partials)
    return problem, from_cache


def sensitivity_model(mech):
    """The module of the constraints' derivatives in the model's parameters
    (`mechsim.symbolic.sensitivity`) for `mech`'s structure, from the cache or generated
    by sympy into it. ModelError where a driver follows a table or a function (the
    derivatives' generation does not reach through them)."""
    from ..codegen import load_model
    evaluated = [d.name for d in mech.drivers
                 if getattr(d, "evaluated", False) or getattr(d, "tabulated", False)]
    if evaluated:
        raise ModelError(f"sensitivities: driver '{evaluated[0]}' follows a table or a "
                         "function, which the derivatives cannot be generated through; give "
                         "its law as an expression")
    items = mech.constraint_items
    structure = {"sensitivity": 2, **mech.structure()}

    def source():
        from ..codegen.printer import sensitivity_source
        from ..codegen.cache import structure_key
        from ..symbolic import build_system
        from ..symbolic.sensitivity import SensitivitySystem
        return sensitivity_source(SensitivitySystem(build_system(mech.bodies, items)),
                                  structure_key(structure))

    return load_model(structure, source)[0]


def _friction_model(mech, joints, owners):
    """The `FrictionModel` of the mechanism's joints with friction, then of its stops (each
    holds its joint while the joint rests on it); None without either."""
    items = list(getattr(mech, "frictions", ())) + list(getattr(mech, "stops", ()))
    if not items:
        return None
    from ..problem.friction import FrictionElement, FrictionModel
    return FrictionModel(tuple(
        FrictionElement(f, joints[f.joint.name],
                        tuple(i for i, o in enumerate(owners) if o == f.joint.name))
        for f in items))


def mass_diagonal(mech) -> np.ndarray:
    """The bodies' mass diagonals in coordinate order. A point mass (a rigid body of inertia
    0) must be held from turning: joined by a prismatic joint to the ground or to a body so
    held (a cross slide), else ModelError naming it. Its angle then stays constant in every
    motion (θ̇ = θ̈ = 0), so its entry of M multiplies zero: it takes a stand-in, its mass
    times the median squared radius of gyration of the other rigid bodies (1 m² where
    there are none), which keeps M invertible and changes no motion, reaction or energy."""
    points = {id(b): b for b in mech.bodies if isinstance(b, RigidBody) and b.inertia == 0.0}
    if not points:
        return np.concatenate([b.mass_diagonal for b in mech.bodies])
    held = {id(mech.ground)}
    grew = True
    while grew:
        grew = False
        for j in mech.joints:
            if j.kind == "prismatic" and (id(j.body_a) in held) != (id(j.body_b) in held):
                held.update((id(j.body_a), id(j.body_b)))
                grew = True
    loose = [b.name for key, b in points.items() if key not in held]
    if loose:
        raise ModelError(f"mechanism '{mech.name}': body '{loose[0]}' is a point mass (inertia "
                         "0) that its joints do not keep from turning; a point mass must "
                         "slide on a prismatic joint to the ground (or to a body so held): "
                         "give it an inertia (RigidBody.rectangle, .disc, .polygon compute "
                         "one from its shape)")
    gyration = [b.inertia / b.mass for b in mech.bodies
                if isinstance(b, RigidBody) and b.inertia > 0.0]
    squared = float(np.median(gyration)) if gyration else 1.0
    out = []
    for b in mech.bodies:
        d = b.mass_diagonal
        out.append(np.array([d[0], d[1], b.mass * squared]) if id(b) in points else d)
    return np.concatenate(out)


def joint_geometry(mech, starts) -> dict:
    """Each joint's name -> its `JointGeometry` (`mechsim.problem.geometry`): what its
    coordinate, rate and reactions are evaluated from."""
    from ..problem.geometry import JointGeometry
    by_id = {id(b): starts[b.name] for b in mech.bodies}
    out = {}
    for j in mech.joints:
        local_a, local_b = (tuple(float(x) for x in pt) for pt in j.attachment_points())
        values = [value_of(x) for x in j.parameter_values()]
        out[j.name] = JointGeometry(j, dict(zip(j.parameter_names, values)),
                                    by_id, local_a, local_b)
    return out


def _load_data(mech, starts, joints):
    """(SpringData list, PointLoad list, RotationalSpringData list) of the mechanism's loads;
    loads on the ground, which do no work, are left out. `joints`: the joints' geometry, for
    loads that read a joint's coordinate."""
    springs, loads, torsion = [], [], []
    for ld in mech.loads:
        if isinstance(ld, Spring):
            sa, sb = ld.body_a.local_point(ld.at_a), ld.body_b.local_point(ld.at_b)
            springs.append(SpringData(
                ld.name, starts[ld.body_a.name], starts[ld.body_b.name],
                tuple(sa), tuple(sb), ld.stiffness, ld.damping, ld.rest_length,
                ld.body_a.point_modes(sa), ld.body_b.point_modes(sb),
                _constant_partials(ld)))
        elif isinstance(ld, RotationalSpring):
            torsion.append(RotationalSpringData(ld.name, starts[ld.body_a.name],
                                                starts[ld.body_b.name], ld.stiffness,
                                                ld.damping, ld.rest_angle,
                                                _constant_partials(ld)))
        elif starts[ld.body.name] is None:
            continue
        elif isinstance(ld, Force):
            s = ld.body.local_point(ld.at)
            loads.append(PointLoad(ld.name, starts[ld.body.name], tuple(s),
                                   _checked(ld, ld.force, f"force '{ld.name}'", _as_force,
                                            "two finite numbers", joints),
                                   False, ld.body.point_modes(s),
                                   callable(ld.force) and ld.inputs != "t",
                                   _constant_partials(ld)))
        else:
            loads.append(PointLoad(ld.name, starts[ld.body.name], None,
                                   _checked(ld, ld.torque, f"torque '{ld.name}'", _as_torque,
                                            "a finite number", joints), True,
                                   reads_state=callable(ld.torque) and ld.inputs != "t",
                                   partials=_constant_partials(ld)))
    return springs, loads, torsion


def _constant_partials(load) -> tuple:
    """((Parameter name, ∂numbers/∂it), …) of a load's numbers as given (a spring's
    stiffness, damping and rest value; a constant force's components or torque)."""
    numbers = load.exact_numbers()
    named = parameter_names(numbers)
    return tuple((name, tuple(column)) for name, column in
                 zip(named, gradient(numbers, named).T.tolist()))


def _flexible_data(mech, starts) -> list[FlexibleData]:
    flexible = []
    for b in mech.bodies:
        if isinstance(b, FlexibleBeam):
            from ..flexible.kernel import load_kernel
            inv = b.invariants()
            flexible.append(FlexibleData(b.name, starts[b.name], inv, load_kernel(b.n_modes),
                                         inv.kernel_parameters(mech.gravity), b.point_modes))
    return flexible


def drawing(mech, starts) -> list:
    """Polylines for drawings and exports, each in its body's frame: a body's own outline
    where a shape constructor gave it one (rectangle, disc, polygon), else a gear's pitch
    circle or a cam's pitch curve (`Gear.spur`, `PointOnCurve`); a body with three or
    more joints not on one line (a ternary link) as the closed polygon round them; one
    held by a single point (a slider block on its guide) as a square of its inertia's size
    (side √(6 I/m), at least 4 % of the mechanism); else a line through its attachment
    points and centre of mass (ordered along their main direction); a beam through 4 points
    per element."""
    span = _span(mech)
    attached = {b.name: [np.zeros(2)] for b in mech.bodies}
    for j in mech.joints:
        for body, local in zip((j.body_a, j.body_b), j.attachment_points()):
            if body.name in attached:
                attached[body.name].append(np.asarray(local, float))
    for ld in mech.loads:
        for body, at in load_points(ld):
            if body.name in attached:
                attached[body.name].append(body.local_point(at))
    # A gear drawn as its pitch circle, a cam as its pitch curve, where no shape is given.
    pitch = {}
    for item in mech.joints + mech.gears:
        for body, line in getattr(item, "drawn", lambda: [])():
            pitch.setdefault(id(body), line)
    out = []
    for b in mech.bodies:
        if isinstance(b, FlexibleBeam):
            xi = np.linspace(0.0, b.length, 4 * b.n_elements + 1)
            local = np.column_stack([xi, np.zeros_like(xi)])
            modal = np.stack([b.point_modes(s) for s in local])
            out.append((b.name, starts[b.name], local, modal))
            continue
        shape = pitch.get(id(b)) if getattr(b, "outline", None) is None else None
        local = shape if shape is not None else _outline(b, attached[b.name], span)
        out.append((b.name, starts[b.name], local, None))
    return out


def _span(mech) -> float:
    """The mechanism's size: the largest distance between two bodies' frames or joint
    points (1 m where it has no extent)."""
    pts = [b.position for b in mech.bodies] + [j.at for j in mech.joints
                                               if getattr(j, "at", None) is not None]
    pts = np.array(pts, float).reshape(-1, 2)
    span = float(np.max(np.ptp(pts, axis=0))) if len(pts) > 1 else 0.0
    return span if span > 0.0 else 1.0


def _outline(body, attached, span) -> np.ndarray:
    """A rigid body's drawing in its frame (see `drawing`)."""
    if getattr(body, "outline", None) is not None:
        return np.asarray(body.outline, float)
    pts = np.unique(np.round(np.array(attached), 12), axis=0)
    joints = np.unique(np.round(np.array(attached[1:]), 12), axis=0).reshape(-1, 2)
    if len(joints) >= 3:
        centred = joints - joints.mean(axis=0)
        if np.linalg.svd(centred, compute_uv=False)[1] > 1e-6 * span:
            angles = np.arctan2(centred[:, 1], centred[:, 0])
            ring = joints[np.argsort(angles)]          # round the joints (a convex link)
            return np.vstack([ring, ring[:1]])
    if len(pts) == 1:
        side = max(math.sqrt(6.0 * body.inertia / body.mass), 0.04 * span)
        corners = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1], [-1, -1]]) * side / 2.0
        return pts[0] + corners
    centred = pts - pts.mean(axis=0)
    direction = np.linalg.svd(centred)[2][0]
    return pts[np.argsort(centred @ direction)]


def _checked(load, given, owner: str, convert, expected: str, joints):
    """`given` if it is a constant; else a function of (t, q, v) that calls the user's with
    what `load.inputs` says (t; t and a joint's coordinate and rate; t, q and v) and turns
    its exception, or a value `convert` refuses (None), into a LoadError naming `owner`."""
    if not callable(given):
        return given
    if load.inputs == "joint":
        from ..problem.geometry import joint_coordinates
        geometry = joints[load.joint.name]

        def arguments(t, q, v):
            s, rate = joint_coordinates(geometry, q[None], v[None])
            return t, float(s[0]), float(rate[0])
    elif load.inputs == "state":
        def arguments(t, q, v):
            return t, q.copy(), v.copy()
    else:
        def arguments(t, q, v):
            return (t,)

    def value(t, q, v):
        got = call_user(given, arguments(t, q, v), owner)
        out = convert(got)
        if out is None:
            raise LoadError(f"{owner}: the function returned {got!r:.60} at t = {t:.9g}; "
                            f"expected {expected}")
        return out
    return value


def _as_force(given):
    try:
        out = np.asarray(given, float)
    except (TypeError, ValueError):
        return None
    return out if out.shape == (2,) and np.all(np.isfinite(out)) else None


def _as_torque(given):
    try:
        out = float(given)
    except (TypeError, ValueError):
        return None
    return out if math.isfinite(out) else None
