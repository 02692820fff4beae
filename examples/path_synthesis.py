"""Four-bar path synthesis with prescribed timing, on exact gradients.

A crank-rocker's coupler point should pass through twelve points, one every 30° of crank
rotation. The design is seven numbers: crank a, coupler b, rocker c, ground d, the
coupler point's place on the coupler (px along it, py across), and the crank's angle at
the first point θ0. The points are those of a known linkage, so the best design traces
them exactly; the search starts from every number 7–8 % off.

`ms.optimize` sets each trial design on the same mechanism (no new build), runs its
kinematic analysis with the exact sensitivities of the coupler point, and hands value and
gradient to scipy's L-BFGS-B; the same optimizer with scipy's finite differences
(``gradient="2-point"``) is run for comparison.

    python examples/path_synthesis.py
"""

from __future__ import annotations

import time

import numpy as np

import mechsim as ms

TRUE = dict(a=0.10, b=0.30, c=0.25, d=0.30, px=0.10, py=0.05, theta0=0.40)
ANGLES = np.radians(np.arange(0.0, 331.0, 30.0))       # crank turned from the first point


# The linkage (`mechsim.examples.coupler_four_bar`): ground pivots (0, 0) and (d, 0), the
# coupler body's frame at its tracing point.
path_four_bar = ms.examples.coupler_four_bar


def targets():
    """The coupler points of the known linkage at ANGLES."""
    known = path_four_bar(**TRUE)
    return known.kinematics(over=("motor", ANGLES)).point(known.body("coupler"), (0.0, 0.0))


def start():
    """Every number of the known design 7 % low or 8 % high, in turn."""
    return {k: v * (1.08 if i % 2 else 0.93) for i, (k, v) in enumerate(TRUE.items())}


def synthesize(gradient="exact", tol=1e-14):
    """(the Design `ms.optimize` finds, wall time [s]) from `start()`."""
    parameters = {k: ms.Parameter(k, v) for k, v in start().items()}
    mech = path_four_bar(**parameters)
    objective = ms.PathPoints("coupler", (0.0, 0.0), targets(), "motor", ANGLES)
    began = time.perf_counter()
    design = ms.optimize(mech, objective, list(parameters), gradient=gradient, tol=tol)
    return design, time.perf_counter() - began


def main():
    path_four_bar(**TRUE).kinematics(over=("motor", ANGLES))     # builds and caches the model
    print(f"{'gradient':>9} {'rms error [m]':>14} {'evaluations':>12} {'time [s]':>9}")
    for gradient in ("exact", "2-point"):
        design, seconds = synthesize(gradient)
        print(f"{gradient:>9} {np.sqrt(design.value):14.3e} {design.evaluations:12d} "
              f"{seconds:9.3f}")
    worst = max(abs(design.parameters[k] / v - 1.0) for k, v in TRUE.items())
    print(f"largest relative deviation from the known design: {worst:.2e}")


if __name__ == "__main__":
    main()
