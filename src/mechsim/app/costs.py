"""What the solvers spend where their work is the point: `mechsim bench costs`.

The tests check what a run computes (motions against exact ones, passages, balances); how
many steps, right-hand sides or bridge evaluations it takes depends on the CPU's round-off
(one step placed a little differently changes every count after it) and belongs here, with
the figures in docs/benchmarks.md. Each case runs one scenario and reports its counts; the
tests assert none of them (a run that grinds shows here, and in its stop rules' messages).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .. import examples


@dataclass(frozen=True)
class CostRow:
    """One count of one case: `case` names the scenario, `figure` the count."""
    case: str
    figure: str
    value: float


def _row_set(case, res, **extra):
    figures = {"status": res.status, "steps": res.stats["steps"],
               "rhs evaluations": res.stats["rhs_evaluations"],
               "bridges": res.stats.get("bridges", 0),
               "bridge evaluations": res.stats.get("bridge_evaluations", 0),
               "bridges over tolerance": res.stats.get("bridges_over_tolerance", 0),
               "wall time [s]": res.stats["wall_time"], **extra}
    return [CostRow(case, k, v) for k, v in figures.items()]


def noisy_bridge():
    """The seed's falling four-bar, projection at rtol 1e-9 with its 0.01 s step bound: at
    its third passage the bridge's error estimate is the round-off of q̈, and the best
    declined bridge is taken. On the Python and on the compiled evaluations."""
    from ..codegen import engine
    mech = examples.four_bar()
    run = dict(t_end=2.0, method="projection", rtol=1e-9, atol=1e-11, max_step=0.01,
               output_step=0.002)
    model = mech.simulate(t_end=1e-3).problem.model
    with engine.python_path(model):
        python = mech.simulate(**run)
    compiled = mech.simulate(**run)
    return (_row_set("four-bar, projection 1e-9, Python path", python) +
            _row_set("four-bar, projection 1e-9, compiled", compiled))


def ten_window():
    """The ten-window chain for 3 s (three passages): projection bridged and stepped
    through, and the hybrid."""
    mech = examples.double_four_bar(10)
    kw = dict(t_end=3.0, rtol=1e-7, atol=1e-9, output_step=0.01)
    return (_row_set("10-window, projection", mech.simulate(method="projection", **kw)) +
            _row_set("10-window, projection without bridges",
                     mech.simulate(method="projection", bridge_passages=False, **kw)) +
            _row_set("10-window, hybrid", mech.simulate(method="hybrid", **kw)))


def adams_hybrid():
    """The hybrid with the paper's Adams integrator: the seed's parallelogram for 2 s (warm
    restarts after switches and bridges) and the double four-bar for 1.6 s (no creeping up
    to a passage: the shortest step past the start-up)."""
    rows = _row_set("four-bar, hybrid/adams", examples.four_bar().simulate(
        t_end=2.0, method="hybrid", integrator="adams", rtol=1e-8, atol=1e-10,
        max_step=0.01, output_step=0.002))
    res = examples.double_four_bar(2).simulate(t_end=1.6, method="hybrid", rtol=1e-8,
                                               atol=1e-10, integrator="adams")
    h = np.diff(res.t)[res.t[1:] > 0.3]
    return rows + _row_set("double four-bar 1.6 s, hybrid/adams", res,
                           **{"shortest step past 0.3 s": float(h.min())})


def stuck_lu():
    """LU alone at the flexible four-bar's first passage: its steps collapse and the run
    stops as stuck."""
    res = examples.flexible_four_bar().simulate(t_end=1.2, method="lu", rtol=1e-6,
                                                atol=1e-8, max_step=5e-4,
                                                integrator="adams")
    return _row_set("flexible four-bar, lu/adams (stuck)", res,
                    **{"stopped at [s]": float(res.t[-1])})


def scipy_integrators():
    """The double four-bar's first two passages at rtol 1e-4 (a local tolerance of 1e-6)
    with each of scipy's integrators under the projection and hybrid methods."""
    rows = []
    mech = examples.double_four_bar(2)
    for method in ("projection", "hybrid"):
        for integrator in ("BDF", "LSODA", "Radau", "RK23"):
            res = mech.simulate(t_end=2.0, method=method, rtol=1e-4, atol=1e-6,
                                output_step=0.01, integrator=integrator, max_steps=1200)
            rows += _row_set(f"double four-bar 2 s, {method}/{integrator}", res)
    return rows


