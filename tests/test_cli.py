"""The command line's options change what `mechsim run` does, each checked against the same
run made through the API."""

import re
import textwrap

import numpy as np
import pytest

import mechsim as ms
from mechsim.app.cli import main

SCENE = textwrap.dedent("""
    name = "pendulum"
    [[body]]
    name = "rod"
    rod = [[0, 0], [1, 0]]
    mass = 1.0
    [[joint]]
    type = "revolute"
    name = "pin"
    bodies = ["ground", "rod"]
    at = [0, 0]
    [simulation]
    t_end = 1.0
    rtol = 1e-8
    atol = 1e-10
    output_step = 0.01
    [output]
    save = true
""")


@pytest.fixture
def scene(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    path = tmp_path / "pendulum.toml"
    path.write_text(SCENE)
    return path


def run(capsys, *argv):
    code = main(["run", *map(str, argv)])
    out = capsys.readouterr()
    return code, out.out, out.err


def steps(out) -> int:
    return int(re.search(r"(\d+) steps", out).group(1))


def api(**settings):
    return ms.load_scene("pendulum.toml").simulate(**settings)


def test_version(capsys):
    with pytest.raises(SystemExit) as done:
        main(["--version"])
    assert done.value.code == 0
    assert capsys.readouterr().out.strip() == f"mechsim {ms.__version__}"


def test_quiet_prints_only_errors(scene, capsys):
    code, out, err = run(capsys, scene, "--quiet")
    assert code == 0 and out == "" and err == ""
    assert (scene.parent / "out" / "pendulum" / "pendulum.npz").exists()
    code, out, err = run(capsys, scene, "--quiet", "--rtol", "-1")
    assert code == 2 and out == "" and "`rtol` must be" in err


@pytest.mark.parametrize("option, value, setting", [
    ("--rtol", 1e-4, "rtol"), ("--atol", 1e-3, "atol"), ("--max-step", 0.002, "max_step"),
])
def test_tolerances_and_max_step(scene, capsys, option, value, setting):
    code, out, _ = run(capsys, scene, option, value)
    assert code == 0
    assert steps(out) == api(**{setting: value}).stats["steps"] != api().stats["steps"]


def test_output_step(scene, capsys):
    code, out, _ = run(capsys, scene, "--output-step", 0.25)
    assert code == 0 and "5 samples" in out


def test_integrator_and_fixed_step(scene, capsys):
    code, out, _ = run(capsys, scene, "--integrator", "Radau")
    assert code == 0 and "hybrid / Radau" in out
    code, out, _ = run(capsys, scene, "--method", "ss-newmark", "--fixed-step", 0.01)
    assert code == 0 and steps(out) == 100
    res = ms.load_result("out/pendulum/pendulum.npz")
    ref = api(method="ss-newmark", h=0.01)
    np.testing.assert_array_equal(res.q, ref.q)
    code, out, err = run(capsys, scene, "--integrator", "Radua")
    assert code == 2 and "did you mean 'Radau'" in err


def test_animate(scene, capsys):
    code, out, _ = run(capsys, scene, "--animate", "--output-step", 0.05)
    assert code == 0 and "pendulum.gif" in out
    from PIL import Image
    with Image.open(scene.parent / "out" / "pendulum" / "pendulum.gif") as im:
        assert im.n_frames == 21


def test_progress_bar_reports_simulated_time_and_changes_nothing(capsys):
    mech = ms.examples.pendulum()
    plain = mech.simulate(1.0, rtol=1e-8, output_step=0.1)
    shown = mech.simulate(1.0, rtol=1e-8, output_step=0.1, progress=True)
    err = capsys.readouterr().err
    assert "100%" in err and "t = 1 of 1 s" in err
    np.testing.assert_array_equal(shown.q, plain.q)


def test_progress_without_tqdm_warns_and_runs(monkeypatch):
    import sys
    monkeypatch.setitem(sys.modules, "tqdm.auto", None)       # as if not installed
    with pytest.warns(UserWarning, match="needs tqdm"):
        res = ms.examples.pendulum().simulate(0.2, progress=True)
    assert res.success


def test_an_interrupt_while_writing_leaves_no_partial_file(scene, capsys, monkeypatch):
    """Ctrl-C during an export, after it wrote part of its series: the export is staged
    (`mechsim.files`), so none of its files lands in the output directory; the run says so
    and what it had written before (the saved result comes first), and exits with 130."""
    import meshio
    scene.write_text(SCENE.replace("save = true", 'save = true\nexport = "motion.vtu"'))
    real, calls = meshio.write, []

    def write(path, mesh, *args, **kwargs):
        calls.append(path)
        if len(calls) == 3:
            raise KeyboardInterrupt
        return real(path, mesh, *args, **kwargs)
    monkeypatch.setattr(meshio, "write", write)
    code, out, err = run(capsys, scene)
    assert code == 130 and len(calls) == 3
    assert "interrupted during writing" in err and "nothing of it was written" in err
    assert "pendulum.npz" in err                              # the save came first
    assert sorted(p.name for p in (scene.parent / "out" / "pendulum").iterdir()) == \
        ["pendulum.npz"]

def test_a_scene_writes_its_table(tmp_path, capsys, monkeypatch):
    """[output] table: the CSV holds time, coordinates, the `points`, the pin's force and
    the scene's channels, equal to the same run's table through the API."""
    monkeypatch.chdir(tmp_path)
    text = SCENE.replace("save = true", 'table = "motion.csv"\nreactions = ["pin"]\n'
                                        'points = [["rod", [0.5, 0.0]]]')
    text += '[[channel]]\nname = "drop"\nexpression = "-2*rod.y"\nunit = "m"\n'
    (tmp_path / "pendulum.toml").write_text(text)
    code, out, _ = run(capsys, "pendulum.toml")
    assert code == 0 and "motion.csv" in out
    import csv
    with open(tmp_path / "out" / "pendulum" / "motion.csv", newline="", encoding="utf-8") as f:
        rows = list(csv.reader(f))
    header, data = rows[0], np.array(rows[1:], float)
    res = api()
    expected = res.table(points=[("rod", (0.5, 0.0))], joints=["pin"])
    assert header == list(expected) and header[-1] == "drop [m]"
    np.testing.assert_allclose(data, np.column_stack(list(expected.values())), rtol=1e-12,
                               atol=1e-12)
    # the rod's tip drops 2 y of its centre; a real swing, not zeros
    np.testing.assert_allclose(data[:, -1], -2 * res.coordinate("rod.y"), rtol=1e-14)
    assert data[:, -1].max() > 0.5


def test_a_table_not_named_csv_is_refused(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "pendulum.toml").write_text(SCENE.replace("save = true", 'table = "motion.txt"'))
    code, _, err = run(capsys, "pendulum.toml")
    assert code == 2 and "[output] table: the table is written as CSV" in err
