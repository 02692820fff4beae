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


def path_four_bar(a, b, c, d, px, py, theta0):
    """The linkage with ground pivots (0, 0) and (d, 0), assembled on the branch with the
    coupler–rocker pin above the line from the crank pin to (d, 0); the coupler body's
    frame is its tracing point (its mass does not enter a kinematic analysis). Each
    argument a number or a Parameter (numpy's functions carry them)."""
    mech = ms.Mechanism("path generator")
    ground = mech.ground
    A = np.array([a * np.cos(theta0), a * np.sin(theta0)])
    O4 = np.array([d, 0.0])
    AO = O4 - A
    span = np.hypot(AO[0], AO[1])
    along = (b * b - c * c + span * span) / (2 * span)
    u = AO / span
    B = A + along * u + np.sqrt(b * b - along * along) * np.array([-u[1], u[0]])
    th3 = np.arctan2(B[1] - A[1], B[0] - A[0])
    P = A + px * np.array([np.cos(th3), np.sin(th3)]) + py * np.array([-np.sin(th3),
                                                                      np.cos(th3)])
    crank = mech.add(ms.RigidBody.rod("crank", (0.0, 0.0), A, mass=1.0))
    coupler = mech.add(ms.RigidBody("coupler", mass=1.0, inertia=0.01, position=P,
                                    angle=th3))
    rocker = mech.add(ms.RigidBody.rod("rocker", O4, B, mass=1.0))
    pin = mech.add(ms.Revolute(ground, crank, at=(0.0, 0.0)))
    mech.add(ms.Revolute(crank, coupler, at=A))
    mech.add(ms.Revolute(coupler, rocker, at=B))
    mech.add(ms.Revolute(rocker, ground, at=O4))
    mech.add(ms.Driver(pin, "t", name="motor"))
    return mech


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
