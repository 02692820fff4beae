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
            "const int64*": "const int64_t *", "int*": "int *", "void*": "void *"}
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
    # the velocities' Φ_q D (A0) and its LU factors, which the accelerations at the same
    # state reuse
    Field("A0", "double*", lambda d: d.r * d.r), Field("LU", "double*", lambda d: d.r * d.r),
    Field("LUpiv", "int*", lambda d: d.r),
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
    Field("wsqrt", "const double*"),       # √winv, correctly rounded as C's sqrt
    *(Field(name, "double*") for name in ("q", "v", "Q", "out")),
    Field("J", "double*", lambda d: d.m * d.n), Field("J1", "double*", lambda d: d.m * d.n),
    Field("A", "double*", lambda d: d.m * d.n), Field("S", "double*", lambda d: d.m * d.m),
    Field("rdiag", "double*", lambda d: d.m),        # 1 / diagonal of `cholesky`'s factor
    Field("X", "double*", lambda d: d.m * d.m), Field("sig", "double*", lambda d: d.m),
    Field("Winv", "double*", lambda d: d.m * d.m),     # `cholesky`'s inverse factor
    Field("U", "double*", lambda d: d.n * d.m), Field("VT", "double*", lambda d: d.m * d.m),
    *(Field(name, "double*", lambda d: d.m) for name in ("g", "lam", "phi", "r", "y")),
    *(Field(name, "double*", lambda d: d.n) for name in ("wq", "x", "q1")),
    Field("cw", "double*", lambda d: 3 * d.m), Field("perm", "int64*", lambda d: d.n),
    Field("nz", "int64*", lambda d: d.m * d.n + d.m),    # `complement`'s columns a row uses
    # Φ_q's pattern as `complement` takes it (`pair_pattern`; pairs = 0: none, each call
    # finds the columns its rows use): the pairs of rows i, k ≤ i that share columns
    # (pair_rows[2 p], pair_rows[2 p + 1]), the columns of pair p pair_cols[pair_start[p]:
    # pair_start[p + 1]]
    Field("pairs", "int64"), Field("pair_rows", "const int64*"),
    Field("pair_start", "const int64*"), Field("pair_cols", "const int64*"),
    # and row i's columns row_cols[row_start[i]:row_start[i + 1]], column j's rows
    # col_rows[col_start[j]:col_start[j + 1]] (with pairs > 0); the
    # Cholesky factor L of J W Jᵀ on that pattern with its fill (`pattern_cholesky`):
    # chol_ops of its entries in the order they are made, entry p = L[chol_ij[2 p],
    # chol_ij[2 p + 1]] taking the products of the columns chol_ks[chol_start[p]:
    # chol_start[p + 1]]; L's rows (columns k < i) and columns (rows k > j) by
    # lrow_start/lrow_cols and lcol_start/lcol_rows
    Field("row_start", "const int64*"), Field("row_cols", "const int64*"),
    Field("col_start", "const int64*"), Field("col_rows", "const int64*"),
    Field("chol_ops", "int64"),
    *(Field(name, "const int64*") for name in (
        "chol_ij", "chol_start", "chol_ks", "lrow_start", "lrow_cols", "lcol_start",
        "lcol_rows")),
    # the model's straight-line code of the same sums (`kernels.pattern_kernels`), where
    # 1, and their scratch (max(m, n))
    Field("kernels", "int64"), Field("tj", "double*", lambda d: max(d.m, d.n)),
    # the rotation of J~'s rows the monitor's last Jacobi SVD ended with (`jacobi_svd`: the
    # next one starts from it where jacobi_warm is 1; a run starts afresh)
    Field("jacobi_warm", "int64"), Field("jacobi_from", "double*", lambda d: d.m * d.m),
    Field("iwork", "int*", lambda d: 8 * d.m),
    # the extreme singular values' workspace (`extremes_of`: bidiagonal, dlasq1's; then the
    # accelerations' QR: its reflectors' factors, R's diagonal and three vectors)
    Field("ext_work", "double*", lambda d: 10 * d.m + d.n + 16),
    # dgesdd's workspace for jobz = 'S' on an n × m matrix, k = min(m, n)
    Field("svd_work", "double*",
          lambda d: 3 * d.k + max(d.n, d.m, 5 * d.k * d.k + 4 * d.k) + 64),
])

