"""Work–precision benchmarks: run time against error for every solver on problems with an
exact reference (`mechsim bench`).

The rigid problems are parallelogram mechanisms whose motion on their branch is the 1-DOF
equation M_eff θ̈ = −K cos θ (integrated independently at rtol 1e-13), so the error of a run is
the largest distance of a crank tip from its exact position over the run. The flexible
four-bar has no closed form: its error is the largest distance of the coupler's midpoint
(elastic deflection included) from a reference run of the projection method at rtol 1e-11.
"""

from __future__ import annotations

import csv
import functools
import math
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .. import examples
from ..files import save_figure, written


@dataclass(frozen=True)
class Problem:
    name: str
    build: object            # () -> Mechanism
    t_end: float
    theta0: float
    omega0: float
    windows: int
    max_step: float = math.inf
    description: str = ""
    integrator: str | None = None         # the problem's default integrator
    reference: object = None              # () -> SimulationResult when there is no exact one
    exact: object = None                  # (result) -> error, where it has its own measure
    quantity: str = "max crank-tip error [m]"

    @property
    def traced(self) -> tuple[str, tuple[float, float]]:
        """(body, local point) whose path the error measures: a coupler point against the
        reference, or the first crank's tip against the exact parallelogram."""
        if self.reference is not None:
            return "coupler", (0.5, 0.0)
        return ("crank1" if self.windows > 1 else "crank"), (0.5, 0.0)

    def error(self, res) -> float:
        if self.exact is not None:
            return float(self.exact(res))
        body, local = self.traced
        return self.point_error(res.t, res.point(body, local))

    def point_error(self, t, xy) -> float:
        """The largest distance of the traced point's path `xy` (N, 2) at times `t` from
        the reference's (interpolated) or the exact one: mechsim's and the peers' alike."""
        t, xy = np.asarray(t, float), np.asarray(xy, float)
        if self.reference is not None:
            ref = self.reference()                     # computed once (cached)
            body, local = self.traced
            path = ref.point(body, local)
            exact = np.column_stack([np.interp(t, ref.t, path[:, k]) for k in range(2)])
        else:
            theta, _ = examples.parallelogram_exact(t, self.theta0, self.omega0,
                                                    n=self.windows)
            exact = np.column_stack([np.cos(theta), np.sin(theta)])
        return float(np.max(np.hypot(*(xy - exact).T)))


PROBLEMS = {
    "parallelogram": Problem("parallelogram", examples.four_bar, 2.0, math.radians(10), 0.0, 1,
                             max_step=0.01, description="seed 001 falling four-bar, 2 s, "
                             "3 singular passages"),
    "double-four-bar": Problem("double-four-bar", lambda: examples.double_four_bar(2), 10.0,
                               math.pi / 2, -1.0, 2, description="IFToMM A02, 10 s, "
                               "10 singular passages"),
    "forty-window": Problem("forty-window", lambda: examples.double_four_bar(40), 20.0,
                            math.pi / 2, -1.0, 40, description="40-window four-bar, 20 s, "
                            "243 coordinates"),
}



@functools.cache
def _flexible_reference():
    return examples.flexible_four_bar().simulate(
        1.2, method="projection", rtol=1e-11, atol=1e-13, max_step=5e-4, output_step=1.2e-4)


PROBLEMS["flexible-four-bar"] = Problem(
    "flexible-four-bar", examples.flexible_four_bar, 1.2, math.radians(10), 0.0, 1,
    max_step=5e-4, integrator="adams", reference=_flexible_reference,
    description="seed 001 elastic coupler, 1.2 s, 2 singular passages",
    quantity="max coupler-midpoint error [m]")


def _slider_error(res) -> float:
    """The driven slider-crank's slider against its exact kinematics."""
    exact = examples.slider_crank_position(150.0 * res.t)
    return float(np.max(np.abs(res.coordinate("slider.x") - exact)))


