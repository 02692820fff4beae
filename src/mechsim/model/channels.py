"""Channels: quantities of the user's own, written as expressions and recorded with every
result of the mechanism (table columns, `SimulationResult.channel`)."""

from __future__ import annotations

import math

from .checks import ModelError
from .expressions import parse

# What a channel's expression may name besides `t` (time [s]), for each coordinate
# `<body>.<coordinate>` and each joint with a coordinate:
COORDINATE_SUFFIXES = ("", ".rate", ".acceleration")
JOINT_SUFFIXES = (".coordinate", ".rate")


def channel_names(mechanism) -> set[str]:
    """The names a channel of `mechanism` may use, as it stands: `t`; every coordinate
    ("crank.angle"), its rate ("crank.angle.rate") and acceleration
    ("crank.angle.acceleration"); every revolute or prismatic joint's coordinate and rate
    ("pin_B.coordinate", "pin_B.rate")."""
    names = {"t"}
    for c in mechanism.coordinate_names:
        names.update(c + s for s in COORDINATE_SUFFIXES)
    for j in mechanism.joints:
        if j.kind in ("revolute", "prismatic"):
            names.update(j.name + s for s in JOINT_SUFFIXES)
    return names


class Channel:
    """A quantity recorded with every result of the mechanism it is added to:
    `Channel("tip_speed", "hypot(rocker.x.rate, rocker.y.rate)", unit="m/s")`.

    `expression` is an arithmetic expression (`mechsim.model.expressions`: numbers, pi, e,
    ``+ − * / **``, parentheses, sin … degrees; parsed, never executed) of the time `t`,
    the coordinates by name (`crank.angle`), their rates (`crank.angle.rate`) and
    accelerations (`crank.angle.acceleration`), and the coordinates and rates of revolute
    and prismatic joints by the joint's name (`pin_B.coordinate`, `pin_B.rate`: the
    relative angle of its bodies, or the slide). It is checked against the mechanism when
    added (`Mechanism.add`: its bodies and joints first), and evaluated at each output
    sample of a result (`SimulationResult.channel(name)`; a column `name [unit]` of its
    table and CSV). Where it is undefined at a sample (log of a negative number, a division
    by zero) that sample is NaN. Accelerations and joint quantities are computed only for
    the results of a mechanism whose channels use them. `unit` is a label ("-" when none).
    """

    kind = "channel"

    def __init__(self, name: str, expression, unit: str = "-"):
        if not isinstance(name, str) or not name.strip() or len(name) > 80 or \
                any(ch in name for ch in "[]\n\r"):
            raise ModelError(f"channel: `name` must be a non-empty string of at most 80 "
                             f"characters without brackets or new lines, got {name!r:.60}")
        self.name = name.strip()
        if not isinstance(unit, str) or not unit.strip() or len(unit) > 40 or \
                any(ch in unit for ch in "[]\n\r,"):
            raise ModelError(f"channel '{self.name}': `unit` must be a short label such as "
                             f"'m/s' (no brackets, commas or new lines), got {unit!r:.60}")
        self.unit = unit.strip()
        if isinstance(expression, bool) or not isinstance(expression, (str, int, float)):
            raise ModelError(f"channel '{self.name}': `expression` must be a number or an "
                             f"expression string, got {type(expression).__name__}")
        self.expression = expression if isinstance(expression, str) else repr(float(expression))

    def parsed(self, names):
        """The parsed expression, checked against `names` (`channel_names`); a ModelError
        naming the channel where it is not a plain expression of them."""
        return parse(self.expression, names, f"channel '{self.name}' `expression`")

    @property
    def column(self) -> str:
        """Its table column: "name [unit]"."""
        return f"{self.name} [{self.unit}]"

    def values(self, result, expression=None):
        """Its value at each sample of `result`, shape (n,) (NaN where undefined)."""
        import numpy as np
        law = expression or self.parsed(channel_names(result.mechanism))
        n = len(result.t)
        columns = {"t": np.asarray(result.t, float)}
        index = {c: k for k, c in enumerate(result.coordinate_names)}
        qdd = None
        for name in law.names:
            if name == "t":
                continue
            base, _, last = name.rpartition(".")
            if name in index:
                columns[name] = result.q[:, index[name]]
            elif last == "rate" and base in index:
                columns[name] = result.v[:, index[base]]
            elif last == "acceleration" and base in index:
                qdd = result.accelerations() if qdd is None else qdd
                columns[name] = qdd[:, index[base]]
            elif last == "coordinate":
                columns[name] = result.joint_coordinate(base)
            else:
                columns[name] = result.joint_rate(base)
        out = np.empty(n)
        for i in range(n):
            try:
                out[i] = law.value(**{k: float(v[i]) for k, v in columns.items()})
            except (ArithmeticError, ValueError):
                out[i] = math.nan
        return out

    def __repr__(self):
        return f"Channel({self.name!r}, {self.expression!r}, unit={self.unit!r})"
