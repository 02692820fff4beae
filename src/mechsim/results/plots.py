"""Plots of results. matplotlib is imported here only, when a plot is asked for; figures are
built with the object API (no pyplot state, never `show()`)."""

from __future__ import annotations


def new_axes(ax, size=(7.0, 3.6)):
    if ax is not None:
        return ax.figure, ax
    from matplotlib.figure import Figure
    fig = Figure(figsize=size, layout="constrained")
    return fig, fig.add_subplot()


def plot_energy(result, path=None, ax=None):
    fig, ax = new_axes(ax)
    ax.plot(result.t, result.energy_drift, lw=1.2, color="C0", label="energy drift")
    for k, sp in enumerate(result.singular_passages):
        ax.axvspan(sp.t_start, max(sp.t_end, sp.t_start + 1e-9 * (result.t[-1] - result.t[0])),
                   color="C3", alpha=0.2, lw=0, label="singular passage" if k == 0 else None)
    for k, sw in enumerate(result.switches):
        ax.axvline(sw.t, color="C2", ls="--", lw=0.8,
                   label="solver switch" if k == 0 else None)
    ax.set_xlabel("time [s]")
    ax.set_ylabel("(E − E₀ − W) / E_scale")
    ax.set_title(f"Energy drift ({result.stats.get('method', '?')})")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize="small")
    if path is not None:
        fig.savefig(path, dpi=120)
    return fig


def _shade_passages(ax, result):
    for k, sp in enumerate(result.singular_passages):
        ax.axvspan(sp.t_start, max(sp.t_end, sp.t_start + 1e-9 * (result.t[-1] - result.t[0])),
                   color="C3", alpha=0.15, lw=0, label="singular passage" if k == 0 else None)


def _finish(fig, ax, title, ylabel, path, xlabel="time [s]"):
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize="small")
    if path is not None:
        fig.savefig(path, dpi=120)
    return fig


def plot_reactions(result, path=None, joints=None, ax=None):
    """The magnitude of each joint's force over time (all joints where `joints` is None),
    singular passages shaded, samples whose reactions are not unique marked."""
    fig, ax = new_axes(ax)
    table = result.reactions
    names = table.joint_names if joints is None else [getattr(j, "name", j) for j in joints]
    for name in names:
        abs_force = _magnitude(table.force(name))
        ax.plot(result.t, abs_force, lw=1.2, label=f"'{name}'")
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
        from matplotlib.figure import Figure
        fig = Figure(figsize=(7.0, 5.4), layout="constrained")
        ax, power_ax = fig.subplots(2, 1, sharex=True)
    else:
        fig, power_ax = ax.figure, None
    for k, name in enumerate(table.driver_names):
        effort = table.effort(name)
        ax.plot(result.t, effort, lw=1.2, color=f"C{k}", label=f"'{name}'")
        if power_ax is not None:
            power_ax.plot(result.t, effort * table.driver_rate(name), lw=1.2, color=f"C{k}",
                          label=f"'{name}'")
    title = f"Driver efforts ({result.problem.title if result.problem else 'result'})"
    if power_ax is not None:
        _shade_passages(power_ax, result)
        _finish(fig, power_ax, "", "power [W]", None)
    _shade_passages(ax, result)
    return _finish(fig, ax, title, "torque [N·m] or force [N]", path,
                   xlabel="time [s]" if power_ax is None else "")


def _magnitude(F):
    import numpy as np
    return np.hypot(F[:, 0], F[:, 1])