PROBLEMS["driven-slider-crank"] = Problem(
    "driven-slider-crank", lambda: examples.slider_crank(driven=True), 0.2, 0.0, 150.0, 1,
    exact=_slider_error, quantity="max slider error [m]",
    description="crank driven at 150 rad/s (0 DOF), 0.2 s")

def _crank_rocker():
    """A Grashof crank-rocker (crank 0.3 m, coupler 0.9 m, rocker 0.7 m, ground 1 m)
    falling from rest at 60°: a smooth motion with no singular configuration."""
    return examples.general_four_bar(0.3, 0.9, 0.7, 1.0, math.radians(60.0),
                                     masses=(1.0, 1.5, 1.0), name="crank-rocker")


@functools.cache
def _crank_rocker_reference():
    # At the bench's output times (t_end / 1000), so that the error needs no interpolation.
    return _crank_rocker().simulate(3.0, method="projection", rtol=1e-12, atol=1e-14,
                                    output_step=3e-3)


PROBLEMS["crank-rocker"] = Problem(
    "crank-rocker", _crank_rocker, 3.0, math.radians(60.0), 0.0, 1,
    reference=_crank_rocker_reference, quantity="max coupler-point error [m]",
    description="Grashof crank-rocker falling from rest, 3 s, no singular passage")
PROBLEMS["seven-window"] = Problem(
    "seven-window", lambda: examples.double_four_bar(7), 3.0, math.pi / 2, -1.0, 7,
    description="7-window four-bar, 3 s, 45 coordinates, 3 singular passages")
PROBLEMS["ten-window"] = Problem(
    "ten-window", lambda: examples.double_four_bar(10), 3.0, math.pi / 2, -1.0, 10,
    description="10-window four-bar, 3 s, 63 coordinates, 3 singular passages")
PROBLEMS["hundred-window"] = Problem(
    "hundred-window", lambda: examples.double_four_bar(100), 20.0, math.pi / 2, -1.0, 100,
    description="100-window four-bar, 20 s, 603 coordinates")

DEFAULT_PROBLEMS = ("parallelogram", "double-four-bar", "driven-slider-crank")
DEFAULT_METHODS = ("lu", "projection", "projection-svd", "hybrid", "baumgarte")
# Benchmark names for a method with options: the seed's projection method takes an SVD at
# every evaluation, where mechsim's, clear of a singular configuration, takes the Cholesky
# factor of the Schur complement (same steps and motion, less cost); seed 001's Table 2
# compares the hybrid with the former.
VARIANTS = {"projection-svd": ("projection", {"factorization": "svd"})}
# The hybrid's time is compared with these methods' (`ratios`, `format_within`).
COMPARED = ("lu", "projection", "projection-svd")
DEFAULT_RTOLS = (1e-5, 1e-6, 1e-7, 1e-8, 1e-9)


@dataclass
class Row:
    problem: str
    method: str
    integrator: str
    rtol: float
    status: str
    error: float
    drift: float
    wall_time: float
    steps: int
    rhs: int
    passages: int


def check(problems, methods, repeat=1):
    """ValueError naming the first unknown problem or method (a registry name or a
    `VARIANTS` one), or a `repeat` below 1: before any run starts."""
    if int(repeat) < 1:
        raise ValueError(f"`repeat` must be a positive number of runs, got {repeat!r}")
    from ..formulations import METHODS
    for method in methods:
        if method not in METHODS and method not in VARIANTS:
            raise ValueError(f"unknown method {method!r}; methods: "
                             f"{', '.join(sorted([*METHODS, *VARIANTS]))}")
    for name in problems:
        if name not in PROBLEMS:
            raise ValueError(f"unknown problem {name!r}; problems: {', '.join(PROBLEMS)}")


