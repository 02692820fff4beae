"""Plots of results. matplotlib is imported here only, when a plot is asked for; figures are
built with the object API and never shown: a plain Figure, or a pyplot one where the program
uses pyplot (`new_figure`), so that `plt.show()` shows it."""

from __future__ import annotations

from ..files import save_figure


def new_figure(size):
    """A figure of `size` inches: a pyplot one where the program uses pyplot (so that
    `plt.show()` shows it), else a plain Figure (no pyplot state for a script that only
    writes files)."""
    import sys
    if "matplotlib.pyplot" in sys.modules:
        import matplotlib.pyplot as plt
        return plt.figure(figsize=size, layout="constrained")
    from matplotlib.figure import Figure
    return Figure(figsize=size, layout="constrained")


def new_axes(ax, size=(7.0, 3.6)):
    if ax is not None:
        return ax.figure, ax
    fig = new_figure(size)
    return fig, fig.add_subplot()


# Beyond this many solver switches, they are marked as ticks on the time axis, not lines.
MAX_SWITCH_LINES = 12


def plot_energy(result, path=None, ax=None):
    """The energies in joules over the energy balance. Above: kinetic T, potential V,
    strain U (where there is any), total E = T + V + U, and the work W of each damper,
    load and driver (dashed), titled with the mechanism, its method and passages. Below:
    the balance (E − E₀ − W) / scale, the scale in joules on the axis, solver switches
    marked (as lines, or as ticks with their count where they are many). Singular
    passages shaded in both. With `ax` given, the balance alone on it."""
    if ax is not None:
        fig = ax.figure
        _balance(ax, result)
        ax.set_title(_energy_title(result))
        return _finish(fig, ax, None, _balance_label(result), path)
    fig = new_figure((7.0, 6.0))
    top, bottom = fig.subplots(2, 1, sharex=True, height_ratios=[3, 2])
    e = result.energy
    top.plot(result.t, e.kinetic, lw=1.2, label="kinetic T")
    top.plot(result.t, e.potential, lw=1.2, label="potential V")
    if e.strain.any():
        top.plot(result.t, e.strain, lw=1.2, label="strain U")
    top.plot(result.t, e.total, lw=2.0, color="k", label="total E = T + V" +
             (" + U" if e.strain.any() else ""))
    if e.channels:
        for k, channel in enumerate(e.channels):
            top.plot(result.t, e.work_by[:, k], "--", lw=1.2, label=f"work W of {channel}")
    elif e.work.any():
        top.plot(result.t, e.work, "--", lw=1.2, label="work W")
    _shade_passages(top, result)
    _finish(fig, top, _energy_title(result), "energy [J]", None, xlabel="")
    _balance(bottom, result)
    return _finish(fig, bottom, None, _balance_label(result), path)


def _energy_title(result) -> str:
    name = result.problem.title if result.problem is not None else "result"
    passages = len(result.singular_passages)
    plural = "" if passages == 1 else "s"
    return (f"Energy: {name} ({result.stats.get('method', '?')}"
            + (f", {passages} singular passage{plural}" if passages else "") + ")")


def _balance_label(result) -> str:
    return f"balance (E − E₀ − W) / {result.energy_scale:.4g} J [-]"


def _balance(ax, result) -> None:
    """The energy balance over time on `ax`, passages shaded and switches marked."""
    ax.plot(result.t, result.energy_drift, lw=1.2, color="C0", label="energy balance")
    _shade_passages(ax, result)
    switches = result.switches
    if len(switches) <= MAX_SWITCH_LINES:
        for k, sw in enumerate(switches):
            ax.axvline(sw.t, color="C2", ls="--", lw=0.8,
                       label="solver switch" if k == 0 else None)
    else:
        ax.plot([sw.t for sw in switches], [0.0] * len(switches), "|", color="C2", ms=10,
                transform=ax.get_xaxis_transform(), label=f"{len(switches)} solver switches")


def _shade_passages(ax, result):
    """The singular passages as shaded spans (one legend entry for all of them)."""
    for k, sp in enumerate(result.singular_passages):
        ax.axvspan(sp.t_start, max(sp.t_end, sp.t_start + 1e-9 * (result.t[-1] - result.t[0])),
                   color="C3", alpha=0.15, lw=0, label="singular passage" if k == 0 else None)


def literal_text(fig):
    """Every text of `fig` drawn as written: names are the user's, and a `$` in one would be
    read as matplotlib's math markup (an unbalanced one fails the drawing). Returns fig."""
    from matplotlib.text import Text
    for text in fig.findobj(Text):
        text.set_parse_math(False)
    return fig


def _finish(fig, ax, title, ylabel, path, xlabel="time [s]"):
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    if title is not None:
        ax.set_title(title)
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize="small")
    literal_text(fig)
    if path is not None:
        save_figure(fig, path)
    return fig


