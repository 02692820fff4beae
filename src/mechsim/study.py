"""Parameter studies: many mechanisms built from parameter sets, each simulated (or analysed)
and reduced to numbers, on a local process pool or a dask.distributed cluster.

    study = ms.sweep(build, grid, simulate=dict(t_end=1.0), measure=fn, client=None)
    study.table              # {column: ndarray}

`grid` is a full-factorial table `{name: values}`, a list of parameter dicts, or a table
whose values are distributions (anything with `rvs`, e.g. `scipy.stats.norm(0.15, 1e-3)`)
for a Monte Carlo study of `samples` draws (`seed`), crossed with the table's sequences and
with the same draws at every factorial point (common random numbers). A constant is a
parameter that does not vary.

Each sample runs `build(**params)` -> Mechanism, then `analyse(mech)` if given (an
equilibrium, modes, a kinematic analysis, a shooting run: any function of the mechanism),
else `mech.simulate(**simulate)`, then `measure(result)` -> {name: number}. Whatever fails
(the build, the run, the measure, a worker process) is recorded in the sample's "status"
and "message" columns, with NaN measures, and the study goes on; a run that ends early
records its own status and message with the measures of its partial result (where
`analyse` returns a tuple, the first item with a `status`).

One compiled structure serves the study: the first sample's model is built before the
samples are dispatched (fused where the mechanism is small, assembled from joint-type
kernels where it is large; `mechsim.build.constraint_model`), and every worker loads it from
the disk cache, the geometry being parameters. Workers on other machines need the same
cache directory or build their own once.

Where the work runs (`run_tasks`, which the shooting regime map uses too): `client`, a
`dask.distributed.Client` (dask is an optional extra, `pip install distributed`,
imported only here); else `workers` local processes (default: every core), forked so
that `build`, `analyse` and `measure` may be lambdas or closures (where fork is not
available they must be importable functions); `workers=1` runs in this process. A
progress bar (tqdm) counts finished samples.
"""

from __future__ import annotations

import itertools
import math
import multiprocessing
import os
import time
import traceback
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .model import ModelError


# --- running tasks ------------------------------------------------------------------------------
_INHERITED: list = []            # (function, tasks) a forked worker finds in its memory


def _inherited(index: int):
    fn, tasks = _INHERITED[-1]
    return fn(tasks[index])


class WorkerLost(RuntimeError):
    """A worker process ended without returning its task's result."""


def run_tasks(fn, tasks, client=None, workers=None, progress=False, desc="tasks"):
    """[fn(task) for task in tasks], computed on `client` (a dask.distributed Client), on
    `workers` local processes (None: every core; 1: in this process), in task order. A
    task whose worker died or whose function raised gives the exception in its place
    (`WorkerLost` for a dead worker) instead of stopping the others; `progress`: a tqdm
    bar of finished tasks."""
    tasks = list(tasks)
    bar = _bar(progress, len(tasks), desc)
    try:
        if client is not None:
            return _on_dask(client, fn, tasks, bar)
        workers = min(workers or os.cpu_count() or 1, max(len(tasks), 1))
        if workers <= 1:
            out = []
            for task in tasks:
                out.append(_guarded(fn, task))
                bar.update()
            return out
        return _on_pool(fn, tasks, workers, bar)
    finally:
        bar.close()


def _guarded(fn, task):
    try:
        return fn(task)
    except Exception as exc:        # recorded in the task's place
        return exc


def _on_pool(fn, tasks, workers, bar):
    methods = multiprocessing.get_all_start_methods()
    if "fork" in methods:
        _INHERITED.append((fn, tasks))
        context, call, args = multiprocessing.get_context("fork"), _inherited, range(len(tasks))
    else:
        context, call, args = multiprocessing.get_context(methods[0]), fn, tasks
    out = [None] * len(tasks)
    try:
        with ProcessPoolExecutor(max_workers=workers, mp_context=context) as pool:
            futures = {pool.submit(call, a): i for i, a in enumerate(args)}
            for future in as_completed(futures):
                out[futures[future]] = _outcome(future)
                bar.update()
    finally:
        if call is _inherited:
            _INHERITED.pop()
    return out


