"""The README's five-minute tour: every picture it shows, made by the code it shows.

    python examples/tour.py [--out docs/images]

1. a driven slider-crank and the torque its motor must deliver;
2. a four-bar's coupler curve, and the singular configurations it passes;
3. an elastic coupler (the seed's flexible four-bar) bending as it falls;
4. the periodic steady state of a damped pendulum under a periodic torque, found by
   shooting, against a long simulation settling onto it.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

import mechsim as ms


def motor_torque(out: Path):
    mech = ms.examples.slider_crank(driven=True, crank_speed=100.0)
    res = mech.simulate(2 * math.pi / 100, rtol=1e-9, output_step=1e-4)
    res.plot_efforts(out / "tour_motor_torque.png")
    print(res.cycle_figures())


def coupler_curve(out: Path):
    mech = ms.examples.four_bar()
    res = mech.simulate(2.0, rtol=1e-8, output_step=1e-3)
    fig = Figure(figsize=(11.0, 4.2), layout="constrained")
    left, right = fig.subplots(1, 2, width_ratios=(1.0, 1.3))
    res.plot_motion(trace=[("coupler", (0.25, 0.0))], snapshots=5, ax=left)
    res.plot_energy(ax=right)
    fig.savefig(out / "tour_coupler_curve.png", dpi=110)
    print([round(p.t_min, 4) for p in res.singular_passages])


def flexible(out: Path):
    mech = ms.examples.flexible_four_bar()
    res = mech.simulate(0.6, rtol=1e-6, max_step=5e-4, integrator="adams", output_step=2e-3)
    fig = Figure(figsize=(11.0, 4.2), layout="constrained")
    left, right = fig.subplots(1, 2)
    res.plot_motion(snapshots=4, exaggeration=50.0, ax=left)
    left.set_title("flexible four-bar (deflection × 50)")
    right.plot(res.t, res.coordinate("coupler.eta1"), label="η₁")
    right.plot(res.t, res.coordinate("coupler.eta2"), label="η₂")
    right.set_xlabel("time [s]")
    right.set_ylabel("modal amplitude [√kg·m]")
    right.grid(True, alpha=0.3)
    right.legend()
    fig.savefig(out / "tour_flexible.png", dpi=110)


def steady_state(out: Path):
    w = 4.0
    mech = ms.examples.shaken_pendulum(omega=w)
    period = 2 * math.pi / w
    sol = mech.steady_state(period)
    orbit = sol.trajectory.result
    brute = mech.simulate(12 * period, rtol=1e-9, output_step=period / 100)
    fig = Figure(figsize=(7.0, 3.6), layout="constrained")
    ax = fig.add_subplot()
    ax.plot(brute.t / period, brute.coordinate("rod.angle"), lw=1, label="simulated from rest")
    for k in range(12):
        ax.plot(k + orbit.t / period, orbit.coordinate("rod.angle"), "k--", lw=0.8,
                label="steady state by shooting" if k == 0 else None)
    ax.set_xlabel("periods of the torque")
    ax.set_ylabel("rod angle [rad]")
    ax.set_title(f"Periodic steady state: {sol.iterations} Newton iterations, "
                 f"Floquet multipliers |μ| ≤ {np.max(np.abs(sol.floquet_multipliers)):.2f}")
    ax.grid(True, alpha=0.3)
    ax.legend()
    fig.savefig(out / "tour_steady_state.png", dpi=110)


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="docs/images", type=Path)
    out = parser.parse_args().out
    out.mkdir(parents=True, exist_ok=True)
    for make in (motor_torque, coupler_curve, flexible, steady_state):
        make(out)
    print(f"wrote the tour's pictures to {out}")
