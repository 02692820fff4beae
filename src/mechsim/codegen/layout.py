"""One description of each structure the compiled evaluations share with Python.

A `Layout` lists a C struct's fields in order: scalars, pointers to arrays that Python fills
(inputs and state), and scratch buffers with their sizes as functions of the problem's
dimensions. From it come the C `typedef` prepended to the engine's source, the matching
`ctypes.Structure`, and the allocated buffers, so that a size or an order is written once.
"""

from __future__ import annotations

import ctypes
from dataclasses import dataclass
from typing import Callable

import numpy as np

_C_TYPES = {"int64": "int64_t", "double": "double", "double*": "double *",
            "const double*": "const double *", "int64*": "int64_t *",
            "const int64*": "const int64_t *", "int*": "int *"}
_CTYPES = {"int64": ctypes.c_int64, "double": ctypes.c_double}
_DTYPES = {"double*": np.float64, "const double*": np.float64, "int64*": np.int64,
           "const int64*": np.int64, "int*": np.intc}


@dataclass(frozen=True)
class Field:
    """A struct member. `size` (`Dims` -> int) makes it a buffer the layout allocates; a
    pointer without a size is set by its owner (`Layout.pointers`)."""
    name: str
    kind: str
    size: Callable[[Dims], int] | None = None


class Layout:
    """A C struct and its ctypes twin, with the buffers it points to."""

    def __init__(self, c_name: str, fields: list[Field]):
        self.c_name = c_name
        self.fields = tuple(fields)
        self.structure = type(c_name, (ctypes.Structure,), {"_fields_": [
            (f.name, _CTYPES.get(f.kind, ctypes.c_void_p)) for f in self.fields]})

    def typedef(self) -> str:
        """The C declaration, in the same order as the ctypes structure."""
        body = "".join(f"  {_C_TYPES[f.kind]} {f.name};\n" for f in self.fields)
        return f"typedef struct {{\n{body}}} {self.c_name};\n"

    def buffers(self, dims: Dims) -> dict[str, np.ndarray]:
        """Zeroed arrays for the fields with a size (at least one element each)."""
        return {f.name: np.zeros(max(int(f.size(dims)), 1), dtype=_DTYPES[f.kind])
                for f in self.fields if f.size is not None}

    def make(self, scalars: dict, arrays: dict):
        """The structure with `scalars` set and each pointer field at its array in
        `arrays` (every pointer field must be given)."""
        values = dict(scalars)
        for f in self.fields:
            if f.kind in _DTYPES:
                values[f.name] = arrays[f.name].ctypes.data
        return self.structure(**values)


@dataclass(frozen=True)
class Dims:
    """The dimensions buffer sizes depend on: coordinates n, constraint equations m, and
    for a partition f independent and r = n − f dependent coordinates."""
    n: int
    m: int
    f: int = 0

    @property
    def r(self) -> int:
        return self.n - self.f

    @property
    def k(self) -> int:
        return min(self.m, self.n)


# The partitioned evaluation: the partition and the last accepted step.
PARTITION = Layout("mechsim_lu", [
    *(Field(name, "int64") for name in ("n", "m", "f", "max_newton", "rheonomic", "fresh")),
    *(Field(name, "double") for name in ("newton_tol", "chord_contraction", "t_last",
                                          "stall_ratio", "stall_span")),
    Field("p", "const double*"), Field("q_ref", "const double*"),
    Field("P", "const double*"),           # r × (3 + f): the dependent coordinates' prediction
    Field("C", "const double*"),           # r × m: (Φ_q D)⁻¹, the chord factor
    Field("winv", "const double*"),
    Field("ind", "const int64*"), Field("dep", "const int64*"),
    *(Field(name, "double*") for name in ("y", "q", "v", "J", "Q", "out")),
    Field("w", "double*", lambda d: d.r), Field("phi", "double*", lambda d: d.m),
    Field("A", "double*", lambda d: d.r * d.r), Field("b", "double*", lambda d: d.r),
    Field("phit", "double*", lambda d: d.m), Field("g", "double*", lambda d: d.m),
    Field("X", "double*", lambda d: d.r * (d.f + 1)), Field("Mh", "double*", lambda d: d.f * d.f),
    Field("Qh", "double*", lambda d: d.f), Field("ipiv", "int*", lambda d: d.r),
    Field("E", "double*", lambda d: d.r * d.n),
    # the last accepted state's independent and dependent coordinates (`follow`)
    Field("z_last", "double*", lambda d: d.f), Field("w_last", "double*", lambda d: d.r),
    Field("zk", "double*", lambda d: d.f),
])

# The projection method, the state projection, the monitor's measure and the LU test.
PROJECTION = Layout("mechsim_projection", [
    *(Field(name, "int64") for name in ("n", "m", "count", "lwork")),
    *(Field(name, "double") for name in ("stall_ratio", "stall_span")),
    Field("p", "const double*"), Field("winv", "const double*"),
    *(Field(name, "double*") for name in ("q", "v", "Q", "out")),
    Field("J", "double*", lambda d: d.m * d.n), Field("J1", "double*", lambda d: d.m * d.n),
    Field("A", "double*", lambda d: d.m * d.n), Field("S", "double*", lambda d: d.m * d.m),
    Field("X", "double*", lambda d: d.m * d.m), Field("sig", "double*", lambda d: d.m),
    Field("U", "double*", lambda d: d.n * d.m), Field("VT", "double*", lambda d: d.m * d.m),
    *(Field(name, "double*", lambda d: d.m) for name in ("g", "lam", "phi", "r", "y")),
    *(Field(name, "double*", lambda d: d.n) for name in ("wq", "x", "q1")),
    Field("cw", "double*", lambda d: 3 * d.m), Field("perm", "int64*", lambda d: d.n),
    Field("iwork", "int*", lambda d: 8 * d.m),
    # dgesdd's workspace for jobz = 'S' on an n × m matrix, k = min(m, n)
    Field("svd_work", "double*",
          lambda d: 3 * d.k + max(d.n, d.m, 5 * d.k * d.k + 4 * d.k) + 64),
])
