"""Seed 000: the state-space Newmark method.

Reproduces Fig. 2 (spectral radius), Figs. 4 and 5 (period and amplitude error over Δt/T for
ζ = 0, 0.01, 0.05, 0.1, 0.5), Figs. 7 and 8 (2-DOF responses by ss-Newmark, RK4 and the exact
solution at Δt = 0.05 s), Fig. 10 (turbo-compressor rotor at 30,000 rpm, horizontal response
at station 1, Δt = 1e-4 s over 0.02 s) and Table 1 (ss-Newmark vs classical Newmark cost, as
a ratio measured here; the paper: 0.0310 / 0.0320 s in Matlab 6.5), and a work–precision
table (error against the exact solution vs wall time) for ss-Newmark, Newmark and RK4 on both
examples.

    python examples/seed000_newmark.py [--out DIR]
"""

from __future__ import annotations

import argparse
import math
import timeit
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

import mechsim as ms
from mechsim import analysis

ZETAS = (0.0, 0.01, 0.05, 0.1, 0.5)


def two_dof():
    m1, m2, k1, k2, z1, z2 = 2000.0, 50.0, 1e3, 1e4, 0.01, 0.2
    c1, c2 = 2 * z1 * math.sqrt(k1 * m1), 2 * z2 * math.sqrt(k2 * m2)
    return ms.LinearSystem(np.diag([m1, m2]), [[c1 + c2, -c2], [-c2, c2]],
                           [[k1 + k2, -k2], [-k2, k2]],
                           force=lambda t: np.array([0.0, 10.0 * np.cos(3.0 * t)]))


def figures_2_4_5(out):
    ratios = np.logspace(-3, 2, 200)
    fig = Figure(figsize=(12, 3.8), layout="constrained")
    ax = fig.subplots(1, 3)
    for z in ZETAS:
        T = 2 * math.pi / math.sqrt(1 - z**2) if z < 1 else 2 * math.pi
        rho = [analysis.spectral_radius("ss-newmark", 1.0, z, r * T) for r in ratios]
        ax[0].semilogx(ratios, rho, label=f"ζ = {z}")
        small = ratios[ratios <= 0.5]
        ep = [analysis.period_error("ss-newmark", 1.0, z, r * T) for r in small]
        ax[1].loglog(small, np.abs(ep), label=f"ζ = {z}")
        if z > 0:   # undamped: |λ| = 1 exactly, no amplitude error to plot
            ea = [abs(analysis.amplitude_error("ss-newmark", 1.0, z, r * T, max(1, round(1 / r))))
                  for r in small]
            ax[2].loglog(small, ea, label=f"ζ = {z}")
    ax[0].set(xlabel="Δt/T", ylabel="spectral radius of A_m", title="Fig. 2: stability")
    ax[1].set(xlabel="Δt/T", ylabel="|period error| [%]", title="Fig. 4: period error")
    ax[2].set(xlabel="Δt/T", ylabel="|amplitude error| after one period",
              title="Fig. 5: amplitude error")
    for a in ax:
        a.grid(True, which="both", alpha=0.3)
        a.legend(fontsize="small")
    fig.savefig(out / "seed000_figs2-4-5.png", dpi=120)


def figures_7_8_table_1(out):
    sys2 = two_dof()
    runs = {m: sys2.simulate(30.0, 0.05, m) for m in ("ss-newmark", "rk4", "exact")}
    fig = Figure(figsize=(8, 6), layout="constrained")
    ax = fig.subplots(2, 1, sharex=True)
    for k, (m, r) in enumerate(runs.items()):
        ls = ":" if m == "exact" else "-"
        ax[0].plot(r.t, r.x[:, 0], ls, color=f"C{k}", label=m)
        ax[1].plot(r.t, r.x[:, 1], ls, color=f"C{k}", label=m)
    ax[0].set(ylabel="x₁ [m]", title="Fig. 7: m₁ (Δt = 0.05 s)")
    ax[1].set(ylabel="x₂ [m]", xlabel="time [s]", title="Fig. 8: m₂")
    for a in ax:
        a.grid(True, alpha=0.3)
        a.legend(fontsize="small")
    fig.savefig(out / "seed000_figs7-8.png", dpi=120)
    ex = runs["exact"]
    for m in ("ss-newmark", "rk4"):
        print(f"2-DOF, Δt = 0.05 s: max |x − exact| {m:10s} = "
              f"{np.abs(runs[m].x - ex.x).max():.3e} m")
    nm = sys2.simulate(30.0, 0.05, "newmark")
    print(f"ss-Newmark vs classical Newmark: max |Δx| = {np.abs(runs['ss-newmark'].x - nm.x).max():.1e} m")
    t_ss = min(timeit.repeat(lambda: sys2.simulate(30.0, 0.05, "ss-newmark"), number=1, repeat=7))
    t_nm = min(timeit.repeat(lambda: sys2.simulate(30.0, 0.05, "newmark"), number=1, repeat=7))
    print(f"Table 1: ss-Newmark {t_ss * 1e3:.2f} ms, Newmark {t_nm * 1e3:.2f} ms, ratio "
          f"{t_ss / t_nm:.2f} (paper 0.0310/0.0320 = 0.97)")