# The arrays of Φ_q's pattern in `PROJECTION` (`pair_pattern`).
PATTERN_ARRAYS = ("pair_rows", "pair_start", "pair_cols", "row_start", "row_cols",
                  "col_start", "col_rows", "chol_ij", "chol_start", "chol_ks", "lrow_start",
                  "lrow_cols", "lcol_start", "lcol_rows")


def pair_pattern(model, m: int, n: int) -> dict[str, np.ndarray]:
    """`PROJECTION`'s pattern arrays for a model of m constraint rows and n coordinates:
    the pairs of rows i and k ≤ i (i outer) whose entries in Φ_q's pattern
    (`JACOBIAN_ROWS`, `JACOBIAN_COLS`: the entries its code sets, all others zero) share
    columns, those columns, each row's columns and each column's rows, in increasing
    order, and the Cholesky factor's (`_cholesky_pattern`); none (one zero each) where the
    model gives no pattern (`complement` then finds the columns a row uses at each call,
    and the other sums run over every entry)."""
    if not hasattr(model, "JACOBIAN_ROWS"):
        return {name: np.zeros(1, np.int64) for name in PATTERN_ARRAYS}
    used = [set() for _ in range(m)]
    for i, j in zip(model.JACOBIAN_ROWS, model.JACOBIAN_COLS):
        used[i].add(j)
    rows, start, shared, row_start, row_cols = [], [0], [], [0], []
    col_start, col_rows = [0], []
    for j in range(n):
        col_rows += [i for i in range(m) if j in used[i]]
        col_start.append(len(col_rows))
    for i in range(m):
        row_cols += sorted(used[i])
        row_start.append(len(row_cols))
        for k in range(i + 1):
            both = sorted(used[i] & used[k])
            if both:
                rows += [i, k]
                shared += both
                start.append(len(shared))
    out = {"pair_rows": rows, "pair_start": start, "pair_cols": shared,
           "row_start": row_start, "row_cols": row_cols, "col_start": col_start,
           "col_rows": col_rows, **_cholesky_pattern(m, rows)}
    return {name: np.array(out[name] or [0], np.int64) for name in PATTERN_ARRAYS}


def _cholesky_pattern(m: int, pairs) -> dict[str, list]:
    """The lists of `PROJECTION`'s chol_* and l* fields for J W Jᵀ of the pattern whose
    lower triangle's entries are `pairs` (flat i, k pairs): L's entries (the pattern with
    the fill of the elimination in its natural order, which the small Cholesky takes),
    column after column, the diagonal first, each with the columns k < j where both its
    row and column j of L have entries."""
    ops, start, ks = [], [0], []
    filled = [[False] * m for _ in range(m)]
    for i, k in zip(pairs[0::2], pairs[1::2]):
        filled[i][k] = True
    for j in range(m):
        for i in range(j, m):
            both = [k for k in range(j) if filled[i][k] and filled[j][k]]
            if i == j or filled[i][j] or both:
                filled[i][j] = True
                ops += [i, j]
                ks += both
                start.append(len(ks))
    lrow_start, lrow_cols, lcol_start, lcol_rows = [0], [], [0], []
    for i in range(m):
        lrow_cols += [k for k in range(i) if filled[i][k]]
        lrow_start.append(len(lrow_cols))
        lcol_rows += [k for k in range(i + 1, m) if filled[k][i]]
        lcol_start.append(len(lcol_rows))
    return {"chol_ij": ops, "chol_start": start, "chol_ks": ks, "lrow_start": lrow_start,
            "lrow_cols": lrow_cols, "lcol_start": lcol_start, "lcol_rows": lcol_rows}


# The most nodes a segment's passage search holds (`mechsim_lu_segment`; more: the loop
# searches).
NODES = 256

