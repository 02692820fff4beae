"""Test setup: a private model cache per test session, so runs neither read nor pollute the
user's cache (shared by the session's workers: each model is built once, as the cache's
concurrent builds are safe), the fused build, one BLAS thread per worker, and
tolerance-scaled error helpers."""

import atexit
import os
import shutil
import sysconfig
import tempfile

import numpy as np
import pytest

# The controlling process makes the directory and removes it when it exits; the workers it
# starts inherit it.
if "MECHSIM_TEST_SESSION_CACHE" not in os.environ:
    os.environ["MECHSIM_TEST_SESSION_CACHE"] = tempfile.mkdtemp(prefix="mechsim-test-cache-")
    atexit.register(shutil.rmtree, os.environ["MECHSIM_TEST_SESSION_CACHE"], ignore_errors=True)
os.environ["MECHSIM_CACHE_DIR"] = os.environ["MECHSIM_TEST_SESSION_CACHE"]
# The suite runs the fused models (compiled where small) it was written against, built in
# its own process: no test depends on when a background build finishes. The assembled
# models and the "auto" choice between the two are tested in test_assembly.py.
os.environ.setdefault("MECHSIM_BUILD", "fused")

# The workers share the cores (one each): each holds its BLAS libraries to one thread, as a
# run does (`mechsim.threads`), also around the tests' own arithmetic and the analyses that
# are not runs. A multithreaded BLAS in two workers on two cores spins for each small
# product (the design tests took 1.5× their CPU time so). test_threads.py raises the limit
# where it checks what a run does with more threads.
import scipy.linalg  # noqa: E402,F401  (its BLAS among the libraries limited)
from threadpoolctl import threadpool_limits  # noqa: E402

_ONE_THREAD = threadpool_limits(limits=1, user_api="blas")


def scaled_error(y, y_ref, rtol, atol):
    """max |y − y*| / (atol + rtol |y*|): below ~5 means the solver met its tolerance."""
    y, y_ref = np.asarray(y, float), np.asarray(y_ref, float)
    return float(np.max(np.abs(y - y_ref) / (atol + rtol * np.abs(y_ref))))


@pytest.fixture
def rng():
    return np.random.default_rng(20261121)


def mechanism_models(directory):
    """The cached modules in `directory` that model a whole mechanism or a beam (not the
    joint types' kernels, which the fused build reads and which are modules too)."""
    return [p for p in directory.glob("mechsim_model_*.py")
            if b"A mechsim type kernel" not in p.read_bytes()]


def seeded_cache(directory):
    """`directory` (made where missing) as a model cache holding the compiled engine's
    object file (`mechsim.codegen.engine.engine_object`, with its digest) of the session's
    cache, compiled there once: for the tests of builds in an empty cache whose subject is
    not the engine's own compile (test_engine.py's are), which would each compile it again
    (~3 s of the compiler a cache). Nothing is copied where compiling is off or fails."""
    from pathlib import Path

    from mechsim.codegen import cache, compiled, engine
    directory = Path(directory)
    directory.mkdir(mode=0o700, parents=True, exist_ok=True)
    if os.environ.get("MECHSIM_NO_COMPILE"):
        return directory
    for found in engine.engine_object(Path(os.environ["MECHSIM_TEST_SESSION_CACHE"]),
                                      compiled.compiler()):
        for path in (found, cache._digest_path(found)):
            if not (directory / path.name).exists():
                shutil.copyfile(path, directory / path.name)
    return directory


# Tests of compiled code: skipped without a C compiler (or with compiling switched off).
needs_compiler = pytest.mark.skipif(
    shutil.which((os.environ.get("CC") or sysconfig.get_config_var("CC") or "cc").split()[0])
    is None or bool(os.environ.get("MECHSIM_NO_COMPILE")), reason="no C compiler")