def run(problems=DEFAULT_PROBLEMS, methods=DEFAULT_METHODS, rtols=DEFAULT_RTOLS,
        integrator=None, max_steps=20000, progress=print, repeat=1, beside=None) -> list[Row]:
    """Run every (problem, method, rtol); one warm-up run per problem first so that model
    building and imports are not timed. With `repeat` > 1 every run is repeated in rounds
    (each round runs all methods and tolerances once) and the shortest wall time is kept:
    on a machine whose speed drifts over minutes, rounds keep the methods' times measured
    side by side, and the minimum is the run least disturbed. `beside(problem, round,
    rounds)`, where given, is called after each round of a problem: what is timed there
    (the floor `mechsim bench peers` measures mechsim against) shares the rounds."""
    check(problems, methods, repeat)
    rows = []
    for name in problems:
        prob = PROBLEMS[name]
        mech = prob.build()
        mech.simulate(t_end=min(0.05, prob.t_end), method="lu")
        # Methods side by side at each tolerance: the ratios at equal rtol compare runs
        # seconds apart, on a machine whose speed drifts over minutes.
        cases = [(method, rtol) for rtol in rtols for method in methods]
        best = {}
        for round_ in range(int(repeat)):
            for case in cases:
                method, rtol = case
                base, options = VARIANTS.get(method, (method, {}))
                res = mech.simulate(t_end=prob.t_end, method=base, rtol=rtol,
                                    atol=rtol * 1e-2, max_step=prob.max_step,
                                    output_step=prob.t_end / 1000,
                                    integrator=integrator or prob.integrator,
                                    max_steps=max_steps, **options)
                wall = res.stats["wall_time"]
                if case in best:
                    best[case].wall_time = min(best[case].wall_time, wall)
                else:
                    best[case] = Row(name, method, res.stats["integrator"], rtol, res.status,
                                     prob.error(res) if res.t[-1] >= prob.t_end else math.nan,
                                     float(np.max(np.abs(res.energy_drift))), wall,
                                     res.stats["steps"], res.stats["rhs_evaluations"],
                                     len(res.singular_passages))
                if round_ == int(repeat) - 1:
                    rows.append(best[case])
                    if progress:
                        progress(format_row(best[case]))
            if beside is not None:
                beside(name, round_, int(repeat))
    return rows


HEADER = (f"{'problem':16s} {'method':14s} {'integrator':10s} {'rtol':>7s} {'status':8s} "
          f"{'error':>9s} {'drift':>9s} {'wall [s]':>9s} {'steps':>7s} {'rhs':>7s} {'pass':>4s}")


def format_row(r: Row) -> str:
    return (f"{r.problem:16s} {r.method:14s} {r.integrator:10s} {r.rtol:7.0e} {r.status:8s} "
            f"{r.error:9.2e} {r.drift:9.2e} {r.wall_time:9.3f} {r.steps:7d} {r.rhs:7d} "
            f"{r.passages:4d}")


def ratios(rows: list[Row], rtol: float) -> dict:
    """Wall-time ratios of the hybrid to each `COMPARED` method at one tolerance, per
    problem (measured in the same run, as the machine is noisy)."""
    out = {}
    for name in dict.fromkeys(r.problem for r in rows):
        wall = {r.method: r.wall_time for r in rows if r.problem == name and r.rtol == rtol}
        found = _hybrid_ratios(wall)
        if found:
            out[name] = found
    return out


def _hybrid_ratios(wall: dict) -> dict:
    """{"hybrid/<method>": ratio} of the wall times {method: seconds} for each `COMPARED`
    method there, when the hybrid is there too."""
    if "hybrid" not in wall:
        return {}
    return {f"hybrid/{m}": wall["hybrid"] / wall[m] for m in COMPARED if m in wall}


def cheapest_within(rows: list[Row], error: float) -> dict:
    """{problem: {method: row}}: each method's cheapest successful run whose error is within
    `error`, for a comparison at equal accuracy. At equal rtol the methods' runs are not
    equally accurate: on the double four-bar at rtol 1e-5 LU's crank tip strays up to 0.1 m,
    the hybrid's 1.7e-3 m; and a method's error need not fall with its rtol (LU's does not
    where it steps through a passage). A method with no such run is left out."""
    out = {}
    for r in rows:
        if r.status != "success" or not r.error <= error:
            continue
        best = out.setdefault(r.problem, {}).get(r.method)
        if best is None or r.wall_time < best.wall_time:
            out[r.problem][r.method] = r
    return out


