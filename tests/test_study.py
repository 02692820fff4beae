"""Parameter studies (`ms.sweep`): the same table serially, on the local process pool and on
a dask.distributed LocalCluster; measures against the closed forms; failing samples
recorded; one compiled model for the whole study; the parameter sets of grids and Monte
Carlo tables; bad arguments."""

import csv
import math
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy import stats

import mechsim as ms
from conftest import mechanism_models, seeded_cache
from mechsim import examples
from mechsim.codegen import cache
from mechsim.study import parameter_sets

SPEED, T_END = 100.0, 0.05
GRID = {"crank_length": [0.1, 0.15, 0.35], "rod_length": [0.3, 0.4]}


def slider(crank_length, rod_length):
    return examples.slider_crank(crank_length=crank_length, rod_length=rod_length,
                                 driven=True, crank_speed=SPEED)


def slider_end(res):
    x = res.q[:, res.coordinate_names.index("slider.x")]
    return {"x_end": x[-1], "x_max": x.max()}


SIMULATE = dict(t_end=T_END, output_step=T_END / 50, rtol=1e-10, atol=1e-12)


def _check_against_closed_form(study):
    """Every buildable sample's slider position is r cos θ + √(l² − r² sin² θ), θ = ω t; the
    crank longer than the rod fails in `build`, with the factory's message."""
    table = study.table
    assert list(table["crank_length"]) == [0.1, 0.1, 0.15, 0.15, 0.35, 0.35]
    for i in range(len(study)):
        r, l = table["crank_length"][i], table["rod_length"][i]
        if r >= l:
            assert table["status"][i] == "failed"
            assert table["message"][i].startswith("build: ValueError: slider-crank: crank")
            assert np.isnan(table["x_end"][i])
            continue
        assert table["status"][i] == "success"
        exact = examples.slider_crank_position(SPEED * T_END, r, l)
        assert abs(table["x_end"][i] - exact) < 1e-8
        assert abs(table["x_max"][i] - (r + l)) < 1e-8
    assert list(study.failed) == [4]


def test_sweep_serial_pool_and_dask_give_the_same_table():
    distributed = pytest.importorskip("distributed")
    import cloudpickle
    cloudpickle.register_pickle_by_value(sys.modules[__name__])
    serial = ms.sweep(slider, GRID, simulate=SIMULATE, measure=slider_end, workers=1)
    _check_against_closed_form(serial)
    pool = ms.sweep(slider, GRID, simulate=SIMULATE, measure=slider_end, workers=2)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster, \
            distributed.Client(cluster) as client:
        on_dask = ms.sweep(slider, GRID, simulate=SIMULATE, measure=slider_end,
                           client=client)
    for other in (pool, on_dask):
        assert set(other.table) == set(serial.table)
        for name in ("crank_length", "rod_length", "x_end", "x_max"):
            assert np.array_equal(other.table[name], serial.table[name], equal_nan=True)
        assert list(other.table["status"]) == list(serial.table["status"])
        assert list(other.table["message"]) == list(serial.table["message"])


def test_one_compiled_model_serves_the_whole_study(tmp_path, monkeypatch):
    """In a fresh cache, the first sample's fused model is built once before dispatch and
    every sample (on two worker processes) loads it: each reports its model came from
    the cache. Linearized about the hanging equilibrium, a rod pinned at its end swings
    at √(3g/(2L)) for every length."""
    monkeypatch.setenv("MECHSIM_CACHE_DIR", str(seeded_cache(tmp_path)))
    cache.clear_memory_cache()

    def modes(mech):
        lin = mech.linearize()
        return mech.from_cache, lin.frequencies[0]

    lengths = [0.3, 0.5, 0.8, 1.3, 2.1]
    study = ms.sweep(lambda length: examples.pendulum(length=length, angle=-math.pi / 2),
                     {"length": lengths}, analyse=modes,
                     measure=lambda out: {"cached": out[0], "omega": out[1]}, workers=2)
    assert list(study.table["status"]) == ["success"] * 5
    assert list(study.table["cached"]) == [1.0] * 5
    assert np.allclose(study.table["omega"], np.sqrt(3 * 9.81 / (2 * np.array(lengths))),
                       rtol=1e-8)
    assert len(mechanism_models(tmp_path)) == 1