def figure_10(out):
    rotor = ms.rotor.turbo_compressor()
    speed = 30000 * 2 * math.pi / 60
    system = rotor.linear_system(speed)
    i = rotor.dof(1, "ux")
    fig = Figure(figsize=(8, 3.8), layout="constrained")
    ax = fig.add_subplot()
    for k, m in enumerate(("ss-newmark", "exact")):
        r = system.simulate(0.02, 1e-4, m)
        ax.plot(r.t, r.x[:, i] * 1e6, ":" if m == "exact" else "-", color=f"C{k}", label=m)
    X = rotor.steady_unbalance_response(speed)
    ax.axhline(abs(X[i]) * 1e6, color="k", lw=0.8, ls="--", label="steady orbit amplitude")
    ax.axhline(-abs(X[i]) * 1e6, color="k", lw=0.8, ls="--")
    ax.set(xlabel="time [s]", ylabel="x at station 1 [µm]",
           title="Fig. 10: turbo-compressor, 30,000 rpm, Δt = 1e-4 s")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize="small")
    fig.savefig(out / "seed000_fig10.png", dpi=120)
    t_ss = min(timeit.repeat(lambda: system.simulate(0.02, 1e-4, "ss-newmark"), number=1, repeat=7))
    t_nm = min(timeit.repeat(lambda: system.simulate(0.02, 1e-4, "newmark"), number=1, repeat=7))
    print(f"rotor 0.02 s: ss-Newmark {t_ss * 1e3:.2f} ms, Newmark {t_nm * 1e3:.2f} ms, "
          f"ratio {t_ss / t_nm:.2f}; first natural frequencies at rest "
          f"{np.round(rotor.natural_frequencies(0.0, 4) / (2 * math.pi), 1)} Hz, at 30,000 rpm "
          f"{np.round(rotor.natural_frequencies(speed, 4) / (2 * math.pi), 1)} Hz")


def work_precision(out):
    """Error against the exact solution vs wall time for ss-Newmark, Newmark and RK4 over a
    sweep of steps, on the 2-DOF system (30 s) and the rotor (0.02 s, station 1 ux)."""
    speed = 30000 * 2 * math.pi / 60
    rotor = ms.rotor.turbo_compressor()
    cases = {"2-DOF": (two_dof(), 30.0, (0.2, 0.1, 0.05, 0.025, 0.0125), None),
             "rotor": (rotor.linear_system(speed), 0.02, (4e-4, 2e-4, 1e-4, 5e-5, 2.5e-5),
                       rotor.dof(1, "ux"))}
    fig = Figure(figsize=(11, 4.2), layout="constrained")
    axes = fig.subplots(1, 2)
    print(f"{'case':6s} {'method':10s} {'h':>9s} {'wall [ms]':>10s} {'max error':>10s}")
    for ax, (name, (system, t_end, steps, dof)) in zip(axes, cases.items()):
        for k, m in enumerate(("ss-newmark", "newmark", "rk4")):
            pts = []
            for h in steps:
                ex = system.simulate(t_end, h, "exact")
                sel = slice(None) if dof is None else dof
                with np.errstate(all="ignore"):          # RK4 diverges on the stiff rotor
                    r = system.simulate(t_end, h, m)
                    err = float(np.max(np.abs(r.x[:, sel] - ex.x[:, sel])))
                    wall = min(timeit.repeat(lambda: system.simulate(t_end, h, m), number=1,
                                             repeat=3))
                stable = np.isfinite(err) and err < 10 * np.max(np.abs(ex.x[:, sel]))
                print(f"{name:6s} {m:10s} {h:9.2e} {wall * 1e3:10.2f} "
                      f"{err if stable else float('nan'):10.2e}{'' if stable else '  unstable'}")
                if stable:
                    pts.append((wall, err))
            if pts:
                x, y = zip(*pts)
                ax.loglog(x, y, "o-", color=f"C{k}", label=m)
        ax.set(xlabel="wall time [s]", ylabel="max |x − exact| [m]",
               title=f"{name}: work–precision")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize="small")
    fig.savefig(out / "seed000_work_precision.png", dpi=120)


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="out/examples", type=Path)
    out = ap.parse_args().out
    out.mkdir(parents=True, exist_ok=True)
    figures_2_4_5(out)
    figures_7_8_table_1(out)
    figure_10(out)
    work_precision(out)
    print(f"figures written to {out}/")