def equal_error(rows: list[Row]) -> list[tuple[str, float, dict]]:
    """(problem, error, {method: row}) with `cheapest_within` at the decades of error from
    each problem's largest error down, while at least two methods get there. Consecutive
    decades served by the same runs are given once, at the smallest of them (those runs
    serve every larger one too)."""
    out = []
    for name in dict.fromkeys(r.problem for r in rows):
        mine = [r for r in rows if r.problem == name]
        errors = [r.error for r in mine if r.status == "success" and np.isfinite(r.error)
                  and r.error > 0.0]
        if not errors:
            continue
        last = None                               # (error, best) of the open group
        for k in range(math.ceil(math.log10(max(errors))),
                       math.ceil(math.log10(min(errors))) - 1, -1):
            best = cheapest_within(mine, 10.0 ** k).get(name, {})
            if len(best) < 2:
                break
            if last is not None and best != last[1]:
                out.append((name, *last))
            last = (10.0 ** k, best)
        if last is not None:
            out.append((name, *last))
    return out


def format_within(name: str, error: float, best: dict) -> str:
    """One line of `cheapest_within` for a problem: each method's time and the rtol that
    reached `error`, then the hybrid's ratios to the `COMPARED` methods that reached it."""
    parts = [f"{m} {r.wall_time:.3f} s (rtol {r.rtol:.0e})" for m, r in best.items()]
    ratios = _hybrid_ratios({m: r.wall_time for m, r in best.items()})
    parts += [f"{k} = {v:.2f}" for k, v in ratios.items()]
    return f"within error {error:.0e}, {name}: " + ", ".join(parts)


# The error a run may reach, in multiples of its rtol, for its tolerance to mean what it
# says (`proportionality`).
PROPORTIONAL = 20.0


def proportionality(rows: list[Row], factor: float = PROPORTIONAL) -> list[str]:
    """Per method, whether its errors follow its rtol: how many of its runs erred at most
    `factor` × rtol (in each problem's own error measure), and which did not (problem,
    rtol, error ÷ rtol; a failed run or one without an error counts as not); then per
    problem and method with two rtols or more, the time at the loosest rtol ÷ at the
    tightest (how much a looser tolerance saves)."""
    lines = []
    for method in dict.fromkeys(r.method for r in rows):
        mine = [r for r in rows if r.method == method]
        over = [r for r in mine if not (r.status == "success" and r.error <= factor * r.rtol)]
        text = (f"tolerance proportionality, {method}: error ≤ {factor:g} rtol in "
                f"{len(mine) - len(over)} of {len(mine)} runs")
        if over:
            text += "; not: " + ", ".join(
                f"{r.problem} at {r.rtol:.0e} (" +
                (f"{r.error / r.rtol:.3g} rtol)" if r.status == "success" and
                 np.isfinite(r.error) else f"{r.status})") for r in over)
        lines.append(text)
    for name in dict.fromkeys(r.problem for r in rows):
        for method in dict.fromkeys(r.method for r in rows if r.problem == name):
            mine = [r for r in rows if r.problem == name and r.method == method]
            loose, tight = max(mine, key=lambda r: r.rtol), min(mine, key=lambda r: r.rtol)
            if loose.rtol > tight.rtol and tight.wall_time > 0.0:
                lines.append(f"{name}, {method}: t(rtol {loose.rtol:.0e}) / t(rtol "
                             f"{tight.rtol:.0e}) = {loose.wall_time / tight.wall_time:.2f}")
    return lines


def write_csv(rows, path: Path, fields) -> Path:
    """One CSV row per row of `rows` with the attributes `fields`, under a header of them
    (`mechsim.files.written`)."""
    def write(p):
        with open(p, "w", newline="") as f:
            w = csv.writer(f)
            w.writerow(fields)
            for r in rows:
                w.writerow([getattr(r, k) for k in fields])
    return written(Path(path), write)


