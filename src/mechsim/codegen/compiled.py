"""C twins of a large model's generated functions, compiled once into the model cache.

A model with many coordinates (`printer.C_MIN_COORDINATES`) carries, besides its Python
functions, their C source (`C_SOURCE`, the same common subexpressions) and signatures
(`C_SIGNATURES`). On loading, the C source is compiled with the system's C compiler into a
shared library next to the cached module (once; atomically, like the module) and the
functions are replaced by ctypes calls into it, several times faster on large models. The
Python functions stay available in
`PYTHON_KERNELS`. Smaller models carry C twins of Φ, Φ_q, Φ_t and γ only, with
`C_REPLACE = False`: a foreign call would cost them as much as the Python kernel, and the
twins serve inside the compiled evaluations of `mechsim.codegen.engine` instead.

Nothing here is required: without a compiler (or with `MECHSIM_NO_COMPILE` set to a true
value), or where compiling or loading fails, the Python functions serve and `COMPILED` is
False; a failure is remembered in the cache and said once per process (`shared_library`).
The compiler is `$CC`, else the one Python was built with, else `cc`. This module must not
import sympy.
"""

from __future__ import annotations

import ctypes
import hashlib
import json
import os
import shlex
import shutil
import subprocess
import sysconfig
import tempfile
import threading
from pathlib import Path

import numpy as np

from ..files import alive
from .cache import adopt, env_flag, read_verified, verified_file, warn_once, write_entry

# Mechanisms with at least this many coordinates call C twins of their functions: there a
# Python kernel costs far more than a foreign call's overhead (docs/design-notes.md); below
# it the Python kernels are as fast as a foreign call, and the C twins of
# Φ, Φ_q, Φ_t and γ serve only inside the compiled partitioned engine. It is also where a
# fused model stops paying for its build (`mechsim.build.constraint_model`).
C_MIN_COORDINATES = 60
# Fused models with at least this many coordinates also give Φ_q as its non-zero entries,
# and a long chain's solvers then take it as a CSR array (`cache.sparse_forms`): below it
# the dense Φ_q from C serves the banded algebra as fast or faster (docs/benchmarks.md).
CSR_MIN_COORDINATES = 200

# The flags every compile of mechsim's C takes: `-ffp-contract=off` keeps multiply-adds
# unfused where a platform has them, so that the C sums round as numpy's. They are part of
# every compiled entry's name (`kernel_library_path`, `engine.library_path`, the engine's
# object), so that an entry compiled with other flags is never taken.
FLAGS = ("-O2", "-fPIC", "-ffp-contract=off")


def spline_c() -> str:
    """`mechsim_pspline`, the C twin of `mechsim.model.splines.evaluate` (spline.c)."""
    from importlib import resources
    return resources.files(__package__).joinpath("spline.c").read_text(encoding="utf-8")


def flags_digest() -> str:
    """A short digest of `FLAGS`, for the names of compiled entries."""
    return hashlib.sha256(" ".join(FLAGS).encode()).hexdigest()[:8]


def kernel_library_path(module_path: Path) -> Path:
    """Where the C twins of the model module at `module_path` are cached: the module's
    name with `.kernels-<digest of FLAGS>.so`."""
    return module_path.with_name(f"{module_path.stem}.kernels-{flags_digest()}.so")


# Why the compiled path does not serve, by library path (see `status`).
_declined: dict[str, str] = {}


def attach(module, path: Path | None) -> bool:
    """Replace `module`'s functions by their compiled twins where it has them; True if it did."""
    module.COMPILED = False
    source = getattr(module, "C_SOURCE", None)
    if not source or not getattr(module, "C_REPLACE", True) or path is None:
        return False
    lib = shared_library(source, kernel_library_path(path))
    if lib is None:
        return False
    try:
        kernels = {name: (getattr(lib, f"mechsim_{name}"), has_v, shapes)
                   for name, has_v, shapes in module.C_SIGNATURES}
    except AttributeError:
        return False
    module.PYTHON_KERNELS = {}
    for name, (cfun, has_v, shapes) in kernels.items():
        cfun.restype = None
        cfun.argtypes = [ctypes.c_void_p] * (2 if has_v else 1) + \
            [ctypes.c_double, ctypes.c_void_p] + [ctypes.c_void_p] * len(shapes)
        module.PYTHON_KERNELS[name] = getattr(module, name)
        setattr(module, name, _kernel(cfun, has_v, shapes))
    module.COMPILED = True
    return True


def compiler() -> list[str]:
    """The C compiler command: `$CC`, else the one Python was built with, else `cc`."""
    return shlex.split(os.environ.get("CC") or sysconfig.get_config_var("CC") or "cc")


