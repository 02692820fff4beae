"""Code cache, results (save/load, plots) and the command line."""

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

import mechsim as ms
from conftest import mechanism_models, seeded_cache
from mechsim.app.cli import main

ROOT = Path(__file__).resolve().parents[1]
SCENES = ROOT / "mechanisms"

_PROBE = textwrap.dedent("""
    import json, sys
    import mechsim as ms
    scene = ms.load_scene(sys.argv[1])
    res = scene.simulate(t_end=0.05)
    print(json.dumps({"from_cache": scene.mechanism.from_cache,
                      "sympy": "sympy" in sys.modules, "status": res.status}))
""")


def _probe(scene, cache_dir):
    env = {**os.environ, "MECHSIM_CACHE_DIR": str(seeded_cache(cache_dir))}
    out = subprocess.run([sys.executable, "-c", _PROBE, str(scene)], env=env, check=True,
                         capture_output=True, text=True).stdout
    return json.loads(out.strip().splitlines()[-1])


# The flexible scene caches two modules besides its joint types' kernels: its constraint
# model and the 2-mode beam kernel.
@pytest.mark.parametrize("scene, modules", [("four_bar.toml", 1), ("flexible_four_bar.toml", 2)])
def test_second_run_is_served_from_the_cache_without_sympy(tmp_path, scene, modules):
    first = _probe(SCENES / scene, tmp_path)
    assert first == {"from_cache": False, "sympy": True, "status": "success"}
    second = _probe(SCENES / scene, tmp_path)
    assert second == {"from_cache": True, "sympy": False, "status": "success"}
    assert len(mechanism_models(tmp_path)) == modules