def write(rows: list[Row], out_dir) -> list[Path]:
    """CSV of all rows and one error-vs-time plot per problem."""
    from matplotlib.figure import Figure
    out_dir = Path(out_dir)
    written = [write_csv(rows, out_dir / "bench.csv", list(Row.__dataclass_fields__))]
    for name in dict.fromkeys(r.problem for r in rows):
        fig = Figure(figsize=(6.4, 4.4), layout="constrained")
        ax = fig.add_subplot()
        for k, method in enumerate(dict.fromkeys(r.method for r in rows if r.problem == name)):
            pts = [(r.wall_time, r.error) for r in rows
                   if r.problem == name and r.method == method and r.status == "success"
                   and np.isfinite(r.error)]
            if pts:
                x, y = zip(*sorted(pts))
                ax.loglog(x, y, "o-", color=f"C{k}", label=method)
        ax.set_xlabel("wall time [s]")
        ax.set_ylabel(PROBLEMS[name].quantity)
        ax.set_title(f"{name}: {PROBLEMS[name].description}")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend()
        png = out_dir / f"bench_{name}.png"
        save_figure(fig, png)
        written.append(png)
    return written


# --- Random mechanisms: the default method against projection -----------------------------

@dataclass
class RandomRow:
    case: str
    method: str
    status: str
    error: float             # max |q − q_ref| over the run's samples (m and rad)
    drift: float
    wall_time: float
    rhs: int
    passages: int


RANDOM_HEADER = (f"{'case':18s} {'method':10s} {'status':8s} {'error':>9s} {'drift':>9s} "
                 f"{'wall [s]':>9s} {'rhs':>7s} {'pass':>4s}")


def random_run(count=12, rtol=1e-8, seed=20261124, methods=("hybrid", "projection"),
               t_end=2.0, progress=print) -> list[RandomRow]:
    """`count` random mechanisms (`examples.random_mechanism`, the kinds in turn) run by each
    of `methods` at `rtol`; each run's error against a projection run at rtol 1e-12 (the
    turning parallelograms: against their exact uniform rotation, θ + speed·t), measured
    at 200 samples. One untimed warm-up run per mechanism builds its model first."""
    rng = np.random.default_rng(seed)
    rows = []
    kinds = examples.RANDOM_KINDS
    for k in range(int(count)):
        kind = kinds[k % len(kinds)]
        mech, params = examples.random_mechanism(rng, kind)
        mech.simulate(t_end=0.01, method="projection")
        step = t_end / 200
        if kind == "parallelogram":
            exact = None
        else:
            ref = mech.simulate(t_end=t_end, method="projection", rtol=1e-12, atol=1e-14,
                                output_step=step)
        for method in methods:
            res = mech.simulate(t_end=t_end, method=method, rtol=rtol, atol=rtol * 1e-2,
                                output_step=step)
            n = len(res.t)
            if kind == "parallelogram":
                exact = params["theta"] + params["speed"] * res.t
                d = res.coordinate("rocker.angle") - exact
                error = float(np.max(np.abs((d + math.pi) % (2 * math.pi) - math.pi)))
            else:
                error = float(np.max(np.abs(res.q - ref.q[:n])))
            row = RandomRow(f"{kind} {k // len(kinds)}", method, res.status, error,
                            float(np.max(np.abs(res.energy_drift))),
                            res.stats["wall_time"], res.stats["rhs_evaluations"],
                            len(res.singular_passages))
            rows.append(row)
            if progress:
                progress(format_random(row))
    return rows


def format_random(r: RandomRow) -> str:
    return (f"{r.case:18s} {r.method:10s} {r.status:8s} {r.error:9.2e} {r.drift:9.2e} "
            f"{r.wall_time:9.3f} {r.rhs:7d} {r.passages:4d}")


