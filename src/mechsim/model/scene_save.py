"""A mechanism built in Python written as a scene (`mechsim.app.scene`'s schema), TOML or JSON:
declarative data that `mechsim.load_mechanism` (or `load_scene`) builds again, never pickle.

Every number is written to round-trip exactly. What the schema cannot hold is refused,
naming it, rather than dropped: a load given as a Python function (give it as a number
or an expression in t),
a load that reads a joint's state, a beam's initial modal amplitudes.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

from ..files import written
from .bodies import RigidBody
from .checks import ModelError
from .flexible_beam import FlexibleBeam
from .forces import Force, RotationalSpring, Spring, TimeLaw, Torque
from .joints import PointOnCurve, Prismatic, Revolute


def _vector(v) -> list[float]:
    return [float(v[0]), float(v[1])]


def scene_data(mech) -> dict:
    """The scene of `mech` as a dict of the scene schema (ModelError naming what it
    cannot hold)."""
    owner = f"mechanism '{mech.name}': save"
    data = {"name": mech.name, "gravity": _vector(mech.gravity), "body": [], "joint": [],
            "driver": [], "gear": [], "stop": [], "friction": [], "spring": [], "force": [], "torque": [], "rotational_spring": [],
            "speed": [], "channel": []}
    for body in mech.bodies:
        data["body"].append(_body(body, owner))
    for joint in mech.joints:
        data["joint"].append(_joint(joint, owner))
    for driver in mech.drivers:
        table = {"name": driver.name, "joint": driver.joint.name}
        if getattr(driver, "evaluated", False) and not driver.tabulated:
            raise ModelError(f"{owner}: driver '{driver.name}' is a Python function: a scene "
                             "holds expressions and tables (give its law as one of them)")
        if getattr(driver, "tabulated", False):
            table["table"] = [[float(t), float(s)]
                              for t, s in zip(driver.law.times, driver.law.values)]
        else:
            table["expression"] = driver.expression
        data["driver"].append(table)
    for stop in mech.stops:
        table = {"name": stop.name, "joint": stop.joint.name,
                 "restitution": float(stop.restitution), "rest_speed": float(stop.rest_speed)}
        table.update({k: float(getattr(stop, k)) for k in ("lower", "upper")
                      if getattr(stop, k) is not None})
        data["stop"].append(table)
    for fr in mech.frictions:
        table = {"name": fr.name, "joint": fr.joint.name, "mu": fr.mu,
                 "mu_static": fr.mu_static, "preload": fr.preload}
        table.update({k: float(getattr(fr, k)) for k in ("radius", "length",
                                                          "transition_velocity")
                      if getattr(fr, k) is not None})
        data["friction"].append(table)
    for gear in mech.gears:
        table = {"type": gear.form, "name": gear.name,
                 "joints": [gear.joint_a.name, gear.joint_b.name]}
        if gear.form == "spur":
            table["radii"] = [float(gear.radius_a), float(gear.radius_b)]
            table["internal"] = bool(gear.internal)
            if gear.carrier_given:
                table["carrier"] = gear.carrier.name
        elif gear.form == "rack":
            table["radius"] = float(gear.radius_a)
        else:
            table["ratio"] = float(gear.ratio)
        data["gear"].append(table)
    for load in mech.loads:
        kind, table = _load(load, owner)
        data[kind].append(table)
    for joint, rate in mech.speeds.items():
        data["speed"].append({"joint": joint, "rate": float(rate)})
    for channel in mech.channels:
        data["channel"].append({"name": channel.name, "expression": channel.expression,
                                "unit": channel.unit})
    return {key: value for key, value in data.items() if value != []}


def _body(body, owner) -> dict:
    if isinstance(body, FlexibleBeam):
        if any(body.eta) or any(body.eta_velocity):
            raise ModelError(f"{owner}: beam '{body.name}' starts deformed (eta or "
                             "eta_velocity): the scene schema holds beams that start straight")
        return {"type": "flexible_beam", "name": body.name, "start": _vector(body.position),
                "length": float(body.length), "angle": float(body.angle),
                "youngs_modulus": float(body.youngs_modulus), "density": float(body.density),
                "area": float(body.area), "second_moment": float(body.second_moment),
                "n_elements": int(body.n_elements), "n_modes": int(body.n_modes),
                "boundary": body.boundary, "damping_ratio": float(body.damping_ratio),
                "velocity": _vector(body.velocity),
                "angular_velocity": float(body.angular_velocity)}
    if type(body) is not RigidBody:
        raise ModelError(f"{owner}: body '{body.name}' is a {type(body).__name__}, which the "
                         "scene schema does not hold")
    table = {"name": body.name, "mass": float(body.mass), "inertia": float(body.inertia),
             "position": _vector(body.position), "angle": float(body.angle),
             "velocity": _vector(body.velocity),
             "angular_velocity": float(body.angular_velocity)}
    if body.outline is not None:
        table["outline"] = [_vector(p) for p in body.outline]
    return table


def _joint(joint, owner) -> dict:
    table = {"type": joint.kind, "name": joint.name,
             "bodies": [joint.body_a.name, joint.body_b.name]}
    if isinstance(joint, Revolute):
        if joint.at is not None:
            table["at"] = _vector(joint.at)
        else:
            table["local_a"], table["local_b"] = _vector(joint.local_a), _vector(joint.local_b)
    elif isinstance(joint, Prismatic):
        table["axis"], table["at"] = _vector(joint.axis), _vector(joint.at)
    elif isinstance(joint, PointOnCurve):
        table["at"], table["centre"] = _vector(joint.at), _vector(joint.centre)
        if hasattr(joint.shape, "points"):                    # a spline through points
            table["polar_points"] = [_vector(row) for row in joint.shape.points]
        else:
            table[joint.form] = _vector(joint.shape) if joint.form == "line" else \
                float(joint.shape) if joint.form == "circle" else joint.shape.text
    else:
        raise ModelError(f"{owner}: joint '{joint.name}' is a {type(joint).__name__}, which "
                         "the scene schema does not hold")
    return table


def _load(load, owner) -> tuple[str, dict]:
    if isinstance(load, Spring):
        return "spring", {"name": load.name, "bodies": [load.body_a.name, load.body_b.name],
                          "at_a": _vector(load.at_a), "at_b": _vector(load.at_b),
                          "stiffness": float(load.stiffness),
                          "rest_length": float(load.rest_length),
                          "damping": float(load.damping)}
    if isinstance(load, RotationalSpring):
        return "rotational_spring", {"name": load.name,
                                     "bodies": [load.body_a.name, load.body_b.name],
                                     "stiffness": float(load.stiffness),
                                     "damping": float(load.damping),
                                     "rest_angle": float(load.rest_angle)}
    if isinstance(load, (Force, Torque)):
        value = load.force if isinstance(load, Force) else load.torque
        if isinstance(value, TimeLaw) and load.joint is None and load.inputs == "t":
            if isinstance(load, Force):
                return "force", {"name": load.name, "body": load.body.name,
                                 "force": list(value.texts), "at": _vector(load.at)}
            return "torque", {"name": load.name, "body": load.body.name,
                              "torque": value.texts[0]}
        if callable(value) or load.joint is not None:
            raise ModelError(f"{owner}: {type(load).__name__.lower()} '{load.name}' is a Python "
                             "function: a scene holds constant forces and torques (save the "
                             "rest of the model without it, or give it as a number)")
        if isinstance(load, Force):
            return "force", {"name": load.name, "body": load.body.name,
                             "force": _vector(value), "at": _vector(load.at)}
        return "torque", {"name": load.name, "body": load.body.name, "torque": float(value)}
    raise ModelError(f"{owner}: {load!r} is a load the scene schema does not hold")


def write_scene(data: dict, path) -> Path:
    """The scene `data` at `path`: JSON where it ends in .json, else TOML (written through
    `mechsim.files.written`)."""
    path = Path(path)
    text = json.dumps(data, indent=2, ensure_ascii=False) + "\n" \
        if path.suffix.lower() == ".json" else toml_text(data)

    def write(p):
        Path(p).write_text(text, encoding="utf-8")
    return written(path, write)


def toml_text(data: dict) -> str:
    """TOML of a scene dict: top-level values first, then each array of tables. Strings
    are written as JSON strings (valid TOML basic strings), numbers by repr (exact)."""
    lines, arrays = [], []
    for key, value in data.items():
        if isinstance(value, list) and value and isinstance(value[0], dict):
            arrays.append((key, value))
        else:
            lines.append(f"{key} = {_toml_value(value)}")
    for key, tables in arrays:
        for table in tables:
            lines += ["", f"[[{key}]]"] + [f"{k} = {_toml_value(v)}" for k, v in table.items()]
    return "\n".join(lines) + "\n"


def _toml_value(value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return json.dumps(value, ensure_ascii=False)
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if not math.isfinite(value):
            raise ValueError(f"a scene holds finite numbers, got {value}")
        return repr(value)
    if isinstance(value, list):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    raise TypeError(f"no TOML for {type(value).__name__}")

