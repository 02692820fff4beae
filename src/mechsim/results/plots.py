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