def plot_reactions(result, path=None, joints=None, ax=None):
    """The magnitude of each joint's force over time (all joints where `joints` is None),
    singular passages shaded, samples whose reactions are not unique marked."""
    fig, ax = new_axes(ax)
    table = result.reactions
    names = table.joint_names if joints is None else [getattr(j, "name", j) for j in joints]
    for name in names:
        abs_force = _magnitude(table.force(name))
        ax.plot(result.t, abs_force, lw=1.2, label=name)
        flagged = table.indeterminate(name)
        if flagged.any():
            ax.plot(result.t[flagged], abs_force[flagged], "x", ms=4, color="k",
                    label=None)
    _shade_passages(ax, result)
    title = f"Joint forces ({result.problem.title if result.problem else 'result'})"
    return _finish(fig, ax, title, "|F| [N]", path)


def plot_efforts(result, path=None, ax=None):
    """Each driver's effort (torque or force) over time above its power; with `ax` given,
    the efforts alone on it."""
    table = result.reactions
    if ax is None:
        fig = new_figure((7.0, 5.4))
        ax, power_ax = fig.subplots(2, 1, sharex=True)
    else:
        fig, power_ax = ax.figure, None
    units = {name: _effort_unit(table, name) for name in table.driver_names}
    for k, name in enumerate(table.driver_names):
        effort = table.effort(name)
        ax.plot(result.t, effort, lw=1.2, color=f"C{k}", label=f"{name} [{units[name]}]")
        if power_ax is not None:
            power_ax.plot(result.t, effort * table.driver_rate(name), lw=1.2, color=f"C{k}",
                          label=name)
    title = f"Driver efforts ({result.problem.title if result.problem else 'result'})"
    if power_ax is not None:
        _shade_passages(power_ax, result)
        _finish(fig, power_ax, "", "power [W]", None)
    _shade_passages(ax, result)
    kinds = set(units.values())
    ylabel = {frozenset({"N·m"}): "torque [N·m]", frozenset({"N"}): "force [N]"}.get(
        frozenset(kinds), "effort [N·m or N, as labelled]")
    return _finish(fig, ax, title, ylabel, path, xlabel="time [s]" if power_ax is None else "")


def _effort_unit(table, driver) -> str:
    return "N" if table.driver_kind(driver) == "prismatic" else "N·m"


def _magnitude(F):
    import numpy as np
    return np.hypot(F[:, 0], F[:, 1])


def plot_quantities(result, coordinates=(), points=(), joints=(), reactions=(), efforts=(),
                    path=None):
    """One panel per kind asked for, over time: coordinates by name, points [(body, local
    point)] (x and y), joint coordinates, joint forces (magnitude) and driver efforts.
    Returns the Figure."""
    from .table import coordinate_unit
    panels = []
    by_unit = {}
    for n in coordinates:
        by_unit.setdefault(coordinate_unit(n), []).append((n, result.coordinate(n)))
    for unit, lines in by_unit.items():
        panels.append((f"coordinate [{unit}]", lines))
    if points:
        lines = []
        for body, local in points:
            xy = result.point(body, local)
            label = f"{getattr(body, 'name', body)} ({float(local[0]):g}, {float(local[1]):g})"
            lines += [(f"{label} x", xy[:, 0]), (f"{label} y", xy[:, 1])]
        panels.append(("position [m]", lines))
    if joints:
        table = result.reactions
        for unit, kind in (("rad", "revolute"), ("m", "prismatic")):
            lines = [(getattr(j, "name", j), result.joint_coordinate(j)) for j in joints
                     if table.kind(j) == kind]
            if lines:
                panels.append((f"joint coordinate [{unit}]", lines))
    if reactions:
        panels.append(("|F| [N]", [(getattr(j, "name", j),
                                    _magnitude(result.joint_force(j))) for j in reactions]))
    if efforts:
        table = result.reactions
        for unit, kind in (("N·m", "revolute"), ("N", "prismatic")):
            lines = [(getattr(d, "name", d), result.driver_effort(d)) for d in efforts
                     if table.driver_kind(d) == kind]
            if lines:
                panels.append((f"{'torque' if unit == 'N·m' else 'force'} [{unit}]", lines))
    if not panels:
        raise ValueError("plot: name something to plot (coordinates=, points=, joints=, "
                         "reactions= or efforts=)")
    fig = new_figure((7.0, 2.2 + 1.8 * len(panels)))
    axes = fig.subplots(len(panels), 1, sharex=True, squeeze=False)[:, 0]
    for ax, (ylabel, lines) in zip(axes, panels):
        for label, y in lines:
            ax.plot(result.t, y, lw=1.2, label=label)
        _shade_passages(ax, result)
        _finish(fig, ax, None, ylabel, None, xlabel="")
    axes[-1].set_xlabel("time [s]")
    axes[0].set_title(result.problem.title if result.problem is not None else "result")
    literal_text(fig)
    if path is not None:
        save_figure(fig, path)
    return fig
