"""Study files: a parameter study of a scene, described in TOML (`mechsim sweep STUDY.toml`).

    scene = "../driven_slider_crank.toml"   # the scene studied, relative to this file
    samples = 1000                          # draws of the distributions (Monte Carlo)
    seed = 1
    output = "out/tolerances.csv"           # the table (default: out/<study name>.csv)

    [vary]                      # the scene's [parameters]: a list of values (crossed, full
    w = [100, 150, 200]         # factorial), a number (held), or a distribution:
    r = { normal = [0.05, 0.0001] }         # mean, standard deviation
    m_rod = { uniform = [0.55, 0.65] }      # low, high

    [[measure]]
    name = "wrist pin peak"     # the column (default: the kind and its subject)
    peak_force = "wrist pin"    # a joint's largest force magnitude over the run

Measure kinds (one per table): `peak_force` (a joint), `peak_effort`, `rms_effort`,
`peak_power` (a driver), and of a coordinate ("body.x", "crank.angle", …) `final`, `max`,
`min`, `range`. Every sample is the scene with its parameters replaced
(`load_scene(path, parameters=)`), run with its own `[simulation]` settings. Every key,
name and value is checked before any sample runs; nothing in the file is executed (numbers
may be expressions, parsed as in scenes).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from functools import partial
from pathlib import Path, PurePath

import numpy as np

from ..model import ModelError
from ..options import unknown_names
from .scene import SceneError, evaluate, load_scene, read_toml
from ..study import RESERVED

_TOP = {"scene", "samples", "seed", "output", "workers", "vary", "measure"}
_DISTRIBUTIONS = {"normal": ("mean", "standard deviation"), "uniform": ("low", "high")}
JOINT_MEASURES = ("peak_force",)
DRIVER_MEASURES = ("peak_effort", "rms_effort", "peak_power")
COORDINATE_MEASURES = ("final", "max", "min", "range")
MEASURES = JOINT_MEASURES + DRIVER_MEASURES + COORDINATE_MEASURES


@dataclass
class StudyFile:
    """A checked study file: the scene's path, the grid for `ms.sweep`, the measures as
    (column, kind, subject), and the settings."""
    path: Path
    scene: Path
    grid: dict
    measures: list
    samples: int | None
    seed: int | None
    workers: int | None
    output: Path

    def run(self, client=None, workers=None, progress=False):
        """The study (`mechsim.study.sweep`) of the scene over the grid."""
        from ..study import sweep
        return sweep(partial(_scene_mechanism, self.scene), self.grid, analyse=_simulate,
                     measure=partial(_measure, self.measures), client=client,
                     samples=self.samples, seed=self.seed,
                     workers=workers or self.workers, progress=progress)


def _scene_mechanism(scene, **parameters):
    loaded = load_scene(scene, parameters)
    mech = loaded.mechanism
    mech.scene_simulation = loaded.simulation
    return mech


def _simulate(mech):
    return mech.simulate(**mech.scene_simulation)


def _measure(measures, res) -> dict:
    out = {}
    for column, kind, subject in measures:
        if kind == "peak_force":
            f = res.joint_force(subject)
            out[column] = float(np.max(np.hypot(f[:, 0], f[:, 1])))
        elif kind in DRIVER_MEASURES:
            e = res.driver_power(subject) if kind == "peak_power" else res.driver_effort(subject)
            out[column] = float(np.sqrt(np.mean(e * e)) if kind == "rms_effort"
                                else np.max(np.abs(e)))
        else:
            x = res.q[:, res.coordinate_names.index(subject)]
            out[column] = float({"final": x[-1], "max": x.max(), "min": x.min(),
                                 "range": x.max() - x.min()}[kind])
    return out


class StudyError(ModelError):
    """A study file is malformed; the message names the file, the table and the key."""


def read_with_scene(path, top, kind: str, error):
    """(the TOML file at `path`, the scene it names, that scene loaded with its own
    parameters): its top-level keys checked against `top` and its `scene`, the error
    class `error` naming the file (`kind`: "a study", "a design file")."""
    f = path.name
    data = read_toml(path)
    message = unknown_names(data, {k: None for k in top}, kind)
    if message:
        raise error(f"{f}: " + message.replace(f"{kind} does not take",
                                               "unknown top-level key(s)"))
    if not isinstance(data.get("scene"), str):
        raise error(f"{f}: `scene` must name the scene file (a string), got "
                    f"{data.get('scene')!r:.60}")
    scene_path = Path(os.path.normpath(path.parent / data["scene"]))
    try:
        return data, scene_path, load_scene(scene_path)
    except SceneError as exc:
        raise error(f"{f}: `scene`: {exc}") from None


def load_study(path) -> StudyFile:
    """Read and check the study file at `path` and the scene it names (built once with its
    own parameters, so that measures naming a missing joint, driver or coordinate are
    errors here); a StudyError names the file, the table and the key."""
    path = Path(path)
    f = path.name
    data, scene_path, base = read_with_scene(path, _TOP, "a study", StudyError)
    declared = {k for k in read_toml(scene_path).get("parameters", {})}
    grid = _grid(f, data.get("vary", {}), declared)
    measures = _measures(f, data.get("measure", []), base.mechanism)
    samples = _count(f, data, "samples")
    if samples is not None and not any(hasattr(v, "rvs") for v in grid.values()):
        raise StudyError(f"{f}: `samples` is for [vary] distributions ({{ normal = [mean, sd] "
                         f"}} or {{ uniform = [low, high] }}); [vary] has none")
    if samples is None and any(hasattr(v, "rvs") for v in grid.values()):
        raise StudyError(f"{f}: [vary] has distributions: give `samples`, how many draws")
    seed = _count(f, data, "seed", low=0)
    workers = _count(f, data, "workers")
    output = data.get("output", f"out/{path.stem}.csv")
    if not isinstance(output, str) or PurePath(output).is_absolute() or \
            ".." in PurePath(output).parts or not output.endswith(".csv"):
        raise StudyError(f"{f}: `output` must be a relative path ending in .csv inside the "
                         f"working directory, got {output!r:.80}")
    return StudyFile(path, scene_path, grid, measures, samples, seed, workers, Path(output))


def _grid(f, vary, declared) -> dict:
    if not isinstance(vary, dict) or not vary:
        raise StudyError(f"{f}: [vary] must be a table of the scene's parameters to vary")
    from scipy import stats
    grid = {}
    for name, value in vary.items():
        where = f"{f}: [vary] {name}"
        if name not in declared:
            raise StudyError(f"{where}: the scene has no such parameter; its [parameters]: "
                             f"{', '.join(sorted(declared)) or '(none)'}")
        if isinstance(value, list):
            if not value:
                raise StudyError(f"{where}: the list of values is empty")
            grid[name] = [evaluate(v, {}, f"{where}[{i}]") for i, v in enumerate(value)]
        elif isinstance(value, dict):
            if len(value) != 1 or next(iter(value)) not in _DISTRIBUTIONS:
                raise StudyError(f"{where}: a distribution is {{ normal = [mean, sd] }} or "
                                 f"{{ uniform = [low, high] }}, got {value!r:.80}")
            kind, args = next(iter(value.items()))
            if not isinstance(args, list) or len(args) != 2:
                raise StudyError(f"{where}: {kind} takes [{', '.join(_DISTRIBUTIONS[kind])}]"
                                 f", got {args!r:.60}")
            a, b = (evaluate(v, {}, f"{where} {kind}") for v in args)
            if not b > (a if kind == "uniform" else 0.0):
                raise StudyError(f"{where}: {kind} needs {_DISTRIBUTIONS[kind][1]} > "
                                 f"{'low' if kind == 'uniform' else '0'}, got {b:g}")
            grid[name] = stats.norm(a, b) if kind == "normal" else stats.uniform(a, b - a)
        else:
            grid[name] = evaluate(value, {}, where)
    return grid


def _measures(f, tables, mech) -> list:
    if not isinstance(tables, list) or not tables or \
            not all(isinstance(t, dict) for t in tables):
        raise StudyError(f"{f}: a study needs [[measure]] tables (one of "
                         f"{', '.join(MEASURES)} each)")
    joints = [j.name for j in mech.joints]
    drivers = [d.name for d in mech.drivers]
    out = []
    for i, table in enumerate(tables):
        where = f"{f}: measure[{i}]"
        kinds = [k for k in table if k in MEASURES]
        extra = [k for k in table if k not in MEASURES and k != "name"]
        if len(kinds) != 1 or extra:
            raise StudyError(f"{where}: give exactly one of {', '.join(MEASURES)} (and "
                             f"optionally `name`); got {', '.join(table) or 'nothing'}")
        kind, subject = kinds[0], table[kinds[0]]
        known = joints if kind in JOINT_MEASURES else drivers if kind in DRIVER_MEASURES \
            else mech.coordinate_names
        if subject not in known:
            what = "joint" if kind in JOINT_MEASURES else "driver" if kind in \
                DRIVER_MEASURES else "coordinate"
            raise StudyError(f"{where}: {kind}: no {what} {subject!r:.60}; {what}s: "
                             f"{', '.join(known) or '(none)'}")
        column = table.get("name", f"{kind} {subject}")
        if not isinstance(column, str) or not column.strip() or \
                column in RESERVED or column in [c for c, _, _ in out]:
            raise StudyError(f"{where}: `name` must be a new column name, got {column!r:.60}")
        out.append((column, kind, subject))
    return out


def _count(f, data, key, low=1):
    value = data.get(key)
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, int) or value < low:
        raise StudyError(f"{f}: `{key}` must be a whole number ≥ {low}, got {value!r:.40}")
    return value


def write_table(study, path: Path) -> None:
    """The study's table as CSV (`Study.to_csv`)."""
    study.to_csv(path)