def random_summary(rows: list[RandomRow], method="hybrid", against="projection") -> str:
    """The default method against projection over the sweep: wall-time and right-hand-side
    ratios per case (median and largest) and each method's largest error."""
    by = {}
    for r in rows:
        by.setdefault(r.case, {})[r.method] = r
    pairs = [(c[method], c[against]) for c in by.values() if method in c and against in c]
    if not pairs:
        return ""
    wall = np.array([a.wall_time / b.wall_time for a, b in pairs])
    rhs = np.array([a.rhs / b.rhs for a, b in pairs])
    return (f"random mechanisms ({len(pairs)}): {method}/{against} wall time median "
            f"{np.median(wall):.2f}, largest {wall.max():.2f}; right-hand sides median "
            f"{np.median(rhs):.2f}, largest {rhs.max():.2f}; largest error {method} "
            f"{max(a.error for a, _ in pairs):.2e}, {against} {max(b.error for _, b in pairs):.2e}"
            f"; failed: {sum(a.status != 'success' for a, _ in pairs)} and "
            f"{sum(b.status != 'success' for _, b in pairs)}")


def write_random(rows: list[RandomRow], out_dir) -> list[Path]:
    """CSV of the random sweep's rows."""
    return [write_csv(rows, Path(out_dir) / "bench_random.csv",
                       list(RandomRow.__dataclass_fields__))]


# --- Shooting against brute force (seed 002) ---------------------------------------------

COULOMB = dict(zeta=0.05, omega_n=100.0, delta_st=0.1, omega=100.0)   # the paper's Fig. 4
# (μ, start): from rest, and from each μ's guess in the example (Table 2's Case 1 for 0.08).
COULOMB_CASES = ((0.07, (0.0, 0.0)), (0.07, (0.0, 10.0)), (0.08, (0.0, 0.0)),
                 (0.08, (-0.014, 2.7)), (0.09, (0.0, 0.0)), (0.09, (-0.01, 2.0)))
DEFAULT_ACCURACIES = (1e-4, 1e-6, 1e-8, 1e-10)


@dataclass
class ShootingRow:
    mu: float
    start: tuple
    accuracy: float          # both runs stop within this of the periodic state (max norm)
    shooting_time: float
    shooting_flows: int      # one-period flows: one per Newton iterate evaluated
    shooting_error: float
    brute_time: float
    brute_periods: int
    brute_error: float

    @property
    def speedup(self) -> float:
        return self.brute_time / self.shooting_time


def settle(problem, u, reference, accuracy, max_periods=100000):
    """Brute force: simulate period after period (`problem.period_map`, the same motion
    shooting uses, without the monodromy) until the state is within `accuracy` of
    `reference` (max norm). Returns (state, periods). Knowing the periodic state is an
    oracle a real run lacks — it would stop on the change per period, which is smaller
    than the distance by the factor 1 − ρ (ρ the contraction per period) — so the
    comparison favours brute force."""
    x = np.asarray(u, float)
    for k in range(1, max_periods + 1):
        x = problem.period_map(x)
        if np.max(np.abs(x - reference)) <= accuracy:
            return x, k
    raise ValueError(f"{type(problem).__name__}: not within {accuracy:g} of the periodic state "
                     f"after {max_periods} periods")


