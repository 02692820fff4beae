"""Seed 002: periodic steady states by shooting.

Tables 1 and 2 (iterations from the paper's starting guesses, Warner and Newton), the cost
of shooting against brute-force simulation to the same steady state (the benchmark of the
shooting issue) for the Coulomb oscillator with Fig. 4's three friction coefficients, Fig. 2
(the linear oscillator's steady motion), and for the impact pair Table 3's Floquet
multipliers, Fig. 7 (relative displacement in several impact modes) and Fig. 8 (the mode
regime map over amplitude × frequency, 30 × 30, on a process pool).

    python examples/seed002_shooting.py [--out DIR]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

import mechsim as ms
from mechsim.app import bench
from mechsim.shooting.oscillators import CoulombOscillator, LinearOscillator

PAPER = bench.COULOMB                   # ζ = 0.05, ω_n = 100, δ_st = 0.1, ω = 100


def table(osc, cases, paper_nit):
    for (name, guess), nit in zip(cases, paper_nit):
        row = [f"{name:7s} guess {guess!s:18s}"]
        for method in ("warner", "newton"):
            t0 = time.perf_counter()
            s = ms.shooting.solve(osc, guess, method=method)
            row.append(f"{method}: {'ok ' if s.converged else 'no '}{s.iterations:3d} it, "
                       f"x0 = ({s.x0[0]:+.5f}, {s.x0[1]:.4f}), {time.perf_counter() - t0:.2f} s")
        print("  ".join(row) + f"   paper NIT: {nit}")


def main(out: Path):
    print("Table 1: linear oscillator (ζ = 0.05, ω_n = 100, δ_st = 0.1, ν = 1)")
    table(LinearOscillator(**PAPER), [("Case 1", (1.0, 150.0)), ("Case 2", (100.0, 900.0)),
                                      ("Case 3", (10000.0, 90000.0))], ("2", "2", "3"))
    print("Table 2: Coulomb oscillator, μ = 0.08 (true solution −.01469, 2.7201)")
    table(CoulombOscillator(**PAPER, mu=0.08), [("Case 1", (-0.014, 2.7)),
                                                 ("Case 2", (-0.07, 10.0)),
                                                 ("Case 3", (-1.1, 15.0))],
          ("3", "15", "fails within 50"))
    fig = Figure(figsize=(8, 4), layout="constrained")
    ax = fig.add_subplot()
    print("Shooting vs brute force to the same accuracy (`mechsim bench coulomb` has the "
          "full sweep):")
    print("  " + bench.SHOOTING_HEADER)
    bench.shooting_run(accuracies=(1e-6, 1e-10), repeat=10,
                       progress=lambda line: print("  " + line))
    for mu, guess in ((0.07, (0.0, 10.0)), (0.08, (-0.014, 2.7)), (0.09, (-0.01, 2.0))):
        sol = ms.shooting.solve(CoulombOscillator(**PAPER, mu=mu), guess, method="newton")
        ax.plot(sol.trajectory.t, sol.trajectory.x[:, 0], label=f"μ = {mu}")
    ax.set(xlabel="time [s]", ylabel="x [mm]", title="Fig. 4: steady states with Coulomb friction")
    ax.grid(True, alpha=0.3)
    ax.legend()
    out.mkdir(parents=True, exist_ok=True)
    fig.savefig(out / "seed002_fig4.png", dpi=120)


def impact_figures(out: Path):
    pair = ms.oscillators.ImpactPair(m1=0.2799, m2=0.000545, clearance=0.028, amplitude=0.189,
                                     omega=50.0, restitution=0.7)
    sol = ms.shooting.solve(pair, [0.14716, 5.9275, 9.4294, -0.68051], method="newton")
    print(f"Table 3 point: mode {sol.mode}, Floquet multipliers "
          f"{np.round(sol.significant_multipliers.real, 4)} besides the neutral pair at 1 "
          f"-> {'stable' if sol.stable else 'unstable'}")
    seed = sol.x0
    A, W = np.linspace(0.10, 0.30, 30), np.linspace(35.0, 65.0, 30)
    rm = ms.shooting.regime_map(A, W, seed, 0.189, 50.0)
    found = rm.modes[:, :, 0] >= 0
    print(f"Fig. 8 regime map 30 x 30 in {rm.wall_time:.1f} s: periodic states at {found.sum()} "
          f"of {found.size} points, {rm.stable.sum()} of them stable; elsewhere the motion "
          f"is irregular at {(rm.periods == 0).sum()} and repeats after k > 1 periods at "
          f"{(rm.periods > 1).sum()}")
    rm.plot(out / "seed002_fig8_regime_map.png")
    # Fig. 7: one period of x1 − x2 in the modes the map found along the column nearest
    # ω = 50 rad/s.
    fig = Figure(figsize=(8, 4.5), layout="constrained")
    ax = fig.add_subplot()
    j = int(np.argmin(np.abs(W - 50.0)))
    shown = set()
    for i in range(len(A)):
        mode = tuple(int(k) for k in rm.modes[i, j])
        if mode[0] < 0 or mode in shown:
            continue
        shown.add(mode)
        p = ms.oscillators.ImpactPair(m1=0.2799, m2=0.000545, clearance=0.028, amplitude=A[i],
                                      omega=W[j], restitution=0.7)
        tr = p.flow(rm.x0[i, j])
        ax.plot(tr.t / p.period, tr.x[:, 0] - tr.x[:, 2], label=f"{mode}, A = {A[i]:.3f} in")
    ax.axhline(0.028, color="k", lw=0.8)
    ax.axhline(-0.028, color="k", lw=0.8)
    ax.set(xlabel="t / T", ylabel="x1 − x2 [in]",
           title=f"Fig. 7: relative displacement in the impact modes (n, m), e = 0.7, "
                 f"ω = {W[j]:.2f} rad/s")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize="small")
    fig.savefig(out / "seed002_fig7.png", dpi=120)


def figure_2(out: Path):
    osc = LinearOscillator(**PAPER)
    sol = ms.shooting.solve(osc, (1.0, 150.0), method="warner")
    fig = Figure(figsize=(7, 3.5), layout="constrained")
    ax = fig.add_subplot()
    ax.plot(sol.trajectory.t, sol.trajectory.x[:, 0])
    ax.set(xlabel="time [s]", ylabel="x [mm]",
           title="Fig. 2: steady state, ζ = 0.05, ω_n = 100 rad/s, δ_st = 0.1 mm")
    ax.grid(True, alpha=0.3)
    fig.savefig(out / "seed002_fig2.png", dpi=120)


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="out/examples", type=Path)
    out = ap.parse_args().out
    main(out)
    figure_2(out)
    impact_figures(out)
