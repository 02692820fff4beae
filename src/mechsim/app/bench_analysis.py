"""`mechsim bench analysis`: what reactions, equilibrium and linearization cost beside a
simulation of the same mechanism."""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path


from .. import examples
from .bench import write_csv


# --- engineering analysis: what reactions, equilibrium and linearization cost ---------------
@dataclass
class AnalysisRow:
    """One measured analysis: `what` on `problem`, its wall time and the reference it is
    measured against (the simulation's own wall time for reactions), best of `repeat`."""
    problem: str
    what: str
    wall_time: float
    reference: float
    note: str


ANALYSIS_HEADER = f"{'problem':18s} {'analysis':34s} {'wall [s]':>9s} {'ratio':>7s}  note"


def analysis_run(repeat=3) -> list[AnalysisRow]:
    """Reactions of every joint of a 10 000-sample double four-bar result against the
    simulation that made it (hybrid, rtol 1e-8, 10 s sampled every millisecond); equilibrium and linearization
    of the 40-window chain (its model built first, not timed)."""
    mech = examples.double_four_bar()
    mech.simulate(0.1)                                   # the model built and compiled
    sims, reactions = [], []
    for _ in range(repeat):
        t0 = time.perf_counter()
        res = mech.simulate(10.0, method="hybrid", rtol=1e-8, atol=1e-10, output_step=1e-3)
        t1 = time.perf_counter()
        for joint in mech.joints:
            res.joint_force(joint)
        reactions.append(time.perf_counter() - t1)
        sims.append(t1 - t0)
    rows = [AnalysisRow("double-four-bar", f"reactions of {len(mech.joints)} joints, "
                        f"{len(res.t)} samples", min(reactions), min(sims),
                        "ratio: against the simulation's wall time")]
    chain = examples.double_four_bar(40)
    chain.problem()
    for what, run in (("equilibrium", chain.equilibrium), ("linearization", chain.linearize)):
        best = min(_timed(run) for _ in range(repeat))
        rows.append(AnalysisRow("forty-window", what, best, float("nan"),
                                f"{len(chain.coordinate_names)} coordinates"))
    return rows


def _timed(fn) -> float:
    t0 = time.perf_counter()
    fn()
    return time.perf_counter() - t0


def format_analysis(r: AnalysisRow) -> str:
    ratio = f"{r.wall_time / r.reference:7.3f}" if r.reference == r.reference else " " * 7
    return f"{r.problem:18s} {r.what:34s} {r.wall_time:9.4f} {ratio}  {r.note}"


def write_analysis(rows: list[AnalysisRow], out_dir) -> list[Path]:
    return [write_csv(rows, Path(out_dir) / "bench_analysis.csv",
                       list(AnalysisRow.__dataclass_fields__))]
