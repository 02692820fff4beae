"""C twins of a large model's generated functions, compiled once into the model cache.

A model with many coordinates (`printer.C_MIN_COORDINATES`) carries, besides its Python
functions, their C source (`C_SOURCE`, the same common subexpressions) and signatures
(`C_SIGNATURES`). On loading, the C source is compiled with the system's C compiler into a
shared library next to the cached module (once; atomically, like the module) and the
functions are replaced by ctypes calls into it: on the 40-window chain `dynamics_terms`
costs 22 µs so, against 134 µs in Python. The Python functions stay available in
`PYTHON_KERNELS`. Smaller models carry C twins of Φ, Φ_q, Φ_t and γ only, with
`C_REPLACE = False`: a foreign call would cost them as much as the Python kernel, and the
twins serve inside the compiled evaluations of `mechsim.codegen.engine` instead.

Nothing here is required: without a compiler (or with `MECHSIM_NO_COMPILE` set), or where
compiling or loading fails, the Python functions serve and `COMPILED` is False. The compiler
is `$CC`, else the one Python was built with, else `cc`. This module must not import sympy.
"""

from __future__ import annotations

import ctypes
import os
import shlex
import subprocess
import sysconfig
import tempfile
from pathlib import Path

import numpy as np


def attach(module, path: Path | None) -> bool:
    """Replace `module`'s functions by their compiled twins where it has them; True if it did."""
    module.COMPILED = False
    source = getattr(module, "C_SOURCE", None)
    if (not source or not getattr(module, "C_REPLACE", True) or path is None
            or os.environ.get("MECHSIM_NO_COMPILE")):
        return False
    library = path.with_suffix(".so")
    if not library.is_file() and not build_library(source, library):
        return False
    try:
        lib = ctypes.CDLL(str(library))
        kernels = {name: (getattr(lib, f"mechsim_{name}"), has_v, shapes)
                   for name, has_v, shapes in module.C_SIGNATURES}
    except (OSError, AttributeError):
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


def build_library(source: str, library: Path) -> bool:
    """Compile `source` into `library`; False if there is no working compiler."""
    compiler = shlex.split(os.environ.get("CC") or sysconfig.get_config_var("CC") or "cc")
    try:
        with tempfile.TemporaryDirectory(dir=library.parent) as tmp:
            c_file, out = Path(tmp) / "model.c", Path(tmp) / "model.so"
            c_file.write_text(source)
            done = subprocess.run(compiler + ["-O2", "-shared", "-fPIC", "-o", str(out),
                                              str(c_file), "-lm"],
                                  capture_output=True, timeout=600)
            if done.returncode != 0 or not out.is_file():
                return False
            os.replace(out, library)
    except (OSError, subprocess.SubprocessError):
        return False
    return True


def _kernel(cfun, has_v: bool, shapes):
    """A Python function with the generated function's signature calling `cfun`."""
    shapes = [(rows,) if cols == 1 else (rows, cols) for rows, cols in shapes]
    single = len(shapes) == 1
    last = [(None, None)]       # (parameter tuple last seen, as an array): one atomic slot

    def call(pointers, t, p):
        seen, values = last[0]
        if seen is not p:
            values = np.ascontiguousarray(p, dtype=float)
            last[0] = (p, values)
        outs = [np.zeros(shape) for shape in shapes]
        cfun(*pointers, t, values.ctypes.data, *[o.ctypes.data for o in outs])
        return outs[0] if single else tuple(outs)

    if has_v:
        def kernel(q, v, t, p):
            q = np.ascontiguousarray(q, dtype=float)
            v = np.ascontiguousarray(v, dtype=float)
            return call((q.ctypes.data, v.ctypes.data), t, p)
    else:
        def kernel(q, t, p):
            q = np.ascontiguousarray(q, dtype=float)
            return call((q.ctypes.data,), t, p)
    return kernel