def compiler_identity(command: list[str]) -> str:
    """What a remembered failure is valid for: the compiler's path, size and time (a new
    or updated compiler is tried again)."""
    found = shutil.which(command[0]) if command else None
    if found is None:
        return f"missing {command[0] if command else '(none)'}"
    st = Path(found).stat()
    return f"{found} {st.st_size} {st.st_mtime_ns}"


def shared_library(source, target: Path, parts=None):
    """The ctypes library compiled from `source` at `target`: loaded where the file there
    passes its digest (`mechsim.codegen.cache`), else built (once: a failure is remembered
    beside it, `<target>.failed`, for the same compiler, and said in one warning per
    process naming the compiler and its error). None where compiling is switched off
    (`MECHSIM_NO_COMPILE`) or fails: the Python path serves.

    `parts` = (own, objects): `source` is `own` followed by code that `objects(command)`
    gives compiled (object files kept in the cache, [] where it cannot): the library is
    built from `own` linked with them, and from `source` whole where that fails. `source`
    and `own` may be functions giving the text: called only where a build is needed."""
    if env_flag("MECHSIM_NO_COMPILE"):
        _declined[str(target)] = "MECHSIM_NO_COMPILE is set"
        return None
    if verified_file(target):
        try:
            return ctypes.CDLL(str(target))
        except OSError:
            pass                              # rebuilt below
    command = compiler()
    identity = compiler_identity(command)
    failed = target.with_name(target.name + ".failed")
    record = read_verified(failed)
    error = None
    if record is not None:
        try:
            memo = json.loads(record)
            if memo.get("compiler") == identity:
                error = memo.get("error", "")
        except ValueError:
            pass
    remembered = error is not None
    if error is None:
        found = parts[1](command) if parts is not None else []
        if not (found and build_library(_text(parts[0]), target, command, found) is None):
            error = build_library(_text(source), target, command)
        if error is None:
            adopt(target)
            failed.unlink(missing_ok=True)
            _declined.pop(str(target), None)
            return ctypes.CDLL(str(target))
        if not transient(error):
            try:
                write_entry(failed, json.dumps({"compiler": identity, "error": error}).encode())
                remembered = True
            except OSError:
                pass
    message = f"the C compiler {shlex.join(command)!r} failed: {error}"
    _declined[str(target)] = message
    then = (f"The failure is remembered in {target.parent}/*.failed until the compiler (or "
            f"CC) changes" if remembered else "It is tried again in the next process")
    warn_once(("compiler", identity), f"mechsim: {message}; models run on the Python path "
              f"(slower). {then}")
    return None


def _text(source) -> str:
    """`source` as text (`shared_library`'s source, or the function giving it)."""
    return source() if callable(source) else source


# What a compile that failed for want of a resource says: not remembered (the next process
# tries again), unlike the compiler's own errors.
TRANSIENT = ("No space left on device", "Disk quota exceeded", "Cannot allocate memory",
             "out of memory", "killed by signal")


def transient(error: str) -> bool:
    """Did a compile fail for want of disk, memory or time that may come back?"""
    return any(mark.lower() in error.lower() for mark in TRANSIENT)


# The prefix of a compile's working directory in the cache (`clean_builds` removes those
# of processes that were killed).
BUILD_PREFIX = "mechsim-build-"


def build_library(source: str, library: Path, command: list[str], objects=(),
                  shared=True) -> str | None:
    """Compile `source` into `library` with `command` (linked with the object files
    `objects`; with `shared` False, into an object file); None on success, else the error
    (the compiler's last lines). The compile works in a directory of its own in the
    cache, removed after it; one left by a killed process is removed by the next
    compile."""
    clean_builds(library.parent)
    try:
        with tempfile.TemporaryDirectory(dir=library.parent,
                                         prefix=f"{BUILD_PREFIX}{os.getpid()}-") as tmp:
            c_file, out = Path(tmp) / "model.c", Path(tmp) / "model.so"
            c_file.write_text(source)
            # The objects (the compiled engine) first: their code then lies at the same
            # place in every model's library, whatever the model's own code's size.
            link = ["-shared", "-o", str(out), *map(str, objects), str(c_file), "-lm"] \
                if shared else ["-c", "-o", str(out), str(c_file)]
            done = subprocess.run(command + [*FLAGS, *link],
                                  capture_output=True, timeout=600)
            if done.returncode != 0 or not out.is_file():
                text = (done.stderr or done.stdout).decode(errors="replace").strip()
                if done.returncode < 0:
                    text += f" (killed by signal {-done.returncode})"
                return " ".join(text.splitlines()[-3:])[:400] or f"exit status {done.returncode}"
            out.replace(library)
    except subprocess.TimeoutExpired:
        return "timed out after 600 s"
    except OSError as exc:
        return exc.strerror or str(exc)
    return None