# The numbers that make a passage search's request (`search_request` in the engine).
SEARCH_KEY = 20
# The singularity monitor's passage search on a step's dense output (`mechsim_anchored`):
# the grid (at most `nodes_cap` = NODES nodes) and its scratch, the dense output (N state
# entries, `rows` coefficients F from t_old over h, y_old) and the measured nodes found
# (`found` of them, rows (t, σ_k, σ_max) in `out`). Sized for states of 2 n entries, so one
# serves a partition's [z; ż] and a state [q; v]. `floors`: whether floor anchors clear first
# (`extreme_bounds`); `floored` of them in the last search, `floors_taken` in all.
SEARCH = Layout("mechsim_search", [
    *(Field(name, "int64") for name in ("n", "m", "nodes_cap", "grid", "kk", "N", "rows",
                                        "open_at_start", "found", "kept", "floors",
                                        "floored", "cached", "floors_taken")),
    *(Field(name, "double") for name in ("chord", "enter", "leave", "apart", "t_old", "h")),
    Field("F", "const double*"), Field("y_old", "const double*"),
    # what the kept search was asked (`kept`: a segment's search, which the loop's search
    # of the same step takes instead of searching again): its inputs, the partition it
    # solved positions on, the dense output's coefficients and start
    Field("key_c", "void*"), Field("key", "double*", lambda d: SEARCH_KEY),
    Field("asked", "double*", lambda d: SEARCH_KEY),
    Field("key_F", "double*", lambda d: 8 * 2 * d.n), Field("key_y", "double*", lambda d: 2 * d.n),
    *(Field(name, "double*", lambda d: NODES) for name in (
        "nodes", "node_chords", "node_low", "node_high", "node_mid", "node_lows")),
    *(Field(name, "int64*", lambda d: NODES) for name in ("node_has", "node_todo",
                                                          "node_fresh", "node_joined",
                                                          "node_slot")),
    Field("node_J", "double*", lambda d: NODES * d.m * d.n),     # J̃ at each node's slot
    Field("node_anchor", "double*", lambda d: 2 * NODES), Field("node_ex", "double*", lambda d: 2),
    *(Field(name, "double*", lambda d: NODES * d.n) for name in ("node_q", "node_mq")),
    Field("node_pieces", "double*", lambda d: 2 * NODES),
    Field("Yn", "double*", lambda d: NODES * 2 * d.n), Field("vn", "double*", lambda d: d.n),
    Field("out", "double*", lambda d: 3 * NODES),
    # the floor anchors' scratch (`extreme_bounds`: J̃ J̃ᵀ, its Cholesky factor, its inverse)
    Field("gram", "double*", lambda d: d.m * d.m), Field("inverse", "double*", lambda d: d.m * d.m),
    # the measured nodes of a search with floors that did not prove its step clear (rows
    # t, σ_k, σ_max, `cached` of them), for the search without floors made after it
    Field("node_cache", "double*", lambda d: 3 * NODES),
])

# The most passages a segment records before the loop reads them (`passages`; more: the
# loop observes the step that would add one).
PASSAGES = 32

