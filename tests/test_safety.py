"""Files and processes around the solver: nothing runs from the working directory, nothing is
written through links, no live memory map is truncated, compiled constants are exact, and
faults leave neither half-written files nor lost runs."""

import math
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import mechsim as ms
from conftest import seeded_cache
from test_cli import SCENE as CLI_SCENE

ROOT = Path(__file__).resolve().parents[1]


def test_a_background_build_never_imports_from_the_working_directory(tmp_path):
    """`mechsim run` in a directory holding a `json.py` (a module every build imports):
    the background build of the fused model runs in isolated mode in the cache directory,
    so the planted module never runs (before, its marker file appeared within seconds), and
    the build still lands in the cache."""
    work, cache = tmp_path / "work", tmp_path / "cache"
    work.mkdir()
    marker = tmp_path / "MARKER"
    for name in ("json.py", "numpy.py", "pickle.py"):
        (work / name).write_text(f"open({str(marker)!r}, 'w').write('ran')\n")
    scene = work / "scene.toml"
    scene.write_text((ROOT / "mechanisms" / "four_bar.toml").read_text())
    env = {**os.environ, "MECHSIM_CACHE_DIR": str(seeded_cache(cache)), "MECHSIM_BUILD": "auto",
           "MECHSIM_BACKGROUND": "1"}
    done = subprocess.run([sys.executable, "-P", "-m", "mechsim.app.cli", "run", scene.name,
                           "--t-end", "0.05", "--quiet", "--out", str(tmp_path / "out")],
                          cwd=work, env=env, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    deadline = time.monotonic() + 120
    while not list(cache.glob("*.evaluations-*.so")) and time.monotonic() < deadline:
        time.sleep(0.5)
    assert list(cache.glob("*.evaluations-*.so")), "the background build did not finish"
    assert not marker.exists()


LAW = "t*cos(5**30) + 12345678901234567890123*t/12345678901234567890123 + 1e-3*3**40*t/3**40"


def test_every_build_agrees_on_laws_with_huge_and_tiny_constants():
    """Integer constants beyond 2⁶⁴ in a driver's law: C read them as integer literals that
    overflow, so the compiled model turned cos(5**30) into −0.49820 where Python has
    0.27471, both reported as success. The law's constants are folded to doubles at parsing
    and the C printer writes long integers as doubles: the compiled, the Python and the
    assembled models all follow the law to round-off."""
    from mechsim.codegen import engine
    exact = math.cos(float(5 ** 30)) + 1.0 + 1e-3
    angles = {}
    for build in ("fused", "assembled"):
        mech = ms.Mechanism("pendulum")
        rod = mech.add(ms.RigidBody.rod("rod", (0, 0), (1, 0), 1.0))
        pin = mech.add(ms.Revolute(mech.ground, rod, at=(0, 0), name="O"))
        mech.add(ms.Driver(pin, LAW, name="motor"))
        mech.problem(build=build)
        res = mech.simulate(1.0, output_step=0.5)
        assert res.status == "success", res.message
        angles[build] = res.coordinate("rod.angle")[-1]
        if build == "fused":
            assert engine.library(res.problem.model) is not None
            with engine.python_path(res.problem.model):
                angles["python"] = mech.simulate(1.0, output_step=0.5).coordinate("rod.angle")[-1]
    for build, angle in angles.items():
        assert abs(angle - exact) < 1e-12, (build, angles, exact)


def test_the_generated_code_writes_long_integers_as_doubles():
    """The printer of the text Python and C share (`neutral_printer`)."""
    import sympy as sp
    from mechsim.codegen.printer import neutral_printer
    t = sp.Symbol("t")
    printer = neutral_printer({t: "t"})
    assert printer.doprint(sp.Integer(5) ** 30 * t) == f"{float(5 ** 30)!r}*t"
    assert printer.doprint(sp.Integer(2) ** 53 + t) == f"t + {2 ** 53}"


# --- streams -----------------------------------------------------------------------------------
def falling_four_bar_run(stream, t_end=0.5, **kw):
    return ms.examples.four_bar().simulate(t_end, output_step=1e-4, stream=stream, **kw)


def test_a_stream_is_never_written_through_a_link(tmp_path):
    """A `meta.json` (or `samples.bin`) planted in a stream directory as a link to another
    file: the stream replaces the link with its own file and the other file is untouched
    (before, it was overwritten). A stream directory that is itself a link is refused."""
    victim = tmp_path / "victim.txt"
    victim.write_text("precious")
    run = tmp_path / "run"
    run.mkdir()
    for name in ("meta.json", "samples.bin", "work.bin"):
        (run / name).symlink_to(victim)
    res = falling_four_bar_run(run, t_end=0.05)
    assert res.status == "success" and victim.read_text() == "precious"
    assert not any((run / name).is_symlink() for name in ("meta.json", "samples.bin"))
    assert ms.load_result(run).t.size == res.t.size
    (tmp_path / "link").symlink_to(run)
    with pytest.raises(ValueError, match="symbolic link"):
        falling_four_bar_run(tmp_path / "link", t_end=0.05)


def test_a_new_stream_leaves_an_earlier_results_memory_map_alive(tmp_path):
    """A second run streamed into the directory of a first whose result (memory-mapped) is
    still alive: before, the new run truncated samples.bin under the live map and the next
    read died with SIGBUS. The new stream writes new files; the old map keeps its data."""
    first = falling_four_bar_run(tmp_path / "run", t_end=0.5)
    last = np.array(first.q[-1])
    loaded = ms.load_result(tmp_path / "run")
    second = falling_four_bar_run(tmp_path / "run", t_end=0.05)
    np.testing.assert_array_equal(first.q[-1], last)
    np.testing.assert_array_equal(loaded.q[-1], last)
    again = ms.load_result(tmp_path / "run")
    assert again.t.size == second.t.size < first.t.size


_LONG_STREAM = """
import sys, mechsim as ms
ms.examples.four_bar().simulate(100.0, output_step=1e-4, stream=sys.argv[1])
"""


def test_a_killed_stream_loads_as_partial(tmp_path):
    """A streamed run killed (SIGKILL) on the way: its directory loads with status
    "partial", the samples whole on disk, and a message saying the run did not finish
    (before: FileNotFoundError on meta.json, or the earlier stream's meta.json with the new
    samples)."""
    run = tmp_path / "run"
    falling_four_bar_run(run, t_end=0.05)                 # an earlier, finished stream
    child = subprocess.Popen([sys.executable, "-c", _LONG_STREAM, str(run)],
                             env={**os.environ, "MECHSIM_BACKGROUND": "0"})
    try:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            samples = run / "samples.bin"
            if samples.exists() and samples.stat().st_size > 3 * 4096 * 8 * 19:
                break
            time.sleep(0.2)
    finally:
        child.kill()
        child.wait()
    res = ms.load_result(run)
    assert res.status == "partial" and "did not finish" in res.message
    assert res.t.size >= 3 * 4096 and np.all(np.diff(res.t) > 0)
    np.testing.assert_allclose(np.diff(res.t), 1e-4, rtol=1e-9)
    assert np.abs(res.q).max() < 10.0                  # real states, not garbage


def test_load_result_checks_a_stream_against_its_files(tmp_path):
    import json
    run = tmp_path / "run"
    res = falling_four_bar_run(run, t_end=0.05)
    meta = json.loads((run / "meta.json").read_text())
    (run / "meta.json").write_text(json.dumps({**meta, "samples": meta["samples"] + 7}))
    with pytest.raises(ValueError, match=f"says {res.t.size + 7} samples, samples.bin holds "
                                         f"{res.t.size}"):
        ms.load_result(run)
    (run / "meta.json").write_text(json.dumps({**meta, "width": 5}))
    with pytest.raises(ValueError, match="rows of 5 numbers for 9 coordinates"):
        ms.load_result(run)
    (run / "meta.json").unlink()
    with pytest.raises(ValueError, match="no meta.json"):
        ms.load_result(run)


def test_a_full_disk_while_streaming_ends_the_run_keeping_its_samples(tmp_path, monkeypatch):
    """A write of the stream fails (ENOSPC, simulated after 200 kB): before, OSError
    escaped `simulate()` and the run was lost. The run ends failed, saying so, with every
    sample it computed: those on disk and those after in memory."""
    import errno
    import mechsim.files as files
    real = files.OutputDirectory.new_file

    class Full:
        def __init__(self, f):
            self.f, self.written = f, 0

        def write(self, data):
            if self.written + len(data) > 200_000:
                raise OSError(errno.ENOSPC, "No space left on device")
            self.written += len(data)
            return self.f.write(data)

        def __getattr__(self, name):
            return getattr(self.f, name)

    monkeypatch.setattr(files.OutputDirectory, "new_file",
                        lambda self, name: Full(real(self, name)))
    res = falling_four_bar_run(tmp_path / "run", t_end=0.5)
    assert res.status == "failed" and "writing the stream failed" in res.message
    assert "No space left on device" in res.message
    assert res.t.size > 200_000 // (8 * 19) and np.all(np.diff(res.t) > 0)
    reference = ms.examples.four_bar().simulate(res.t[-1], output_step=1e-4)
    np.testing.assert_allclose(res.q, reference.q[:res.t.size], atol=1e-9)


# --- the command line's outputs ----------------------------------------------------------------
# test_cli's pendulum, half as long, with a plot.
SCENE = CLI_SCENE.replace("t_end = 1.0", "t_end = 0.5").replace(
    "save = true", 'save = true\nplots = ["energy"]')


def _cli(capsys, *argv):
    from mechsim.app.cli import main
    code = main(["run", *map(str, argv)])
    out = capsys.readouterr()
    return code, out.out, out.err


@pytest.fixture
def pendulum_scene(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    path = tmp_path / "pendulum.toml"
    path.write_text(SCENE)
    return path


def test_an_output_directory_that_is_a_link_or_a_file_is_refused_before_the_run(
        pendulum_scene, tmp_path, capsys, monkeypatch):
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    (tmp_path / "out").symlink_to(elsewhere)
    ran = []
    monkeypatch.setattr(ms.Mechanism, "simulate", lambda *a, **k: ran.append(1))
    code, _, err = _cli(capsys, pendulum_scene, "--out", tmp_path / "out")
    assert code == 2 and "is a symbolic link" in err and not ran
    assert list(elsewhere.iterdir()) == []
    (tmp_path / "file").write_text("x")
    code, _, err = _cli(capsys, pendulum_scene, "--out", tmp_path / "file")
    assert code == 2 and "is not a directory" in err and not ran


def test_outputs_are_never_written_through_a_planted_link(pendulum_scene, tmp_path, capsys,
                                                          monkeypatch):
    """A link planted in the output directory where the plot goes, during the run (after
    the up-front check, which refuses a link already there): the link is replaced by the
    file (renamed into place), its target untouched. The same for the output directory
    swapped for a link during the run: mechsim holds the directory open and writes into
    it, not through the new link."""
    import mechsim.app.cli as cli
    out, moved = tmp_path / "out", tmp_path / "out-moved"
    victim, elsewhere = tmp_path / "victim", tmp_path / "elsewhere"
    victim.write_text("precious")
    elsewhere.mkdir()
    summary = cli._summary

    def plant(scene, res):
        (out / "pendulum_energy.png").symlink_to(victim)
        summary(scene, res)
    monkeypatch.setattr(cli, "_summary", plant)
    code, _, err = _cli(capsys, pendulum_scene, "--out", out)
    assert code == 0, err
    assert victim.read_text() == "precious" and not (out / "pendulum_energy.png").is_symlink()
    assert sorted(p.name for p in out.iterdir()) == ["pendulum.npz", "pendulum_energy.png"]
    assert ms.load_result(out / "pendulum.npz").t.size == 51

    from mechsim.files import OutputDirectory
    directory = OutputDirectory(tmp_path / "held")
    (tmp_path / "held").rename(moved)
    (tmp_path / "held").symlink_to(elsewhere)
    directory.write_text("a.txt", "inside")
    with directory.staged() as staged:
        (staged / "b.png").write_bytes(b"png")
    assert list(elsewhere.iterdir()) == [] and sorted(p.name for p in moved.iterdir()) == \
        ["a.txt", "b.png"]


def test_an_interrupt_after_the_run_keeps_the_saved_result(pendulum_scene, capsys, monkeypatch):
    """Ctrl-C (or SIGTERM, taken as Ctrl-C) during the summary after a finished run: the
    result was saved first (before, plots came first and the result was lost)."""
    import signal
    import mechsim.app.cli as cli

    def summary(scene, res):
        os.kill(os.getpid(), signal.SIGTERM)
    monkeypatch.setattr(cli, "_summary", summary)
    code, _, err = _cli(capsys, pendulum_scene)
    assert code == 130 and "interrupted during the summary" in err and "pendulum.npz" in err
    res = ms.load_result(pendulum_scene.parent / "out" / "pendulum" / "pendulum.npz")
    assert res.status == "success" and res.t[-1] == 0.5
    assert signal.getsignal(signal.SIGTERM) is not None          # restored after the run


# --- sweeps --------------------------------------------------------------------------------------
def test_a_sweep_over_driver_speeds_compiles_one_model(monkeypatch):
    """25 crank speeds from np.linspace (numpy scalars, which once failed as "unknown
    function 'np.float64'"): the driver's law keeps its numbers as parameters of the
    compiled model, so all 25 mechanisms have one structure and at most one fused model is
    generated (before: 25 sympy and gcc builds, 41 s cold), and each run follows its own
    speed exactly."""
    from mechsim.build import background
    from mechsim.codegen.cache import structure_key
    monkeypatch.setenv("MECHSIM_BUILD", "fused")
    speeds = np.linspace(20.0, 140.0, 25)
    keys, generated = set(), []
    source = background.fused_source
    monkeypatch.setattr(background, "fused_source",
                        lambda *a: generated.append(1) or source(*a))

    def build(crank_speed):
        mech = ms.examples.slider_crank(driven=True, crank_speed=crank_speed)
        keys.add(structure_key(mech.structure()))
        return mech

    def measure(res):
        crank = res.coordinate("crank.angle")
        return {"rate": float((crank[-1] - crank[0]) / (res.t[-1] - res.t[0]))}
    study = ms.sweep(build, {"crank_speed": speeds},
                     simulate=dict(t_end=0.05, output_step=0.01), measure=measure, workers=1)
    assert list(study.table["status"]) == ["success"] * 25
    np.testing.assert_allclose(study.table["rate"], speeds, rtol=1e-9)
    assert len(keys) == 1 and len(generated) <= 1


def test_names_with_math_markup_are_drawn_as_written(tmp_path):
    """A `$` in a user's name was read as matplotlib math markup: `rod $\\frac$` broke every
    plot after the run. Every text of mechsim's figures is drawn as written."""
    mech = ms.Mechanism("cost $x^$")
    rod = mech.add(ms.RigidBody.rod("rod $\\frac$", (0, 0), (1, 0), 1.0))
    mech.add(ms.Revolute(mech.ground, rod, at=(0, 0), name="pin $_$"))
    res = mech.simulate(0.3, output_step=0.01)
    res.plot_energy(tmp_path / "e.png")
    res.plot_reactions(tmp_path / "r.png")
    res.plot(tmp_path / "p.png", coordinates=["rod $\\frac$.angle"])
    fig = res.plot_motion(tmp_path / "m.png")
    res.animate(tmp_path / "a.gif", fps=5)
    assert fig.axes[0].get_title().startswith("cost $x^$")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.gif", "e.png", "m.png", "p.png",
                                                          "r.png"]


def test_an_unreachable_dask_scheduler_is_said_plainly(tmp_path, capsys, monkeypatch):
    pytest.importorskip("distributed")
    import distributed
    from mechsim.app.cli import main

    def refuse(address, timeout=None):
        raise OSError(f"Timed out trying to connect to {address} after 10 s")
    monkeypatch.setattr(distributed, "Client", refuse)
    study = ROOT / "mechanisms" / "studies" / "slider_crank_tolerances.toml"
    code = main(["sweep", str(study), "--scheduler", "tcp://127.0.0.1:1", "--quiet",
                 "--out", str(tmp_path / "t.csv")])
    err = capsys.readouterr().err
    assert code == 2 and "cannot reach the dask scheduler at 'tcp://127.0.0.1:1'" in err


def test_a_background_build_has_a_time_limit(tmp_path):
    """The background build's process limits its own processor time (a law of a hundred
    and fifty factors kept sympy busy for over five minutes with no limit): the child's
    entry point sets RLIMIT_CPU before it reads its payload."""
    import pickle
    pytest.importorskip("resource")
    from mechsim.build import background
    code = ("import resource, sys; from mechsim.build import background; "
            "background.build = lambda *a: print(resource.getrlimit(resource.RLIMIT_CPU), a); "
            "background.main()")
    done = subprocess.run([sys.executable, "-I", "-c", code], input=pickle.dumps((1, 2, 3)),
                          capture_output=True, cwd=tmp_path, timeout=60)
    assert done.returncode == 0, done.stderr
    limit = background.CPU_SECONDS
    assert done.stdout.decode().strip() == f"({limit}, {limit}) (1, 2, 3)"


def test_a_streamed_run_needs_memory_for_its_times_only(tmp_path, monkeypatch):
    """On a machine of 1 GiB, 1e7 samples of the four-bar (1.4 GiB in memory) are refused
    before the run; streamed, only their times stay in memory (76 MiB), and the run
    starts."""
    import mechsim.options as options
    monkeypatch.setattr(options, "machine_memory", lambda: 2.0 ** 30)
    with pytest.raises(ValueError, match="1e\\+07 samples of 9 coordinates.*GiB"):
        ms.examples.four_bar().simulate(1e3, output_step=1e-4, max_steps=10)
    res = ms.examples.four_bar().simulate(1e3, output_step=1e-4, max_steps=10,
                                          stream=tmp_path / "run")
    assert res.status == "failed" and "max_steps = 10" in res.message and res.t.size > 100