def _four_bar(case):
    """The four-bar, with a crank torque that turns NaN at t = 0.02 for case "nan"."""
    if case == "build":
        raise ms.ModelError("no such mechanism")
    mech = examples.four_bar()
    if case == "nan":
        mech.add(ms.Torque(mech.bodies[0], lambda t: 1.0 if t < 0.02 else math.nan))
    mech.case = case
    return mech


def _measure(out):
    case, res = out
    if case == "list":
        return [res.q[-1, 2]]
    return {"angle": "high" if case == "text" else res.q[-1, 2], "t_last": res.t[-1]}


def test_failures_of_every_stage_are_recorded(capsys):
    """A build, a measure and a measure's value that fail are recorded with their stage;
    a run that fails part-way keeps its status and message with the measures of its
    partial result; the others succeed; a progress bar counts the samples."""
    cases = ["build", "fine", "list", "text", "nan"]
    study = ms.sweep(_four_bar, {"case": cases},
                     analyse=lambda mech: (mech.case, mech.simulate(t_end=0.05)),
                     measure=_measure, workers=1, progress=True)
    status, message = list(study.table["status"]), list(study.table["message"])
    assert status == ["failed", "success", "failed", "failed", "failed"]
    assert message[0] == "build: ModelError: no such mechanism"
    assert message[2].startswith("measure: TypeError: `measure` must return a dict")
    assert "for 'angle'; expected a number" in message[3]
    assert "returned nan at t = 0.02" in message[4]
    assert np.isnan(study.table["angle"][[0, 2, 3]]).all()
    assert study.table["t_last"][1] == 0.05
    assert 0.0 < study.table["t_last"][4] <= 0.02           # the partial result ends early
    assert list(study.failed) == [0, 2, 3, 4]
    assert "5/5" in capsys.readouterr().err


def test_parameter_sets_factorial_monte_carlo_and_lists():
    assert parameter_sets({"a": [1, 2], "b": [10, 20, 30], "c": 5.0}) == [
        {"c": 5.0, "a": a, "b": b} for a in (1, 2) for b in (10, 20, 30)]
    assert list(parameter_sets({"m": [1, 2], "r": stats.uniform(0, 1), "k": 3.0},
                               samples=2)[0]) == ["m", "r", "k"]       # the table's order
    assert parameter_sets([{"a": 1}, {"a": 2, "b": 3}]) == [{"a": 1}, {"a": 2, "b": 3}]
    sets = parameter_sets({"r": stats.norm(0.15, 1e-3), "speed": [50.0, 100.0]}, samples=400,
                          seed=3)
    assert len(sets) == 800
    draws = np.array([s["r"] for s in sets if s["speed"] == 50.0])
    assert np.array_equal(draws, [s["r"] for s in sets if s["speed"] == 100.0])
    assert abs(draws.mean() - 0.15) < 4 * 1e-3 / math.sqrt(400)
    assert abs(draws.std() / 1e-3 - 1.0) < 0.15
    again = parameter_sets({"r": stats.norm(0.15, 1e-3), "speed": [50.0, 100.0]}, samples=400,
                           seed=3)
    assert again == sets


@pytest.mark.parametrize("kwargs, message", [
    (dict(build=5, grid={"a": [1]}), "`build` must be a function"),
    (dict(grid={"a": stats.norm()}), "need `samples`"),
    (dict(grid={"a": [1]}, samples=3), "`samples` is for grids with distributions"),
    (dict(grid={"status": [1]}), "'status' is a column of every study"),
    (dict(grid={"a b": [1]}), "parameter names must be identifiers"),
    (dict(grid={"a": []}), "grid 'a' has no values"),
    (dict(grid="a=1"), "`grid` must be a dict"),
    (dict(grid={"a": [1]}, simulate=dict(t_end=1), analyse=len), "not both"),
    (dict(grid={"a": [1]}, workers=0), "`workers` must be a count"),
    (dict(grid={"a": [1]}, measure="peak"), "`measure` must be a function"),
])
def test_bad_study_arguments_fail_before_any_sample(kwargs, message):
    def build(**_):
        raise AssertionError("no sample may run")
    with pytest.raises(ms.ModelError, match=message):
        ms.sweep(**{"build": build, **kwargs})