def seed_svd():
    """The seed's projection method (an SVD of J̃ at every evaluation) against mechsim's
    (SVDs near the passages only), on the seed's four-bar: SVDs per run."""
    from ..linalg import dense
    calls = []
    svd = dense.svd

    def counted(A):
        calls.append(A.shape)
        return svd(A)

    mech = examples.four_bar()
    kw = dict(t_end=2.0, method="projection", rtol=1e-8, atol=1e-10, max_step=0.01,
              output_step=0.002)
    dense.svd = counted
    try:
        seed = mech.simulate(factorization="svd", **kw)
        n_seed = len(calls)
        calls.clear()
        default = mech.simulate(**kw)
        n_default = len(calls)
    finally:
        dense.svd = svd
    return (_row_set("four-bar, projection, SVD at every evaluation", seed,
                     **{"SVDs": n_seed}) +
            _row_set("four-bar, projection", default, **{"SVDs": n_default}))


def random_work(rtol=1e-8, t_end=2.0):
    """The random mechanisms of the tests (two of each kind, `examples.random_mechanism`
    from the tests' seed): the default method's right-hand sides against the cheapest
    method that followed the motion."""
    from ..formulations import METHODS
    rng = np.random.default_rng(20261124)
    rows = []
    for kind in examples.RANDOM_KINDS:
        for k in range(2):
            mech, _ = examples.random_mechanism(rng, kind)
            counts = {}
            for method in sorted(m for m in METHODS if m != "ss-newmark"):
                res = mech.simulate(t_end=t_end, rtol=rtol, atol=1e-2 * rtol, method=method,
                                    output_step=0.01)
                if res.success and "may have left its branch" not in res.message:
                    counts[method] = res.stats["rhs_evaluations"]
            if "hybrid" in counts:
                rows.append(CostRow(f"random {kind} {k}", "hybrid rhs / cheapest",
                                    counts["hybrid"] / min(counts.values())))
    return rows


def heavy_rod():
    """The slider-crank scene with a 1e10 kg rod: the singularity monitor's evaluations of
    σ_min/σ_max (the search inside each step once took its whole budget of 4000)."""
    from ..formulations.monitor import SingularityMonitor
    from .scene import load_scene
    scene_file = Path(__file__).resolve().parents[2] / "mechanisms" / "slider_crank.toml"
    if not scene_file.is_file():
        return []
    calls = []
    measure = SingularityMonitor.measure

    def counted(self, *args, **kwargs):
        calls.append(1)
        return measure(self, *args, **kwargs)

    scene = load_scene(scene_file, parameters={"rod_mass": 1e10})
    SingularityMonitor.measure = counted
    try:
        res = scene.simulate()
    finally:
        SingularityMonitor.measure = measure
    return _row_set("slider-crank scene, 1e10 kg rod", res, **{"σ ratio evaluations": len(calls)})


CASES = {"noisy-bridge": noisy_bridge, "heavy-rod": heavy_rod, "ten-window": ten_window, "adams-hybrid": adams_hybrid,
         "stuck-lu": stuck_lu, "scipy-integrators": scipy_integrators, "seed-svd": seed_svd,
         "random-work": random_work}


def run(cases=tuple(CASES), progress=print) -> list[CostRow]:
    """Every case's rows; ValueError naming an unknown case before any runs."""
    for name in cases:
        if name not in CASES:
            raise ValueError(f"unknown cost case {name!r}; cases: {', '.join(CASES)}")
    rows = []
    for name in cases:
        found = CASES[name]()
        rows += found
        if progress:
            for r in found:
                progress(format_row(r))
    return rows


HEADER = f"{'case':48s} {'figure':28s} {'value':>12s}"


def format_row(r: CostRow) -> str:
    value = r.value if isinstance(r.value, str) else (
        f"{r.value:12d}" if isinstance(r.value, (int, np.integer)) else f"{r.value:12.4g}")
    return f"{r.case:48s} {r.figure:28s} {value:>12s}"


def write(rows, out_dir) -> list[Path]:
    """The rows as CSV (`costs.csv` in out_dir)."""
    from .bench import write_csv
    return [write_csv(rows, Path(out_dir) / "costs.csv", ("case", "figure", "value"))]