# Consecutive plain steps of a partition in one call (`mechsim.run.segment`): the integrator's,
# the monitor's, the hybrid policy's and the run's state a step reads and changes, with the
# buffers of one step. `stages` rows of K are DOP853's with its dense output's extra ones.
SEGMENT = Layout("mechsim_segment", [
    *(Field(name, "int64") for name in (
        "budget", "count", "reason", "steps", "max_steps", "runaway_from", "runaway_every",
        "stages", "extra_rows", "extra_width", "dense_rows", "dense_cols", "n_ts", "next",
        "held", "capacity", "y_rows", "evaluations", "factorizations", "corrections",
        "hybrid", "held_steps", "has_limit", "policy_steps", "small", "max_skip", "skipped",
        "has_prev", "has_floor", "has_measured", "has_fall", "cur", "known_n", "every_step",
        "grid",
        # the step's rate: its context's kind (0 projection, 1 partition); the projection
        # method's steps (`mechsim_projection_segment`): its far flag now and for the last
        # step, the hybrid's stable steps, the bridge's previous plan, what was counted
        "kind", "far", "far_taken", "stable", "stable_steps", "bridging", "has_bprev",
        "has_landing", "has_free", "free_bound", "has_planned", "plan_reset", "projections",
        "pending",
        "dense_formed", "open_at_start",
        # the passages a segment observes itself (`handles_passages`; `through`: also
        # through their band, a step ending inside one): the open one, whether its
        # singular vector is the segment's (else its joints are the loop's), the passages
        # recorded (`passages_n` of at most `passages_cap`), and whether the latest
        # measurement's singular vector is kept (`vector`)
        "handles_passages", "through", "has_open", "open_u_set", "passages_n",
        "passages_cap", "has_vector")),
    *(Field(name, "double") for name in (
        "t", "t_old", "h_abs", "h_previous", "t_bound", "direction", "max_step",
        "run_max_step", "rtol", "safety", "min_factor", "max_factor", "exponent",
        "min_advance", "sign", "repartition_at", "reference_span", "limit", "enter", "leave",
        "blind",
        "weyl_span", "hermite_margin", "peak", "peak_rate", "last", "rate", "prev_t", "prev_s",
        "prev_rate", "floor_t", "floor_v", "m_smin", "m_smax", "m_speed", "skip_rise",
        "ratio_speed", "cond_max",
        "growth", "keep_t", "chord", "machine_eps", "rank_factor", "rate_step",
        "rate_rcond", "cut", "min_rcond", "previous", "lu_limit", "project_tol", "skip_tol",
        "bprev_t", "bprev_rate", "landing", "free_step", "planned_t", "planned_star",
        "plan_rate", "landing_share", "edge",
        "round_off", "open_t_start", "open_t_min", "open_s_min", "open_bridged", "vector_t",
        "refine_tol")),
    *(Field(name, "const double*") for name in ("coef", "extra_coef", "dense", "atol", "ts")),
    *(Field(name, "double*") for name in ("rows", "Y", "log")),
    *(Field(name, "double*", lambda d: 2 * d.f) for name in (
        "y", "fy", "y_old", "y_new", "f_new", "work")),
    Field("K", "double*", lambda d: 16 * 2 * d.f), Field("F", "double*", lambda d: 7 * 2 * d.f),
    Field("in", "double*", lambda d: 13), Field("out", "double*", lambda d: 5),
    Field("extra_in", "double*", lambda d: 7), Field("extra_out", "double*", lambda d: 2),
    Field("inverse", "double*", lambda d: d.r * d.r),
    Field("reduced", "double*", lambda d: d.r * d.f), Field("block", "double*", lambda d: 2),
    # the partition's end at the last step committed whole (a pending step's follows it)
    Field("kept_inverse", "double*", lambda d: d.r * d.r),
    Field("kept_reduced", "double*", lambda d: d.r * d.f),
    Field("kept_block", "double*", lambda d: 2),
    *(Field(name, "double*", lambda d: d.n) for name in ("q_new", "v_new")),
    *(Field(name, "double*", lambda d: d.f) for name in ("z", "z0")),
    *(Field(name, "double*", lambda d: d.r) for name in ("w", "wd", "w0")),
    Field("P", "double*", lambda d: d.r * (3 + d.f)),
    Field("measured", "double*", lambda d: 5 + d.m),
    *(Field(name, "double*", lambda d: d.m * d.n) for name in ("Jm", "Jc", "Jq",
                                                                "fall_work", "J_end")),
    *(Field(name, "double*", lambda d: 2 * d.m * d.n) for name in ("Js", "Ds", "Ps")),
    # the projection context's warm start of the monitor's SVD before the step's
    # observation (`keep_measures`): put back where the loop observes the step again
    Field("jacobi_kept", "int64"), Field("jacobi_open", "int64"),
    Field("jacobi_keep", "double*", lambda d: d.m * d.m),
    Field("fall_scalars", "double*", lambda d: 8), Field("known", "double*", lambda d: 6),
    # the passage search's grid and scratch (a `SEARCH` structure the segment owns), the
    # step's rate's context
    Field("search", "void*"), Field("rate_ctx", "void*"),
    Field("f_here", "double*", lambda d: 2 * d.f),
    # a step's end re-solved after a re-reference, and the partition before it
    Field("y_here", "double*", lambda d: 2 * d.f),
    *(Field(name, "double*", lambda d: d.n) for name in ("q_here", "v_here", "keep_q_ref")),
    Field("keep_P", "double*", lambda d: d.r * (3 + d.f)),
    Field("keep_C", "double*", lambda d: d.r * d.r), Field("keep_z", "double*", lambda d: d.f),
    Field("keep_w", "double*", lambda d: d.r),
    # a new partition's choice (`keeps_set`)
    Field("set_work", "double*", lambda d: d.m * d.n), Field("set_mark", "int64*", lambda d: d.n),
    Field("set_piv", "int*", lambda d: d.n),
    # the passages (`handles_passages`): the open one's singular vector and a step's
    # candidate, the latest measurement's, a dip's measurement and J̃ there, and the rows
    # recorded (t_start, t_end, s_min, t_min, bridged, vector set, vector)
    *(Field(name, "double*", lambda d: d.m) for name in ("open_u", "cand_u", "vector")),
    Field("dip_measured", "double*", lambda d: 5 + d.m),
    Field("dip_J", "double*", lambda d: d.m * d.n),
    Field("passages", "double*", lambda d: PASSAGES * (6 + d.m)),
])