def _outcome(future):
    from concurrent.futures.process import BrokenProcessPool
    try:
        return future.result()
    except BrokenProcessPool as exc:
        return WorkerLost(f"the worker process died ({exc})")
    except Exception as exc:
        return exc


def _on_dask(client, fn, tasks, bar):
    from distributed import as_completed as dask_completed
    futures = client.map(fn, tasks, pure=False)
    index = {f.key: i for i, f in enumerate(futures)}
    out = [None] * len(tasks)
    for future in dask_completed(futures):
        try:
            out[index[future.key]] = future.result()
        except Exception as exc:
            out[index[future.key]] = exc
        bar.update()
    return out


class _NoBar:
    def update(self, n=1):
        pass

    def close(self):
        pass


def _bar(progress, total, desc):
    from .progress import tqdm_bar
    bar = tqdm_bar(total=total, desc=desc, unit="sample") if progress else None
    return _NoBar() if bar is None else bar


# --- the samples -------------------------------------------------------------------------------
def parameter_sets(grid, samples=None, seed=None) -> list[dict]:
    """The studied parameter sets of `grid` (see the module): a list of dicts as given; a
    table's sequences crossed (the first key varying slowest), its constants held, and
    with distributions, `samples` draws crossed with the sequences."""
    if isinstance(grid, (list, tuple)):
        sets = [dict(s) for s in grid]
        for k, s in enumerate(sets):
            _check_names(s, f"grid[{k}]")
        return sets
    if not isinstance(grid, dict):
        raise ModelError(f"sweep: `grid` must be a dict of parameter values or a list of "
                         f"dicts, got {type(grid).__name__}")
    _check_names(grid, "grid")
    axes, draws, constants = {}, {}, {}
    for name, values in grid.items():
        if hasattr(values, "rvs"):
            draws[name] = values
        elif isinstance(values, (str, bytes)) or not hasattr(values, "__iter__"):
            constants[name] = values
        else:
            axes[name] = list(values)
            if not axes[name]:
                raise ModelError(f"sweep: grid '{name}' has no values")
    if draws:
        if samples is None or int(samples) < 1:
            raise ModelError(f"sweep: the distributions of {', '.join(draws)} need "
                             f"`samples` (a count ≥ 1), got {samples!r}")
        rng = np.random.default_rng(seed)
        drawn = {name: np.asarray(d.rvs(size=int(samples), random_state=rng), float)
                 for name, d in draws.items()}
        monte_carlo = [{name: float(v[i]) for name, v in drawn.items()}
                       for i in range(int(samples))]
    elif samples is not None:
        raise ModelError("sweep: `samples` is for grids with distributions (objects with "
                         "`rvs`, e.g. scipy.stats.norm(mean, sd)); this grid has none")
    else:
        monte_carlo = [{}]
    sets = [{**constants, **dict(zip(axes, point)), **mc}
            for point in itertools.product(*axes.values()) for mc in monte_carlo]
    return [{name: s[name] for name in grid} for s in sets]      # in the grid's order


# Columns every study's table has besides its parameters and measures.
RESERVED = ("status", "message", "time")


def _check_names(params, where):
    for name in params:
        if not isinstance(name, str) or not name.isidentifier():
            raise ModelError(f"sweep: {where}: parameter names must be identifiers (keyword "
                             f"arguments of `build`), got {name!r}")
        if name in RESERVED:
            raise ModelError(f"sweep: {where}: '{name}' is a column of every study "
                             f"({', '.join(RESERVED)}); name the parameter otherwise")