def summary(study) -> list[str]:
    """Lines describing each measure's distribution over the successful samples (mean,
    standard deviation, the 5th, 50th and 95th percentiles, the extremes) and the
    failures."""
    ok = study.table["status"] == "success"
    lines = [f"samples    {len(study)} in {study.wall_time:.2f} s; {int(ok.sum())} succeeded"]
    width = max((len(m) for m in study.measures), default=0)
    if study.measures:
        lines.append(f"{'':{width + 2}}{'mean':>12}{'std':>12}{'min':>12}{'p5':>12}"
                     f"{'p50':>12}{'p95':>12}{'max':>12}")
    for name in study.measures:
        x = study.table[name][ok]
        x = x[np.isfinite(x)]
        if not x.size:
            lines.append(f"  {name:{width}}  (no successful sample)")
            continue
        p5, p50, p95 = np.percentile(x, [5, 50, 95])
        values = (x.mean(), x.std(ddof=1) if x.size > 1 else 0.0, x.min(), p5, p50, p95,
                  x.max())
        lines.append(f"  {name:{width}}" + "".join(f"{v:12.6g}" for v in values))
    for i in study.failed[:4]:
        lines.append(f"failed     sample {i}: {study.table['status'][i]}: "
                     f"{study.table['message'][i]}")
    if len(study.failed) > 4:
        lines.append(f"failed     … and {len(study.failed) - 4} more (see the table)")
    return lines