# --- study files and `mechsim sweep` -------------------------------------------------------------
SCENE = Path(__file__).resolve().parents[1] / "mechanisms" / "driven_slider_crank.toml"
STUDY = f"""
scene = "{SCENE}"
samples = 6
seed = 2

[vary]
r = {{ normal = [0.05, 0.0005] }}
m_rod = {{ uniform = [0.5, 0.7] }}
w = ["2*pi*25", "2*pi*50"]

[[measure]]
name = "stroke"
range = "piston.x"

[[measure]]
peak_effort = "motor"
"""


def test_sweep_command_runs_a_study_file(tmp_path, capsys):
    """`mechsim sweep` writes the table and summarises it: 12 samples (6 draws × 2 speeds,
    the same draws at each speed); the piston's stroke is 2r in each (at 1500 and 3000 rpm
    the output grid holds both dead centres), and the motor's peak torque grows with
    speed."""
    from mechsim.app.cli import main
    study = tmp_path / "study.toml"
    study.write_text(STUDY)
    out = tmp_path / "table.csv"
    assert main(["sweep", str(study), "--out", str(out), "--workers", "2"]) == 0
    printed = capsys.readouterr().out
    assert "samples    12 in" in printed and "12 succeeded" in printed
    assert "peak_effort motor" in printed and f"wrote {out}" in printed
    with open(out) as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 12 and all(r["status"] == "success" for r in rows)
    for r in rows:
        assert abs(float(r["stroke"]) - 2 * float(r["r"])) < 1e-8
    slow, fast = rows[:6], rows[6:]
    assert [r["r"] for r in slow] == [r["r"] for r in fast]
    assert all(float(b["peak_effort motor"]) > float(a["peak_effort motor"])
               for a, b in zip(slow, fast))


@pytest.mark.parametrize("edit, message", [
    (("samples = 6", "samples = 6\nthreads = 2"), "unknown top-level key(s) 'threads'"),
    (("r = {", "radius = {"), "[vary] radius: the scene has no such parameter"),
    (("normal = [0.05, 0.0005]", "normal = [0.05, -1]"), "normal needs standard deviation > 0"),
    (("normal = [0.05, 0.0005]", "gauss = [0.05, 1]"), "a distribution is { normal"),
    (('range = "piston.x"', 'range = "piston.z"'), "range: no coordinate 'piston.z'"),
    (('peak_effort = "motor"', 'peak_effort = "pump"'), "no driver 'pump'; drivers: motor"),
    (('peak_effort = "motor"', 'peak_force = "motor"'), "no joint 'motor'"),
    (("samples = 6\n", ""), "give `samples`"),
    (("r = { normal = [0.05, 0.0005] }\nm_rod = { uniform = [0.5, 0.7] }\n", ""),
     "`samples` is for [vary] distributions"),
    (('name = "stroke"', 'name = "status"'), "`name` must be a new column name"),
    (('w = ["2*pi*25", "2*pi*50"]', 'w = ["__import__(\'os\')"]'), "unknown function '__import__'"),
])
def test_bad_study_files_are_refused_before_any_sample(tmp_path, capsys, edit, message):
    from mechsim.app.cli import main
    study = tmp_path / "study.toml"
    old, new = edit
    assert old in STUDY
    study.write_text(STUDY.replace(old, new))
    assert main(["sweep", str(study), "--out", str(tmp_path / "t.csv")]) == 2
    assert message in capsys.readouterr().err
    assert not (tmp_path / "t.csv").exists()
