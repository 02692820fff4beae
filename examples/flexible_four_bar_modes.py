"""Modes of the seed's flexible four-bar at rest.

The parallelogram four-bar with an elastic copper coupler (1 m, 1 cm square, 10 elements,
2 pinned–pinned modes) comes to rest hanging under gravity. Linearized about that
equilibrium (in its independent coordinates, the constraints' second-order terms included)
it has one swinging mode and the coupler's bending modes. Held at 40° by a torsion spring
on its crank instead, the first bending mode couples with the links' motion; it approaches
the free beam's pinned–pinned frequency as the crank is made heavy.

    python examples/flexible_four_bar_modes.py [--out DIR]
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

import mechsim as ms


def main(out_dir: Path):
    mech = ms.examples.flexible_four_bar()
    eq = mech.equilibrium()
    print(f"equilibrium: {eq.message} ({eq.method}); crank at "
          f"{math.degrees(eq.q[2]):.2f}°")
    lin = mech.linearize(eq.q)
    beam = mech.body("coupler").frequencies
    print("modes about it (rad/s):", ", ".join(f"{w:.4f}" for w in lin.frequencies))
    print("the free beam, pinned–pinned:", ", ".join(f"{w:.4f}" for w in beam))
    print("held at 40° by a torsion spring, the crank of mass m:")
    print(f"{'m [kg]':>10s} {'swing':>9s} {'1st bending':>12s} {'shift':>10s}")
    for mass in (1.0, 10.0, 100.0, 1000.0, 10000.0):
        held = ms.examples.flexible_four_bar(crank_mass=mass, tilt=math.radians(40.0))
        held.add(ms.RotationalSpring(held.ground, held.body("crank"), 20 * (mass + 1) * 9.81))
        lh = held.linearize()
        print(f"{mass:10g} {lh.frequencies[0]:9.4f} {lh.frequencies[1]:12.4f} "
              f"{lh.frequencies[1] / beam[0] - 1:10.2e}")

    # The first bending mode's shape along the coupler, from its modal amplitudes.
    out_dir.mkdir(parents=True, exist_ok=True)
    names = mech.coordinate_names
    k = int(np.argmin(np.abs(lin.frequencies - beam[0])))
    eta = lin.modes[k, [names.index("coupler.eta1"), names.index("coupler.eta2")]]
    coupler = mech.body("coupler")
    xi = np.linspace(0.0, coupler.length, 101)
    shape = np.array([coupler.point_modes((x, 0.0))[1] @ eta for x in xi])
    fig = Figure(figsize=(6.5, 3.2), layout="constrained")
    ax = fig.add_subplot()
    ax.plot(xi, shape / np.max(np.abs(shape)))
    ax.set_xlabel("along the coupler [m]")
    ax.set_ylabel("transverse deflection (normalized)")
    ax.set_title(f"Flexible four-bar at rest: mode at {lin.frequencies[k]:.2f} rad/s")
    ax.grid(True, alpha=0.3)
    fig.savefig(out_dir / "flexible_four_bar_mode.png", dpi=120)
    print(f"wrote {out_dir / 'flexible_four_bar_mode.png'}")


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="out/examples", type=Path)
    main(parser.parse_args().out)
