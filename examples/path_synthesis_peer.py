"""Path synthesis on exact gradients against pylinkage's particle swarm, same target.

The target and the design are those of `examples/path_synthesis.py`: twelve coupler
points, one every 30° of crank rotation, of a known crank-rocker; seven numbers (crank a,
coupler b, rocker c, ground d, the coupler point px, py, the crank's first angle θ0).
mechsim runs `ms.optimize` (L-BFGS-B on the kinematic sensitivities) from every number
7–8 % off; pylinkage (a benchmark-only peer: ``pip install pylinkage``, not a mechsim
dependency) runs its particle swarm over a box of ±10 % around the known design, which
holds that start, scoring each particle by the same mean squared distance computed from
its own simulation of the linkage (an unbuildable one scores infinity). Printed: the rms
error reached, the evaluations and the time of each.

    python examples/path_synthesis_peer.py
"""

from __future__ import annotations

import importlib.util
import math
import pathlib
import time

import numpy as np

spec = importlib.util.spec_from_file_location(
    "path_synthesis", pathlib.Path(__file__).with_name("path_synthesis.py"))
synthesis = importlib.util.module_from_spec(spec)
spec.loader.exec_module(synthesis)

NAMES = list(synthesis.TRUE)


def pylinkage_locus(pl, a, b, c, d, px, py, theta0):
    """The coupler point at the twelve crank angles, by pylinkage (its dyad started on the
    branch mechsim's linkage is built on)."""
    A = np.array([a * math.cos(theta0), a * math.sin(theta0)])
    AO = np.array([d, 0.0]) - A
    span = math.hypot(*AO)
    along = (b * b - c * c + span * span) / (2 * span)
    u = AO / span
    B0 = A + along * u + math.sqrt(max(b * b - along * along, 0.0)) * np.array([-u[1], u[0]])
    ground, pivot = pl.Ground(0.0, 0.0), pl.Ground(d, 0.0)
    crank = pl.Crank(anchor=ground, radius=a, angular_velocity=math.pi / 6,
                     initial_angle=theta0)
    pin = pl.RRRDyad(crank.output, pivot, distance1=b, distance2=c, x=B0[0], y=B0[1])
    point = pl.FixedDyad(crank.output, pin, distance=math.hypot(px, py),
                         angle=math.atan2(py, px))
    linkage = pl.Linkage([ground, pivot, crank, pin, point])
    steps = np.array([positions[-1] for positions in linkage.step(iterations=12)], float)
    return np.roll(steps, 1, axis=0)           # its steps end a turn later: the first last


def swarm(pl, targets, seed=0):
    """(rms error [m], evaluations, seconds) of pylinkage's particle swarm."""
    return pylinkage_swarm(pl, lambda values: pylinkage_locus(pl, *values), targets,
                           np.array(list(synthesis.TRUE.values())), seed)


def pylinkage_swarm(pl, locus, targets, known, seed=0):
    """(rms error [m], evaluations, seconds) of pylinkage's particle swarm over a box of
    ±10 % around the design `known`, each particle scored by the mean squared distance of
    `locus(values)` (pylinkage's own simulation of that design) from `targets`; an
    unbuildable linkage scores infinity."""
    from pylinkage.optimization.particle_swarm import particle_swarm_optimization
    count = [0]

    def score(_linkage, values, _coords):
        count[0] += 1
        try:
            d = locus(values) - targets
        except (ArithmeticError, ValueError, pl.UnbuildableError):
            return math.inf
        value = float(np.mean(np.sum(d * d, axis=1)))
        return value if math.isfinite(value) else math.inf

    box = (known - 0.1 * np.abs(known), known + 0.1 * np.abs(known))
    dummy = pl.Linkage([pl.Ground(0.0, 0.0)])
    np.random.seed(seed)
    began = time.perf_counter()
    best = particle_swarm_optimization(score, dummy, dimensions=len(known), bounds=box,
                                       n_particles=50, iterations=200, order_relation=min,
                                       verbose=False)
    seconds = time.perf_counter() - began
    values = np.asarray(best[0].dimensions if hasattr(best[0], "dimensions")
                        else best[0][1], float)
    d = locus(values) - targets
    return math.sqrt(float(np.mean(np.sum(d * d, axis=1)))), count[0], seconds


def main():
    targets = synthesis.targets()
    synthesis.path_four_bar(**synthesis.TRUE).kinematics(over=("motor", synthesis.ANGLES))
    print(f"{'method':>28} {'rms error [m]':>14} {'evaluations':>12} {'time [s]':>9}")
    for gradient in ("exact", "2-point"):
        design, seconds = synthesis.synthesize(gradient)
        print(f"{'mechsim L-BFGS-B, ' + gradient:>28} {math.sqrt(design.value):14.3e} "
              f"{design.evaluations:12d} {seconds:9.3f}")
    try:
        import pylinkage as pl
    except ImportError:
        print("pylinkage is not installed (pip install pylinkage): its swarm is not run")
        return
    check = pylinkage_locus(pl, *synthesis.TRUE.values()) - targets
    print(f"(pylinkage's locus of the known design against mechsim's: "
          f"{np.max(np.abs(check)):.1e} m)")
    error, evaluations, seconds = swarm(pl, targets)
    print(f"{'pylinkage particle swarm':>28} {error:14.3e} {evaluations:12d} {seconds:9.3f}")


if __name__ == "__main__":
    main()
