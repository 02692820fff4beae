"""The API reference (docs/, Sphinx autodoc over the docstrings) builds without a warning:
a docstring that stops parsing as reStructuredText fails the suite."""

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

DOCS = Path(__file__).resolve().parent.parent / "docs"


def test_the_api_reference_builds_without_warnings(tmp_path):
    pytest.importorskip("sphinx")
    done = subprocess.run([sys.executable, "-m", "sphinx", "-W", "--keep-going", "-q", "-b",
                           "html", str(DOCS), str(tmp_path / "html")],
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-3000:]
    page = (tmp_path / "html" / "api" / "engineering.html").read_text()
    for name in ("ReactionTable", "Equilibrium", "Linearization", "joint_force"):
        assert name in page
    scenes = (tmp_path / "html" / "api" / "scenes.html").read_text()
    for name in ("rotational_spring", "load_mechanism", "set_speed", "scene_data"):
        assert name in scenes, name
    shutil.rmtree(tmp_path / "html")
