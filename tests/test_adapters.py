"""The adapters that put a projected state into a running scipy integrator
(`mechsim.integrators.adapters`) write attributes scipy does not document, so they are
checked against this scipy and against the oldest that pyproject allows
(`mechsim.integrators.adapter_check`: the state moved by 1e-3 mid-run must carry over,
with the history, to the exact solution through the moved state)."""

import math
import os
import re
import shutil
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

import mechsim
from mechsim.integrators import adapter_check
from scipy.integrate import BDF, DOP853, LSODA, RK23, RK45, Radau

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize("cls", [RK23, RK45, DOP853, Radau, BDF, LSODA],
                         ids=lambda c: c.__name__)
def test_a_moved_state_carries_over_on_this_scipy(cls):
    ok, what = adapter_check.check_one(cls)
    assert ok, what


@pytest.mark.parametrize("cls", [RK23, RK45, DOP853, Radau, BDF, LSODA],
                         ids=lambda c: c.__name__)
def test_a_shifted_state_keeps_its_motion_on_this_scipy(cls):
    ok, what = adapter_check.check_shift(cls)
    assert ok, what


def test_the_adams_method_takes_a_shift_in_place():
    from mechsim.integrators import AdamsPECE
    solver, taken = adapter_check._pendulum(AdamsPECE, shift_at=0.7)
    reference, _ = adapter_check._pendulum(adapter_check.DOP853, rtol=1e-13, atol=1e-15)
    assert taken and solver.status == "finished"
    assert abs(solver.y[0] - reference.y[0] - 2 * math.pi) < 1e-6


def _lowest(requirement_name):
    deps = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["dependencies"]
    for dep in deps:
        m = re.fullmatch(rf"{requirement_name}>=([0-9.]+)(,<[0-9.]+)?", dep.replace(" ", ""))
        if m:
            return m.group(1)
    raise AssertionError(f"pyproject gives no lower bound for {requirement_name}")


# A study (installs the oldest allowed numpy and scipy): run it when their ranges change.
@pytest.mark.slow
def test_a_moved_state_carries_over_on_the_oldest_allowed_scipy(tmp_path):
    """The lowest numpy and scipy of pyproject's ranges installed into a directory of their
    own, ahead of this environment's on the import path, with a copy of this mechsim
    (a new virtual environment took twice as long); skipped where the package registry
    cannot be reached."""
    numpy, scipy = _lowest("numpy"), _lowest("scipy")
    deps = tmp_path / "deps"
    done = subprocess.run([sys.executable, "-m", "pip", "install", "-q",
                           "--disable-pip-version-check", "--target", str(deps),
                           f"numpy=={numpy}", f"scipy=={scipy}"],
                          capture_output=True, text=True, timeout=600)
    if done.returncode != 0:
        pytest.skip(f"cannot install numpy {numpy} and scipy {scipy}: "
                    f"{done.stderr.strip().splitlines()[-1:]}")
    shutil.copytree(Path(mechsim.__file__).parent, tmp_path / "pkg" / "mechsim",
                    ignore=shutil.ignore_patterns("__pycache__"))
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(deps), str(tmp_path / "pkg")])}
    out = subprocess.run([sys.executable, "-s", "-m", "mechsim.integrators.adapter_check"],
                         capture_output=True, text=True, env=env, timeout=300)
    assert f"scipy {scipy}" in out.stdout
    assert out.returncode == 0, out.stdout + out.stderr