def shooting_run(cases=COULOMB_CASES, accuracies=DEFAULT_ACCURACIES, repeat=5,
                 progress=print) -> list[ShootingRow]:
    """Shooting (Newton with the exact monodromy) against brute-force simulation to the
    same accuracy on the Coulomb oscillator, both from the same start and on the same
    closed-form motion. Shooting stops at max |g| < accuracy / ‖(I − M)⁻¹‖∞, M the
    monodromy at the periodic state u*: to first order u − u* = (I − M)⁻¹ g (the bound is
    24 at μ = 0.07, 19 at 0.08, 2.2 at 0.09), or where its Newton step predicts the next
    iterate within the accuracy (`xtol`). The row reports the error each run reached,
    measured against u*.
    Every run starts on a fresh oscillator (nothing cached), is repeated `repeat` times in
    rounds, and keeps its shortest wall time."""
    from .. import shooting
    from ..shooting.oscillators import CoulombOscillator
    if int(repeat) < 1:
        raise ValueError(f"`repeat` must be a positive number of runs, got {repeat!r}")
    refs = {}
    for mu, start in cases:
        osc = CoulombOscillator(**COULOMB, mu=mu)
        ref = shooting.solve(osc, start, method="newton", tol=1e-13, floquet=False).x0
        gain = np.linalg.norm(np.linalg.inv(np.eye(2) - osc.floquet_matrix(ref)), np.inf)
        refs[mu, tuple(start)] = ref, gain
    runs = [(mu, tuple(start), acc) for mu, start in cases for acc in accuracies]
    best = {}
    for _ in range(int(repeat)):                  # rounds, as in `run`
        for mu, start, acc in runs:
            ref, gain = refs[mu, start]
            osc = CoulombOscillator(**COULOMB, mu=mu)
            t0 = time.perf_counter()
            sol = shooting.solve(osc, start, method="newton", tol=acc / gain, xtol=acc,
                                 floquet=False)
            t_shoot = time.perf_counter() - t0
            if not sol.converged:
                raise RuntimeError(f"shooting did not converge for μ = {mu} from {start}: "
                                   f"{sol.message}")
            flows = osc.flows
            osc = CoulombOscillator(**COULOMB, mu=mu)
            t0 = time.perf_counter()
            x, periods = settle(osc, start, ref, acc)
            t_brute = time.perf_counter() - t0
            row = best.get((mu, start, acc))
            if row is None:
                best[mu, start, acc] = ShootingRow(
                    mu, start, acc, t_shoot, flows, float(np.max(np.abs(sol.x0 - ref))),
                    t_brute, periods, float(np.max(np.abs(x - ref))))
            else:
                row.shooting_time = min(row.shooting_time, t_shoot)
                row.brute_time = min(row.brute_time, t_brute)
    rows = [best[k] for k in runs]
    if progress:
        for row in rows:
            progress(format_shooting_row(row))
    return rows


SHOOTING_HEADER = (f"{'mu':>5s} {'start':16s} {'accuracy':>8s} {'shoot [ms]':>10s} {'flows':>5s} "
                   f"{'error':>8s} {'brute [ms]':>10s} {'periods':>7s} {'error':>8s} "
                   f"{'speed-up':>8s}")


def format_shooting_row(r: ShootingRow) -> str:
    return (f"{r.mu:5.2f} {str(r.start):16s} {r.accuracy:8.0e} {1e3 * r.shooting_time:10.2f} "
            f"{r.shooting_flows:5d} {r.shooting_error:8.1e} {1e3 * r.brute_time:10.2f} "
            f"{r.brute_periods:7d} {r.brute_error:8.1e} {r.speedup:7.1f}×")


def write_shooting(rows: list[ShootingRow], out_dir) -> list[Path]:
    """CSV of the rows and a plot of wall time against accuracy, per case and method."""
    from matplotlib.figure import Figure
    out_dir = Path(out_dir)
    path = write_csv(rows, out_dir / "bench_coulomb.csv",
                      list(ShootingRow.__dataclass_fields__) + ["speedup"])
    fig = Figure(figsize=(6.4, 4.4), layout="constrained")
    ax = fig.add_subplot()
    for k, case in enumerate(dict.fromkeys((r.mu, r.start) for r in rows)):
        sel = [r for r in rows if (r.mu, r.start) == case]
        acc = [r.accuracy for r in sel]
        label = f"μ = {case[0]}, from {case[1]}"
        ax.loglog(acc, [r.shooting_time for r in sel], "o-", color=f"C{k}",
                  label=f"{label}: shooting")
        ax.loglog(acc, [r.brute_time for r in sel], "s--", color=f"C{k}",
                  label=f"{label}: brute force")
    ax.invert_xaxis()
    ax.set_xlabel("accuracy of the periodic state (max norm)")
    ax.set_ylabel("wall time [s]")
    ax.set_title("Coulomb oscillator: shooting against brute-force simulation")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=6)
    png = out_dir / "bench_coulomb.png"
    save_figure(fig, png)
    return [path, png]
