"""A result as a table an engineer can take away: one column per quantity, each named with
its SI unit ("t [s]", "crank.angle [rad]", "motor effort [N·m]"), as a dict of arrays,
a CSV file (`mechsim.files`: never through a link, never half-written) or a pandas
DataFrame (the `pandas` extra).

Columns, in order: time; every coordinate, then its rate (with `velocities`); the global
position of each point asked for; for each joint asked for, the force it applies to its
body_b in global axes, the couple of a prismatic joint, the coordinate and rate of a
revolute or prismatic one; for each
driver asked for, its effort and power (a joint's friction and stop forces with its
reactions); the mechanism's channels (`mechsim.Channel`,
"name [unit]"); the functions passed as `channels`. Reactions and efforts are computed only
when asked for (`SimulationResult.reactions`).
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

# A coordinate's unit by the last part of its name (`<body>.<coordinate>`); modal
# amplitudes of mass-normalised modes (Φᵀ M Φ = I) are in √kg·m.
COORDINATE_UNITS = {"x": "m", "y": "m", "angle": "rad"}
MODAL_UNIT = "√kg·m"


def coordinate_unit(name: str) -> str:
    """The unit of the coordinate `name` ("crank.angle" -> "rad", "coupler.eta1" -> √kg·m)."""
    last = name.rsplit(".", 1)[-1]
    if last in COORDINATE_UNITS:
        return COORDINATE_UNITS[last]
    return MODAL_UNIT if last.startswith("eta") else "-"


def _rate(unit: str) -> str:
    return f"{unit}/s" if unit != "-" else "1/s"


def columns(result, points=(), joints=None, drivers=None, velocities=True,
            channels=None) -> dict:
    """{column name with unit: (n,) array} of `result` (see the module docstring).
    `points`: (body, local point) pairs; `joints`, `drivers`: names or objects, or True for
    all of them, None for none; `channels`: {column name (with its unit, as you write it):
    a function of the result giving one number per sample}, the user's own quantities
    (`lambda r: r.point_velocity("crank", (0.1, 0))[:, 0]`), last."""
    out = {"t [s]": np.asarray(result.t)}
    names = result.coordinate_names
    for k, name in enumerate(names):
        out[f"{name} [{coordinate_unit(name)}]"] = result.q[:, k]
    if velocities:
        for k, name in enumerate(names):
            out[f"{name} rate [{_rate(coordinate_unit(name))}]"] = result.v[:, k]
    for body, local in points:
        label = getattr(body, "name", body)
        xy = result.point(body, local)
        where = f"{label}({float(local[0]):g}, {float(local[1]):g})"
        out[f"{where}.x [m]"], out[f"{where}.y [m]"] = xy[:, 0], xy[:, 1]
    if joints is not None or drivers is not None:
        table = result.reactions
        for joint in _chosen(joints, table.joint_names):
            name = getattr(joint, "name", joint)
            kind = table.kind(name)
            force = result.joint_force(name)
            out[f"{name} force x [N]"], out[f"{name} force y [N]"] = force[:, 0], force[:, 1]
            if kind == "prismatic":
                out[f"{name} couple [N·m]"] = result.joint_moment(name)
            if kind in ("revolute", "prismatic"):        # the joints with a coordinate
                unit = "m" if kind == "prismatic" else "rad"
                out[f"{name} coordinate [{unit}]"] = result.joint_coordinate(name)
                out[f"{name} rate [{unit}/s]"] = result.joint_rate(name)
                effort = "N" if kind == "prismatic" else "N·m"
                for element in _contacts(result, name):   # its friction's and stops' forces
                    out[f"{element.name} {element.kind} force [{effort}]"] = \
                        result.friction_force(element.name) if element.kind == "friction" \
                        else result.stop_force(element.name)
        for driver in _chosen(drivers, table.driver_names):
            name = getattr(driver, "name", driver)
            unit = "N" if table.driver_kind(name) == "prismatic" else "N·m"
            out[f"{name} effort [{unit}]"] = result.driver_effort(name)
            out[f"{name} power [W]"] = result.driver_power(name)
    for channel in getattr(result.mechanism, "channels", ()):
        out[channel.column] = channel.values(result)
    for name, channel in (channels or {}).items():
        out[name] = _channel(result, name, channel)
    return out


def _contacts(result, joint: str) -> list:
    """The friction and stop elements on the joint named `joint` (`FrictionModel`)."""
    model = getattr(result.problem, "friction", None)
    return [e for e in (model.elements if model is not None else ())
            if e.geometry.joint.name == joint]


def _channel(result, name, channel) -> np.ndarray:
    """The user's channel `name` evaluated on `result`, checked: one finite-or-NaN number
    per sample, else a ValueError naming it."""
    if not isinstance(name, str) or not name.strip():
        raise ValueError(f"table: a channel's name must be a non-empty string, got {name!r}")
    if not callable(channel):
        raise ValueError(f"table: channel {name!r} must be a function of the result, got "
                         f"{type(channel).__name__}")
    values = np.asarray(channel(result), dtype=float)
    if values.shape != (len(result.t),):
        raise ValueError(f"table: channel {name!r} gave shape {values.shape}; it must give one "
                         f"number per sample, shape ({len(result.t)},)")
    return values


def _chosen(which, every):
    if which is None:
        return []
    if which is True:
        return list(every)
    if isinstance(which, str) or not hasattr(which, "__iter__"):
        return [which]
    return list(which)


def write_csv(table: dict, path) -> Path:
    """The columns `table` as a CSV file at `path`: a header of the column names, then one
    row per sample, numbers written to round-trip exactly."""
    from ..files import written
    keys = list(table)
    data = np.column_stack([np.asarray(table[k], float) for k in keys]) if keys else \
        np.zeros((0, 0))

    def write(p):
        with open(p, "w", newline="", encoding="utf-8") as f:
            w = csv.writer(f)
            w.writerow(keys)
            w.writerows([repr(float(x)) for x in row] for row in data)
    return written(path, write)


def data_frame(table: dict):
    """The columns `table` as a pandas DataFrame (the `pandas` extra)."""
    try:
        import pandas
    except ImportError:
        raise ImportError("to_pandas needs pandas: pip install pandas (from a checkout, pip "
                          "install '.[pandas]')") from None
    return pandas.DataFrame(table)