@dataclass(frozen=True)
class _Spec:
    """What every sample runs (pickled to dask workers, inherited by forked ones)."""
    build: object
    simulate: dict
    analyse: object
    measure: object
    model_build: str

    def __call__(self, params) -> dict:
        start = time.perf_counter()
        stage = "build"
        try:
            mech = self.build(**params)
            stage = "analyse" if self.analyse is not None else "simulate"
            mech.problem(build=self.model_build)
            res = self.analyse(mech) if self.analyse is not None else \
                mech.simulate(**self.simulate)
            status, message = _status_of(res)
            stage = "measure"
            values = _numbers(self.measure(res)) if self.measure is not None else {}
        except Exception as exc:
            return dict(status="failed", message=f"{stage}: {type(exc).__name__}: {exc}",
                        values={}, time=time.perf_counter() - start,
                        trace=traceback.format_exc(limit=-3))
        return dict(status=status, message=message, values=values,
                    time=time.perf_counter() - start, trace="")


def _status_of(res) -> tuple[str, str]:
    """(status, message) of a run's or analysis's result, or of the first item with a
    status in a tuple or list `analyse` returned; ("success", "") for anything else."""
    for item in (res, *(res if isinstance(res, (tuple, list)) else ())):
        if hasattr(item, "status"):
            return str(item.status), str(getattr(item, "message", "") or "")
    return "success", ""


def _numbers(values) -> dict:
    if not isinstance(values, dict):
        raise TypeError(f"`measure` must return a dict of numbers, got {type(values).__name__}")
    out = {}
    for name, value in values.items():
        if not isinstance(name, str) or name in RESERVED:
            raise TypeError(f"`measure` returned the key {name!r}; keys must be strings "
                            f"other than {', '.join(RESERVED)}")
        try:
            out[name] = float(value)
        except (TypeError, ValueError):
            raise TypeError(f"`measure` returned {value!r:.60} for '{name}'; expected a "
                            "number") from None
    return out


@dataclass
class Study:
    """A finished study.

    Attributes
    ----------
    table : dict of str -> ndarray
        One entry per sample in each column: the parameters, each measure (NaN where the
        sample did not give it), "status" ("success", a run's own status, or "failed"),
        "message" and "time" (the sample's wall time in seconds).
    parameters, measures : list of str
        The parameter and measure columns of `table`, in order.
    wall_time : float
        The whole study's wall time in seconds.
    """
    table: dict
    parameters: list
    measures: list
    wall_time: float = 0.0
    traces: list = field(default_factory=list, repr=False)

    def __len__(self) -> int:
        return len(self.table["status"])

    @property
    def failed(self) -> np.ndarray:
        """Indices of the samples whose status is not "success"."""
        return np.flatnonzero(self.table["status"] != "success")

    def to_csv(self, path) -> Path:
        """The table as CSV at `path`: a header of its columns, one row per sample, numbers
        written to round-trip exactly and a failed sample's measures empty (written through
        `mechsim.files.written`: never through a link, never half-written)."""
        import csv
        from .files import written
        columns = list(self.table)

        def cell(value):
            if isinstance(value, (float, np.floating)):
                return "" if math.isnan(value) else repr(float(value))
            return value

        def write(p):
            with open(p, "w", newline="", encoding="utf-8") as out:
                writer = csv.writer(out)
                writer.writerow(columns)
                for i in range(len(self)):
                    writer.writerow([cell(self.table[c][i]) for c in columns])
        return written(path, write)

    def to_pandas(self):
        """The table as a pandas DataFrame (pandas must be installed)."""
        try:
            import pandas as pd
        except ImportError:
            raise ImportError("Study.to_pandas needs pandas (pip install pandas; from a checkout, pip install '.[pandas]'); "
                              "`Study.table` holds the same columns as numpy arrays") from None
        return pd.DataFrame(self.table)

    def __repr__(self):
        return (f"Study({len(self)} samples, {len(self) - len(self.failed)} succeeded; "
                f"parameters {self.parameters}, measures {self.measures}; "
                f"{self.wall_time:.3g} s)")