def clean_builds(directory: Path) -> None:
    """Remove the compile directories in `directory` whose process is gone."""
    try:
        entries = list(directory.iterdir())
    except OSError:
        return
    for entry in entries:
        if not entry.name.startswith(BUILD_PREFIX) or entry.is_symlink():
            continue
        pid = entry.name[len(BUILD_PREFIX):].split("-", 1)[0]
        if pid.isdigit() and not alive(int(pid)):
            shutil.rmtree(entry, ignore_errors=True)



def declined(target: Path) -> str | None:
    """Why the library at `target` does not serve (None: it does, or was not asked for)."""
    return _declined.get(str(target))


def _kernel(cfun, has_v: bool, shapes):
    """A Python function with the generated function's signature calling `cfun`. Its
    inputs are copied into buffers kept with their addresses (an array's `.ctypes.data`
    costs more than copying a state of a few hundred numbers), the parameters' array and
    address kept while the same parameter tuple comes; its outputs are written into kept
    zeroed buffers and returned as copies (the caller owns them); a lock keeps the buffers
    to one call at a time (ctypes lets other threads run during the call)."""
    shapes = [(rows,) if cols == 1 else (rows, cols) for rows, cols in shapes]
    single = len(shapes) == 1
    lock = threading.Lock()
    kept = {}               # "q", "v": (buffer, its address); "p": (tuple, array, address)
    outs = [np.zeros(shape) for shape in shapes]
    at_outs = [o.ctypes.data for o in outs]

    def address(name, x):
        buffer, at = kept.get(name, (None, 0))
        x = np.asarray(x, dtype=float)
        if buffer is None or buffer.shape != x.shape:
            buffer = np.empty(x.shape)
            at = buffer.ctypes.data
            kept[name] = (buffer, at)
        buffer[...] = x
        return at

    def call(t, p, q, v=None):
        with lock:
            seen, _, at_p = kept.get("p", (None, None, 0))
            if seen is not p:
                values = np.ascontiguousarray(p, dtype=float)
                at_p = values.ctypes.data
                kept["p"] = (p, values, at_p)
            pointers = (address("q", q),) if v is None else (address("q", q),
                                                              address("v", v))
            for o in outs:
                o.fill(0.0)
            cfun(*pointers, t, at_p, *at_outs)
            if single:
                return outs[0].copy()
            return tuple(o.copy() for o in outs)

    if has_v:
        def kernel(q, v, t, p):
            return call(t, p, q, v)
    else:
        def kernel(q, t, p):
            return call(t, p, q)
    return kernel


class Compilation:
    """Whether compiled code serves a model (`Mechanism.compilation()`):

    kernels : bool
        the model's generated functions run as C (models of `printer.C_MIN_COORDINATES`
        coordinates or more);
    engine : bool
        the compiled evaluations of `mechsim.codegen.engine` serve its LU, QR, projection
        and hybrid runs (small rigid mechanisms);
    reason : str
        why neither serves, or "" where one does."""

    __slots__ = ("kernels", "engine", "reason")

    def __init__(self, kernels: bool, engine: bool, reason: str):
        self.kernels, self.engine, self.reason = kernels, engine, reason

    @property
    def serves(self) -> bool:
        return self.kernels or self.engine

    def __repr__(self):
        return f"Compilation(kernels={self.kernels}, engine={self.engine}, reason={self.reason!r})"


def compilation(problem) -> Compilation:
    """What compiled code serves `problem` (a NumericProblem); builds what is missing."""
    from . import engine
    model = problem.model
    kernels = bool(getattr(model, "COMPILED", False))
    served = engine.for_problem(problem) is not None
    path = getattr(model, "__file__", None)
    reason = ""
    if not (kernels or served):
        if env_flag("MECHSIM_NO_COMPILE"):
            reason = "MECHSIM_NO_COMPILE is set"
        elif getattr(model, "ASSEMBLED", False):
            reason = ("the model is assembled from joint-type kernels (numpy); the fused "
                      "compiled model serves builds after it is in the cache "
                      "(`Mechanism.problem(build=\"fused\")` builds it now)")
        elif path is None:
            reason = "the model is kept in memory only (its cache could not be written)"
        else:
            why = [declined(kernel_library_path(Path(path))),
                   declined(engine.library_path(Path(path)))]
            reason = next((w for w in why if w), "") or engine.why_not(problem)
    return Compilation(kernels, served, reason)
