"""The fused model of a long mechanism, built in a separate process while its first runs
go on the assembled one (`mechsim.assembly`).

A long mechanism's fused model (its joint types' kernels unrolled,
`mechsim.assembly.unrolled`, with compiled twins of its functions) evaluates faster than
its assembly from the kernels (a 40-window chain's runs 0.78× the time) and gives the
same numbers, but its C compile takes 10 s at 243 coordinates, 45 s at 603. `start` hands
the mechanism's bodies and constraint items to a new Python process (through a pipe,
never a file) that builds it into the model cache and exits; builds of the same
structure after it has finished load the fused model. The process outlives a short
script that started it; a process starts one at a time. It is not started where
`MECHSIM_BACKGROUND` is set false, or where the cache is not the configured directory
(another process could not find it).

The process runs in Python's isolated mode (no PYTHON* variables, no user site, nothing
prepended to its import path) in the cache directory, with the parent's import path minus
the working directory handed over: a `json.py` or `numpy.py` beside the user's scene is
never imported. It has `CPU_SECONDS` of processor time (a new joint type's kernel is
derived by sympy there, and a compiler may stall), after which the assembled model goes
on serving.
"""

from __future__ import annotations

import os
import pickle
import subprocess
import sys

from ..codegen.cache import cache_dir, env_flag, store, structure_key

_started: set[str] = set()
# The build this process started last, while it runs: one at a time (a study of chains of
# many lengths would otherwise compile them all at once, each for up to a minute).
_running: list = []
# The processor time a background build may take.
CPU_SECONDS = 300
# What the child runs: the import path from its arguments, then `main`.
_CHILD = ("import sys; sys.path[:0] = sys.argv[1:]; "
          "from mechsim.build.background import main; main()")


def enabled() -> bool:
    """Whether background builds may start (`MECHSIM_BACKGROUND`, on by default)."""
    value = os.environ.get("MECHSIM_BACKGROUND")
    return value is None or env_flag("MECHSIM_BACKGROUND")


def start(bodies, items, structure) -> bool:
    """Start building the fused model of `structure` (the mechanism's `bodies` and
    constraint `items`) in a new process, once per structure and process and while no
    other build this process started runs; True if one was started."""
    key = structure_key(structure)
    if key in _started or not enabled() or store() != cache_dir() or \
            any(child.poll() is None for child in _running):
        return False
    try:
        payload = pickle.dumps((bodies, items, structure))
        child = subprocess.Popen([sys.executable, "-I", "-c", _CHILD, *import_path()],
                                 stdin=subprocess.PIPE, stdout=subprocess.DEVNULL,
                                 stderr=subprocess.DEVNULL, start_new_session=True,
                                 cwd=store())
        child.stdin.write(payload)
        child.stdin.close()
    except (OSError, pickle.PicklingError, TypeError, AttributeError):
        return False                  # the assembled model serves; nothing is lost
    _started.add(key)
    _running[:] = [child]
    return True


def import_path() -> list[str]:
    """The parent's import path for the child: without the working directory (nor '',
    which means it), and with mechsim's own root first."""
    here = os.path.realpath(os.getcwd())
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    path = [root]
    for entry in sys.path:
        if entry and os.path.realpath(entry) != here and entry not in path:
            path.append(entry)
    return path


def main() -> None:
    """The child: limit its processor time, read the build's payload from stdin, build."""
    try:
        import resource
        resource.setrlimit(resource.RLIMIT_CPU, (CPU_SECONDS, CPU_SECONDS))
    except (ImportError, ValueError, OSError):
        pass                            # no such limit here: the build runs unbounded
    build(*pickle.load(sys.stdin.buffer))


def fused_source(bodies, items, structure) -> str:
    """The fused module's text: what `mechsim.build` compiles on a miss, the joint types'
    kernels unrolled with the drivers' laws (`mechsim.assembly.unrolled`: the assembled
    model's arithmetic; sympy runs only for a kernel not yet cached)."""
    from ..assembly.unrolled import unrolled_source
    return unrolled_source(bodies, items, structure_key(structure))


def build(bodies, items, structure):
    """The fused model (from the cache, or built into it), with its compiled evaluations
    where they serve; returns the module."""
    from ..model import FlexibleBeam
    from ..codegen import engine
    from ..codegen.cache import load_model
    from ..linalg import banded
    module, _ = load_model(structure, lambda: fused_source(bodies, items, structure))
    # The compiled evaluations take rigid models (whose mass is constant and diagonal,
    # `MassModel.constant`) on the dense algebra only: a long chain's banded one runs in
    # Python (their library would compile its model's C once more).
    rigid = not any(isinstance(b, FlexibleBeam) for b in bodies)
    if rigid and not banded.takes(module.M, rigid):
        engine.library(module)
    return module

