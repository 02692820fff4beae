"""Alt's nine-point path synthesis, on exact Jacobians, against finite differences and
pylinkage's particle swarm.

Nine points fix a four-bar's coupler curve: Alt posed the problem in 1923, and Wampler,
Morgan and Sommese ("Complete solution of the nine-point path synthesis problem for
four-bar linkages") found all its solutions by homotopy continuation, 1442 up to
relabelling and Roberts' cognates, for their test cases. This is their case of points on
two circles (three on one, four on another). The problem is square: a linkage passes
through all nine points exactly, so the published optimum's error is zero. Among the
solutions is a crank-rocker that meets the points in order within one turn of its crank
(`KNOWN`, `ADVANCES`; the test suite checks that mechsim's analysis of it passes through
every point to round-off).

The design is eighteen numbers: the linkage's ten (crank a, coupler b, rocker c, ground d,
the coupler point px, py, the crank's first angle θ0, the crank's pivot x0, y0 and the
ground line's direction `tilt`: `mechsim.examples.coupler_four_bar`) and the crank's eight
advances between the points (no prescribed timing: `PathPoints(free_timing=True)`). Each
search starts from every number 5 % off that linkage, alternately low and high:

- mechsim: `ms.optimize(method="least_squares")`, scipy's trust-region least squares on
  the points' errors and their exact Jacobian (kinematic sensitivities, and the point's
  velocity over the crank's rate for the advances);
- the same search with scipy's finite-difference Jacobian (``gradient="2-point"``);
- mechsim's L-BFGS-B on the exact gradient of the mean squared error (the default
  `optimize`);
- `ms.multistart` of the least-squares search from 16 designs over ±30 % of that
  linkage, the advances equal: the global search without a near start;
- pylinkage's particle swarm (a benchmark-only peer: ``pip install pylinkage``, not a
  mechsim dependency) over a box ±10 % around the known design, which holds the start,
  each particle scored by the same mean squared distance from pylinkage's own simulation
  of the linkage (an unbuildable one scores infinity).

Printed: the rms error reached [m], the evaluations and the time of each.

    python examples/nine_point_synthesis.py
"""

from __future__ import annotations

import importlib.util
import math
import pathlib
import time

import numpy as np

import mechsim as ms

POINTS = np.array([(0.25, 0.00), (0.52, 0.10), (0.80, 0.70), (1.20, 1.00), (1.40, 1.30),
                   (1.10, 1.48), (0.70, 1.40), (0.20, 1.00), (0.02, 0.40)])
# The crank-rocker through the nine points, in order (coupler–rocker pin right of the line
# from the crank pin to the rocker's pivot: branch −1), and the crank's advances between
# the points [rad] (5.47 rad in all: within one turn).
KNOWN = dict(a=0.6120956019364877, b=0.8369062564334891, c=0.7237468412883614,
             d=0.8109133477771588, px=0.4001916177372108, py=-0.5971369429343735,
             theta0=4.070381614349303, x0=1.2166973529514573, y0=0.8858501133219254,
             tilt=-1.4167414658624562)
ADVANCES = np.array([0.6433523891891451, 0.2995427212686055, 0.2677868681648974,
                     0.6994134180604332, 0.8044450773637797, 0.7375328287141238,
                     1.026833619591832, 0.9964965169880617])
BRANCH = -1
OFF = 0.05


def linkage(a, b, c, d, px, py, theta0, x0, y0, tilt):
    """The path four-bar of these numbers (numbers or Parameters)."""
    return ms.examples.coupler_four_bar(a, b, c, d, px, py, theta0, branch=BRANCH,
                                        origin=(x0, y0), tilt=tilt)


def start():
    """(the linkage's numbers, the advances), every one `OFF` low or high in turn."""
    sign = np.resize([-1.0, 1.0], len(KNOWN) + len(ADVANCES))
    shifted = (1.0 + OFF * sign) * np.concatenate([list(KNOWN.values()), ADVANCES])
    return dict(zip(KNOWN, shifted[:len(KNOWN)].tolist())), shifted[len(KNOWN):]


def synthesize(gradient="exact", method="least_squares", tol=1e-15):
    """(the Design `ms.optimize` finds, wall time [s]) from `start()`."""
    numbers, advances = start()
    parameters = {k: ms.Parameter(k, v) for k, v in numbers.items()}
    mech = linkage(**parameters)
    objective = ms.PathPoints("coupler", (0.0, 0.0), POINTS, "motor",
                              np.concatenate([[0.0], np.cumsum(advances)]), free_timing=True)
    began = time.perf_counter()
    design = ms.optimize(mech, objective, list(parameters), gradient=gradient,
                         method=method, tol=tol)
    return design, time.perf_counter() - began


