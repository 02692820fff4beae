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
    env = {**os.environ, "MECHSIM_CACHE_DIR": str(cache), "MECHSIM_BUILD": "auto",
           "MECHSIM_BACKGROUND": "1"}
    done = subprocess.run([sys.executable, "-P", "-m", "mechsim.cli", "run", scene.name,
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


def test_the_c_printer_writes_long_integers_as_doubles():
    import sympy as sp
    from mechsim.codegen.printer import c_printer
    t = sp.Symbol("t")
    assert c_printer().doprint(sp.Integer(5) ** 30 * t) == f"{float(5 ** 30)!r}*t"
    assert c_printer().doprint(sp.Integer(2) ** 53 + t) == f"t + {2 ** 53}"