# The engine's functions as ctypes calls them: argument codes, then ">" and the result's
# (p a pointer, d a double, l an int64_t, i an int, "-" none).
SIGNATURES = {
    "mechsim_lu_state": "pd>i", "mechsim_lu_accelerations": "pd>i", "mechsim_lu_rhs": "pd>i",
    "mechsim_lu_states": "plpppppp>i", "mechsim_lu_end": "pdppp>i",
    "mechsim_lu_predictor": "pdldppppppppp>-", "mechsim_lu_segment": "ppp>l",
    "mechsim_projection_segment": "pp>l", "mechsim_history": "pplpdpp>l",
    "mechsim_history_start": "ppp>i",
    "mechsim_projection_accelerations": "pddd>i", "mechsim_project_state": "pddddll>i",
    "mechsim_lu_condition": "pd>d", "mechsim_choose": "ppddpp>i", "mechsim_measure": "pddpp>i",
    "mechsim_inverse_norm_bound": "lpp>d", "mechsim_extreme_bounds": "plppp>-",
    "mechsim_bounds_of": "ppp>-",
    "mechsim_project_states": "plpppplp>-", "mechsim_chords": "plppp>-",
    "mechsim_extremes": "pllppp>i", "mechsim_dop853": "pll" + "p" * 11 + ">i",
    "mechsim_dop853_extra": "pll" + "p" * 7 + ">i", "mechsim_interpolate": "llpddplpp>-",
    "mechsim_change": "pdpp>d", "mechsim_fall_rates": "plll" + "p" * 9 + ">-",
    "mechsim_dense_coefficients": "lllpppppdp>-",
    "mechsim_passage_minimum": "pppdddp>i", "mechsim_anchored": "pppddlpl>i",
    "mechsim_multipliers": "plppppddppp>l",
    "mechsim_bridge_corrector": "pllppppl" + "pddd" + "pl" + "dd" + "p" * 5 + ">i",
    "mechsim_bridge_attempt": "pplppddldpplpdpl" + "p" * 7 + ">l",
    "mechsim_adams_values": "llpdpplplpppp>-",
}
_CODES = {"p": ctypes.c_void_p, "d": ctypes.c_double, "l": ctypes.c_int64, "i": ctypes.c_int,
          "-": None}


def declare(lib) -> None:
    """Set the argument and result types of the engine's functions in `lib` (`SIGNATURES`);
    AttributeError where one is missing."""
    for name, code in SIGNATURES.items():
        args, result = code.split(">")
        fn = getattr(lib, name)
        fn.argtypes, fn.restype = [_CODES[a] for a in args], _CODES[result]
