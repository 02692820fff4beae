"""The figures an engineer reads off a cycle: peak and RMS driver effort and power, peak
joint forces, and the transmission angle of four-bar loops.

The transmission angle μ at a revolute joint between a coupler (a link with no joint to
the ground) and an output link (pinned to the ground, not driven) is the angle between the
two links' lines through that joint, folded into [0°, 90°]: 90° transmits the coupler's
force wholly into turning the output link, and designers keep its minimum above about 40°.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.integrate import trapezoid


@dataclass
class CycleFigures:
    """drivers: name -> {"unit", "peak_effort", "rms_effort", "peak_power", "mean_power"}
    (efforts in `unit`, N·m or N; powers in W; peak = largest magnitude); joints: name -> {"peak_force" [N],
    "at": its time [s]}; transmission: joint name -> {"min", "max"} [degrees]; note: where
    some reactions are not unique (`ReactionTable.note`)."""
    drivers: dict = field(default_factory=dict)
    joints: dict = field(default_factory=dict)
    transmission: dict = field(default_factory=dict)
    note: str = ""

    def __str__(self):
        lines = []
        for name, d in self.drivers.items():
            unit = d.get("unit", "N·m")
            lines.append(f"driver '{name}': peak effort {d['peak_effort']:.4g} {unit}, RMS "
                         f"{d['rms_effort']:.4g} {unit}; peak power {d['peak_power']:.4g} W, "
                         f"mean {d['mean_power']:.4g} W")
        for name, j in self.joints.items():
            lines.append(f"joint '{name}': peak force {j['peak_force']:.4g} N at "
                         f"t = {j['at']:.4g} s")
        for name, mu in self.transmission.items():
            lines.append(f"transmission angle at '{name}': {mu['min']:.1f}° … "
                         f"{mu['max']:.1f}°")
        if self.note:
            lines.append(self.note)
        return "\n".join(lines)


def rms(x, t) -> float:
    """Root mean square of samples x(t) over the span (trapezoidal mean)."""
    if len(t) < 2:
        return float(np.sqrt(np.mean(x * x)))
    return float(np.sqrt(trapezoid(x * x, t) / (t[-1] - t[0])))


def cycle_figures(res) -> CycleFigures:
    """The figures of a result (a kinematic analysis or a simulation over a cycle)."""
    table = res.reactions
    out = CycleFigures(note=table.note())
    span = res.t[-1] - res.t[0] if len(res.t) > 1 else 1.0
    for name in table.driver_names:
        effort = table.effort(name)
        power = effort * table.driver_rate(name)
        out.drivers[name] = {
            "unit": "N" if table.driver_kind(name) == "prismatic" else "N·m",
            "peak_effort": float(effort[np.argmax(np.abs(effort))]),
            "rms_effort": rms(effort, res.t),
            "peak_power": float(power[np.argmax(np.abs(power))]),
            "mean_power": float(trapezoid(power, res.t) / span) if len(res.t) > 1
            else float(power[0])}
    for name in table.joint_names:
        magnitude = np.linalg.norm(table.force(name), axis=1)
        k = int(np.argmax(magnitude))
        out.joints[name] = {"peak_force": float(magnitude[k]), "at": float(res.t[k])}
    if res.problem is not None:
        out.transmission = transmission_angles(res.problem, res.q)
    return out


def transmission_angles(problem, q) -> dict:
    """joint name -> {"min", "max"} of the transmission angle (module docstring) at every
    coupler–output joint of the mechanism, over the states q."""
    from ..problem.geometry import joint_point
    joints = problem.joints
    driven = set(problem.driver_joints.values())
    grounded = {}            # body id -> the name of its (undriven) revolute to the ground
    links = {}               # body id -> the revolutes on it
    for name, g in joints.items():
        if g.joint.kind != "revolute":
            continue
        for body, start in ((g.joint.body_a, g.start_a), (g.joint.body_b, g.start_b)):
            if start is not None:
                links.setdefault(id(body), []).append(name)
        if (g.start_a is None) != (g.start_b is None) and name not in driven:
            moving = g.joint.body_b if g.start_a is None else g.joint.body_a
            grounded[id(moving)] = name
    points = {}

    def at(name):
        if name not in points:
            points[name] = joint_point(joints[name], q)
        return points[name]
    out = {}
    for name, g in joints.items():
        if g.joint.kind != "revolute" or g.start_a is None or g.start_b is None:
            continue
        for coupler, output in ((g.joint.body_a, g.joint.body_b),
                                (g.joint.body_b, g.joint.body_a)):
            if id(output) not in grounded or id(coupler) in grounded or \
                    any(joints[j].start_a is None or joints[j].start_b is None
                        for j in links.get(id(coupler), ())):
                continue
            others = [j for j in links.get(id(coupler), ()) if j != name]
            if len(others) != 1:
                continue
            p = at(name)
            u, w = at(others[0]) - p, at(grounded[id(output)]) - p
            cos = np.sum(u * w, axis=1) / (np.linalg.norm(u, axis=1) * np.linalg.norm(w, axis=1))
            mu = np.degrees(np.arccos(np.clip(np.abs(cos), 0.0, 1.0)))
            out[name] = {"min": float(mu.min()), "max": float(mu.max())}
    return out