def pylinkage_locus(pl, a, b, c, d, px, py, theta0, x0, y0, tilt, *advances):
    """The coupler point at the nine crank angles, by pylinkage (its dyad started on the
    branch of the mechsim linkage, its crank stepped by each advance)."""
    O2 = np.array([x0, y0])
    O4 = O2 + d * np.array([math.cos(tilt), math.sin(tilt)])
    A = O2 + a * np.array([math.cos(theta0), math.sin(theta0)])
    AO = O4 - A
    span = math.hypot(*AO)
    along = (b * b - c * c + span * span) / (2 * span)
    u = AO / span
    B0 = A + along * u + BRANCH * math.sqrt(max(b * b - along * along, 0.0)) * \
        np.array([-u[1], u[0]])
    ground, pivot = pl.Ground(x0, y0), pl.Ground(O4[0], O4[1])
    crank = pl.Crank(anchor=ground, radius=a, angular_velocity=1.0, initial_angle=theta0)
    pin = pl.RRRDyad(crank.output, pivot, distance1=b, distance2=c, x=B0[0], y=B0[1])
    point = pl.FixedDyad(crank.output, pin, distance=math.hypot(px, py),
                         angle=math.atan2(py, px))
    mech = pl.Linkage([ground, pivot, crank, pin, point])
    points = []
    for step in (0.0, *advances):
        points.append(list(mech.step(iterations=1, dt=step))[-1][-1])
    return np.array(points, float)


def swarm(pl, seed=0):
    """(rms error [m], evaluations, seconds) of pylinkage's particle swarm
    (`examples/path_synthesis_peer.py`) on the nine points."""
    spec = importlib.util.spec_from_file_location(
        "path_synthesis_peer", pathlib.Path(__file__).with_name("path_synthesis_peer.py"))
    peer = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(peer)
    known = np.concatenate([list(KNOWN.values()), ADVANCES])
    return peer.pylinkage_swarm(pl, lambda values: pylinkage_locus(pl, *values), POINTS,
                                known, seed)


def global_search(starts=16, seed=1, workers=2):
    """(the `ms.multistart` result, seconds): least-squares searches from `starts` designs
    spread over ±30 % of the known linkage's numbers (a Latin hypercube), the advances
    all equal (5.6 rad over the turn), none of it near the answer."""
    bounds = {k: tuple(sorted((0.7 * v, 1.3 * v))) for k, v in KNOWN.items()}
    even = np.concatenate([[0.0], np.cumsum(np.full(len(ADVANCES), 5.6 / len(ADVANCES)))])
    objective = ms.PathPoints("coupler", (0.0, 0.0), POINTS, "motor", even,
                              free_timing=True)
    began = time.perf_counter()
    found = ms.multistart(linkage, objective, bounds, starts=starts, seed=seed,
                          workers=workers, method="least_squares", tol=1e-15)
    return found, time.perf_counter() - began


def main():
    linkage(**KNOWN).kinematics(over=("motor", [0.0, 0.1]))   # builds and caches the model
    print(f"{'search':>34} {'rms error [m]':>14} {'evaluations':>12} {'time [s]':>9}")
    for label, gradient, method in (("least squares, exact Jacobian", "exact",
                                      "least_squares"),
                                     ("least squares, 2-point Jacobian", "2-point",
                                      "least_squares"),
                                     ("L-BFGS-B, exact gradient", "exact", None)):
        design, seconds = synthesize(gradient, method)
        print(f"{label:>34} {math.sqrt(design.value):14.3e} {design.evaluations:12d} "
              f"{seconds:9.2f}")
    found, seconds = global_search()
    errors = np.sqrt(np.asarray(found.study.table["value"], float))
    exact = int(np.sum(errors < 1e-12))
    print(f"multistart, 16 starts over ±30 %, equal advances: {exact} end on an exact "
          f"linkage ({np.nanmin(errors):.1e} m), {int(np.sum(np.isnan(errors)))} do not "
          f"assemble at their start; {seconds:.2f} s on 2 processes")
    try:
        import pylinkage as pl
    except ImportError:
        print("pylinkage is not installed (pip install pylinkage): its swarm is skipped")
        return
    check = pylinkage_locus(pl, *KNOWN.values(), *ADVANCES) - POINTS
    print(f"pylinkage's locus of the known linkage: {np.abs(check).max():.1e} m off the points")
    for seed in range(3):
        rms, count, seconds = swarm(pl, seed)
        print(f"{f'pylinkage swarm, seed {seed}':>34} {rms:14.3e} {count:12d} {seconds:9.2f}")


if __name__ == "__main__":
    main()