def sweep(build, grid, simulate=None, measure=None, client=None, *, analyse=None,
          samples=None, seed=None, workers=None, progress=False) -> Study:
    """Build, run and measure a mechanism for every parameter set of `grid` (see the
    module for `grid`, `samples`, `seed`, `analyse`, `client` and `workers`).

    Parameters
    ----------
    build : callable
        ``build(**params)`` returns a Mechanism.
    grid : dict or list of dict
    simulate : dict, optional
        Keyword arguments of `Mechanism.simulate` (with no `analyse`).
    measure : callable, optional
        ``measure(result)`` returns ``{name: number}``; the result is the simulation's, or
        what `analyse` returned.
    client : dask.distributed.Client, optional
    progress : bool
        A tqdm progress bar of finished samples.

    Bad arguments raise before any sample runs; failing samples are recorded (see
    `Study`).
    """
    if not callable(build):
        raise ModelError(f"sweep: `build` must be a function of the parameters returning a "
                         f"Mechanism, got {type(build).__name__}")
    for name, fn in (("measure", measure), ("analyse", analyse)):
        if fn is not None and not callable(fn):
            raise ModelError(f"sweep: `{name}` must be a function, got {type(fn).__name__}")
    if analyse is not None and simulate is not None:
        raise ModelError("sweep: give `simulate` (keyword arguments of Mechanism.simulate) "
                         "or `analyse` (a function of the mechanism), not both")
    if simulate is not None and not isinstance(simulate, dict):
        raise ModelError(f"sweep: `simulate` must be a dict of Mechanism.simulate's keyword "
                         f"arguments, got {type(simulate).__name__}")
    if workers is not None and (not isinstance(workers, int) or workers < 1):
        raise ModelError(f"sweep: `workers` must be a count ≥ 1, got {workers!r}")
    sets = parameter_sets(grid, samples, seed)
    start = time.perf_counter()
    spec = _Spec(build, dict(simulate or {}), analyse, measure, _prepare(build, sets))
    records = run_tasks(spec, sets, client=client, workers=workers, progress=progress,
                        desc="sweep")
    records = [r if isinstance(r, dict) else
               dict(status="failed", message=f"worker: {type(r).__name__}: {r}", values={},
                    time=math.nan, trace="") for r in records]
    return _study(sets, records, time.perf_counter() - start)


def _prepare(build, sets) -> str:
    """Build the first sample's model into the cache (so that workers load it) and say
    which build the samples use: fused for a small mechanism, assembled for a large one.
    A first sample that cannot be built leaves the choice to each sample ("auto" without
    background builds would differ by timing, so "fused")."""
    from .codegen.compiled import C_MIN_COORDINATES
    try:
        mech = build(**sets[0]) if sets else None
        n = len(mech.initial_coordinates())
    except Exception:
        return "fused"
    mode = "fused" if n < C_MIN_COORDINATES else "assembled"
    try:
        mech.problem(build=mode)
        if mode == "fused":
            from .codegen import engine
            engine.for_problem(mech.problem())      # the compiled evaluations, built once
    except Exception:
        pass                      # the sample itself will record what fails
    return mode


def _study(sets, records, wall_time) -> Study:
    names = list(dict.fromkeys(k for s in sets for k in s))
    measures = list(dict.fromkeys(k for r in records for k in r["values"]))
    table = {}
    for name in names:
        column = [s.get(name, math.nan) for s in sets]
        try:
            table[name] = np.array(column, dtype=float)
        except (TypeError, ValueError):
            table[name] = np.array(column, dtype=object)
    for name in measures:
        table[name] = np.array([r["values"].get(name, math.nan) for r in records], float)
    table["status"] = np.array([r["status"] for r in records], dtype=object)
    table["message"] = np.array([r["message"] for r in records], dtype=object)
    table["time"] = np.array([r["time"] for r in records], dtype=float)
    return Study(table, names, measures, wall_time, [r["trace"] for r in records])