def test_import_is_light():
    code = ("import sys, mechsim; print(sorted(m for m in ('sympy', 'matplotlib', 'meshio', "
            "'scipy') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], check=True, capture_output=True, text=True)
    assert out.stdout.strip() == "[]"


def test_corrupt_cache_entry_is_rebuilt(tmp_path, monkeypatch):
    from mechsim.codegen import cache
    monkeypatch.setenv("MECHSIM_CACHE_DIR", str(seeded_cache(tmp_path)))
    cache.clear_memory_cache()
    mech = ms.examples.pendulum()
    mech.problem()
    (entry,) = mechanism_models(tmp_path)
    entry.write_text("this is not python")
    cache.clear_memory_cache()
    again = ms.examples.pendulum()
    with pytest.warns(UserWarning, match="does not match its digest"):
        again.problem()
    assert not again.from_cache
    assert np.allclose(again.problem().phi(again.initial_coordinates(), 0.0), 0.0)
    cache.clear_memory_cache()


def test_result_save_load_roundtrip(tmp_path):
    res = ms.examples.double_four_bar().simulate(t_end=0.2, rtol=1e-8, atol=1e-10,
                                                 output_step=0.02)
    path = res.save(tmp_path / "run.npz")
    back = ms.load_result(path)
    assert back.status == res.status and back.coordinate_names == res.coordinate_names
    np.testing.assert_array_equal(back.q, res.q)
    np.testing.assert_array_equal(back.energy.total, res.energy.total)
    np.testing.assert_array_equal(back.energy_drift, res.energy_drift)
    np.testing.assert_array_equal(back.constraint_violation, res.constraint_violation)
    np.testing.assert_array_equal(back.point("coupler1", (0.5, 0)), res.point("coupler1", (0.5, 0)))
    assert back.stats["steps"] == res.stats["steps"]


def test_point_velocity_is_the_derivative_of_point():
    res = ms.examples.double_four_bar().simulate(t_end=0.3, rtol=1e-10, atol=1e-12,
                                                 output_step=1e-3)
    p, v = res.point("coupler2", (0.3, 0.1)), res.point_velocity("coupler2", (0.3, 0.1))
    fd = (p[2:] - p[:-2]) / (2e-3)
    np.testing.assert_allclose(v[1:-1], fd, atol=1e-5)


def test_passage_drift_is_the_energy_change_across_each_passage():
    """`passage_drift`: the drift from the last sample before a passage to the first after
    it; a passage reaching past either end of the run takes the end sample."""
    from mechsim.results import EnergyLog, SimulationResult, SingularPassage

    t = np.linspace(0.0, 1.0, 11)
    kinetic = 1.0 + 0.01 * (t > 0.45) - 0.002 * (t > 0.95)     # jumps inside two passages
    res = SimulationResult(t, np.zeros((11, 1)), np.zeros((11, 1)), ["x"],
                           energy=EnergyLog(kinetic, np.zeros(11), np.zeros(11)),
                           singular_passages=[SingularPassage(0.42, 0.48, 1e-6),
                                              SingularPassage(0.7, 0.8, 1e-6),
                                              SingularPassage(-0.1, 0.05, 1e-6),
                                              SingularPassage(0.92, 1.3, 1e-6)])
    np.testing.assert_allclose(res.passage_drift(), [0.01 / 1.01, 0.0, 0.0, -0.002 / 1.01],
                               atol=1e-15)


def test_energy_plot_is_written(tmp_path):
    res = ms.examples.pendulum().simulate(t_end=0.5, output_step=0.01)
    fig = res.plot_energy(path=tmp_path / "e.png")
    assert (tmp_path / "e.png").stat().st_size > 5000
    assert fig.axes[-1].get_xlabel() == "time [s]" and fig.axes[0].get_ylabel() == "energy [J]"


def test_scene_and_factory_build_the_same_four_bar():
    scene = ms.load_scene(SCENES / "four_bar.toml")
    factory = ms.examples.four_bar()
    np.testing.assert_allclose(scene.mechanism.initial_coordinates(),
                               factory.initial_coordinates(), atol=1e-15)
    a = scene.mechanism.simulate(t_end=0.1, rtol=1e-9, atol=1e-11, output_step=0.01)
    b = factory.simulate(t_end=0.1, rtol=1e-9, atol=1e-11, output_step=0.01)
    np.testing.assert_allclose(a.q, b.q, atol=1e-12)


@pytest.mark.parametrize("scene", ["four_bar", "double_four_bar", "slider_crank"])
def test_cli_runs_each_shipped_scene(scene, tmp_path, capsys):
    assert main(["run", str(SCENES / f"{scene}.toml"), "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "1 degree(s) of freedom" in out and "status     success" in out
    assert (tmp_path / f"{scene}_energy.png").exists() and (tmp_path / f"{scene}.npz").exists()
    res = ms.load_result(tmp_path / f"{scene}.npz")
    assert np.max(np.abs(res.energy_drift)) < 1e-6


def test_cli_bench_coulomb_writes_its_table(tmp_path, capsys):
    """`mechsim bench coulomb`: one row per case and accuracy, CSV and plot written; a bad
    accuracy list is an error naming it."""
    assert main(["bench", "coulomb", "--accuracies", "1e-6", "--repeat", "1",
                 "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    rows = [line for line in out.splitlines() if line.strip().startswith(("0.07", "0.08", "0.09"))]
    assert len(rows) == 6 and all(line.endswith("×") for line in rows)
    assert (tmp_path / "bench_coulomb.csv").exists() and (tmp_path / "bench_coulomb.png").exists()
    assert main(["bench", "coulomb", "--accuracies", "fine", "--out", str(tmp_path)]) == 2
    assert "`--accuracies` takes comma-separated positive numbers, got 'fine'" in capsys.readouterr().err


def test_cli_reports_bad_scene(tmp_path, capsys):
    bad = tmp_path / "x.toml"
    bad.write_text("[simulation]\nt_end = 1\n[[body]]\nname = 'a'\n")
    assert main(["run", str(bad)]) == 2
    assert "needs `mass`" in capsys.readouterr().err


def test_a_large_model_runs_compiled_c_twins_of_its_kernels(tmp_path, monkeypatch, rng):
    """The ten-window chain (63 coordinates) carries C twins of its generated functions,
    compiled into the cache next to the module: they agree with the Python functions to
    round-off. Without a working compiler the Python functions serve, with equal results."""
    import shutil
    import sysconfig
    from mechsim.codegen import cache

    if shutil.which((os.environ.get("CC") or sysconfig.get_config_var("CC") or "cc").split()[0]) is None:
        pytest.skip("no C compiler on this machine")
    monkeypatch.setenv("MECHSIM_CACHE_DIR", str(tmp_path))
    monkeypatch.delenv("MECHSIM_NO_COMPILE", raising=False)
    cache.clear_memory_cache()
    mech = ms.examples.double_four_bar(10)
    model = mech.problem().model
    assert model.COMPILED and len(list(tmp_path.glob("mechsim_model_*.so"))) == 1
    p = mech.problem().p
    for _ in range(3):
        q, v = rng.normal(size=model.N), rng.normal(size=model.N)
        for name, args in [("phi", (q, 0.3, p)), ("phi_q", (q, 0.3, p)),
                           ("position_terms", (q, 0.3, p)), ("gamma", (q, v, 0.3, p)),
                           ("dynamics_terms", (q, v, 0.3, p)), ("terms", (q, v, 0.3, p))]:
            fast, slow = getattr(model, name)(*args), model.PYTHON_KERNELS[name](*args)
            for a, b in zip(*(x if isinstance(x, tuple) else (x,) for x in (fast, slow))):
                np.testing.assert_allclose(a, b, rtol=1e-13, atol=1e-13 * (1 + np.abs(b).max()))
    # The twins copy their inputs into kept buffers: a strided view and a list are read
    # as their values, and threads calling at once each get their own state's answer.
    Q = rng.normal(size=(model.N, 8))
    expected = [model.PYTHON_KERNELS["gamma"](Q[:, k], Q[::-1, k], 0.3, p) for k in range(8)]
    np.testing.assert_allclose(model.gamma(list(Q[:, 0]), Q[::-1, 0], 0.3, p), expected[0],
                               rtol=1e-13, atol=1e-13 * (1 + np.abs(expected[0]).max()))
    from concurrent.futures import ThreadPoolExecutor
    with ThreadPoolExecutor(4) as pool:
        got = list(pool.map(lambda k: [model.gamma(Q[:, k], Q[::-1, k], 0.3, p)
                                       for _ in range(200)], range(8)))
    for answers, b in zip(got, expected):
        for a in answers:
            np.testing.assert_allclose(a, b, rtol=1e-13, atol=1e-13 * (1 + np.abs(b).max()))
    # The same cache entry without its library, and no compiler: the Python functions.
    (library,) = tmp_path.glob("mechsim_model_*.so")
    library.unlink()
    monkeypatch.setenv("CC", str(tmp_path / "no-such-compiler"))
    cache.clear_memory_cache()
    fallback, from_cache = cache.load_model(mech.structure(), lambda: "not used")
    assert from_cache and not fallback.COMPILED and not list(tmp_path.glob("*.so"))
    np.testing.assert_allclose(fallback.dynamics_terms(q, v, 0.3, p)[0],
                               model.dynamics_terms(q, v, 0.3, p)[0], rtol=0, atol=1e-13)
