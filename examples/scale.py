"""Scale benchmarks (docs/benchmarks.md, "scale"): cold and cached builds of window chains,
wall time per step against their length, and a 1000-sample Monte Carlo study of the
slider-crank serially and on two processes.

    python examples/scale.py builds            # a fresh process and cache per line
    python examples/scale.py steps 10 40 100 200 400
    python examples/scale.py passages 100 200    # 20 s through 20 passages, empty cache
    python examples/scale.py montecarlo --samples 1000
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time

import numpy as np

import mechsim as ms
from mechsim import examples

_BUILD = """
import sys, time
import mechsim, mechsim.run.solver, mechsim.formulations
from mechsim import examples
n = int(sys.argv[1])
t0 = time.perf_counter()
mech = examples.four_bar() if n == 0 else examples.double_four_bar(n)
problem = mech.problem()
t1 = time.perf_counter()
mech.simulate(t_end=1e-4, output_step=1e-4, method="hybrid")
t2 = time.perf_counter()
print(problem.n, t1 - t0, t2 - t1)
"""


_PASSAGES = """
import math, sys, time
t0 = time.perf_counter()
from mechsim import bench, examples
n = int(sys.argv[1])
mech = examples.double_four_bar(n)
res = mech.simulate(t_end=20.0, output_step=0.01, method="hybrid", rtol=1e-8, atol=1e-10)
wall = time.perf_counter() - t0
err = bench.Problem("chain", lambda: mech, 20.0, math.pi / 2, -1.0, n).error(res)
s = res.stats
print(f"{n:4d} windows: {wall:6.2f} s, crank-tip error {err:.2e}, {res.status}, "
      f"{s['steps']} steps, {s['bridges']} of {len(res.singular_passages)} passages bridged")
"""


def passages(windows):
    """The N-window chain for 20 s (20 singular passages), hybrid at rtol 1e-8, against the
    exact parallelogram branch; each in a new process with an empty cache, so the time
    includes imports and the cold build."""
    for n in windows:
        with tempfile.TemporaryDirectory() as cache:
            env = {**os.environ, "MECHSIM_CACHE_DIR": cache, "MECHSIM_BACKGROUND": "0"}
            env.pop("MECHSIM_BUILD", None)
            subprocess.run([sys.executable, "-c", _PASSAGES, str(n)], env=env, check=True)


def builds(windows):
    """Build and first step of each chain from an empty cache, then cached, each in a new
    process (background builds off, so "cached" is the assembled model)."""
    print(f"{'mechanism':>10} {'n':>5} {'cold build':>11} {'first step':>11} {'cold':>8} "
          f"{'cached':>8}")
    for n in windows:
        with tempfile.TemporaryDirectory() as cache:
            env = {**os.environ, "MECHSIM_CACHE_DIR": cache, "MECHSIM_BACKGROUND": "0"}
            env.pop("MECHSIM_BUILD", None)
            runs = [subprocess.run([sys.executable, "-c", _BUILD, str(n)], env=env,
                                   capture_output=True, text=True, check=True).stdout.split()
                    for _ in range(2)]
        (size, build, step), (_, build2, step2) = [[float(x) for x in r] for r in runs]
        name = "four-bar" if n == 0 else f"{n} windows"
        print(f"{name:>10} {int(size):5d} {build:10.3f}s {step:10.3f}s "
              f"{build + step:7.3f}s {build2 + step2:7.3f}s")


def steps(windows):
    """Wall time per step and per right-hand side over 0.3 s of smooth motion (hybrid,
    rtol 1e-7, assembled models)."""
    for n in windows:
        mech = examples.double_four_bar(n)
        mech.problem(build="assembled")
        mech.simulate(t_end=0.01, output_step=0.01, method="hybrid", rtol=1e-7, atol=1e-9)
        start = time.perf_counter()
        res = mech.simulate(t_end=0.3, output_step=0.1, method="hybrid", rtol=1e-7, atol=1e-9)
        wall = time.perf_counter() - start
        s = res.stats
        print(f"{n:4d} windows, n = {len(mech.coordinate_names):5d}: {wall:7.3f} s, "
              f"{1e3 * wall / s['steps']:8.2f} ms/step, "
              f"{1e3 * wall / s['rhs_evaluations']:7.3f} ms per right-hand side")


def slider_crank(crank_length, rod_length, crank_mass, rod_mass, slider_mass):
    return examples.slider_crank(crank_length=crank_length, rod_length=rod_length,
                                 crank_mass=crank_mass, rod_mass=rod_mass,
                                 slider_mass=slider_mass, driven=True, crank_speed=100.0)


def wrist_pin_peak(res):
    f = res.joint_force("B")
    return {"peak B": float(np.max(np.hypot(f[:, 0], f[:, 1])))}


def montecarlo(samples):
    """Tolerances on lengths (σ = 0.05 mm) and masses (±2 %), one revolution each, on one
    and on two processes: the same table, and the speed-up."""
    from scipy import stats
    grid = dict(crank_length=stats.norm(0.15, 5e-5), rod_length=stats.norm(0.30, 5e-5),
                crank_mass=stats.uniform(0.3528, 0.0144),
                rod_mass=stats.uniform(0.1481, 0.0060),
                slider_mass=stats.uniform(0.07404, 0.00302))
    simulate = dict(t_end=2 * np.pi / 100.0, output_step=1e-4, rtol=1e-8)
    walls, tables = [], []
    for workers in (1, 2):
        start = time.perf_counter()
        study = ms.sweep(slider_crank, grid, simulate=simulate, measure=wrist_pin_peak,
                         samples=samples, seed=1, workers=workers)
        walls.append(time.perf_counter() - start)
        x = study.table["peak B"]
        tables.append(x)
        print(f"{workers} worker(s): {walls[-1]:.2f} s, {len(study.failed)} failed; wrist pin "
              f"peak {x.mean():.3f} ± {x.std(ddof=1):.3f} N (p5 {np.percentile(x, 5):.3f}, "
              f"p95 {np.percentile(x, 95):.3f})")
    print(f"speed-up {walls[0] / walls[1]:.2f}; tables equal: "
          f"{np.array_equal(tables[0], tables[1])}")


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("what", choices=("builds", "steps", "passages", "montecarlo"))
    parser.add_argument("windows", nargs="*", type=int,
                        help="chain lengths (builds: 0 is the four-bar)")
    parser.add_argument("--samples", type=int, default=1000)
    args = parser.parse_args(argv)
    if args.what == "builds":
        builds(args.windows or [0, 10, 40, 100, 200])
    elif args.what == "steps":
        steps(args.windows or [10, 40, 100, 200, 400])
    elif args.what == "passages":
        passages(args.windows or [100, 200])
    else:
        montecarlo(args.samples)


if __name__ == "__main__":
    main()
