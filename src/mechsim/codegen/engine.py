"""The evaluations of small rigid mechanisms, compiled with the model's C twins.

An evaluation of "lu" or "qr" on a small rigid mechanism is about twenty small numpy and
LAPACK calls (the chord Newton on the dependent coordinates, Φ_q, the velocity solve, γ and
the reduced accelerations), each costing more in Python's call overhead than in arithmetic.
Here they run in one C function (`engine.c`), compiled with the model's C twins of Φ, Φ_q,
Φ_t and γ, with LAPACK taken from scipy's own (the pointers `scipy.linalg.cython_lapack`
exports). Python keeps the forces, which may be any user code.

It is the dense constraint algebra's implementation of its state-level operations
(`mechsim.problem.algebra.DenseAlgebra`, which builds and calls it; no formulation does):

- one coordinate partition's solver (`PartitionedEngine`, the algebra's
  `partition_solver`): the dependent coordinates and velocities of a state or of a
  step's samples, and the reduced accelerations;
- the projection method's accelerations (`ProjectionEngine.accelerations`, `rhs`): by the
  Cholesky factor of J W Jᵀ where LAPACK's condition estimate clears it, else by the SVD
  of J̃ where no singular value is under the truncation cut;
- the projection of a state onto the constraints (`project_state`), one Cholesky factor
  for the positions' chord Newton and the velocities;
- the singularity monitor's σ_min, σ_max and their rates (`measure`), its skip's bounds
  (`change`, `extreme_bounds`), and its passage search's grid: J̃'s chords between states and
  the extreme singular values at many (`chords`, `extremes`);
- the hybrid's test for a return to LU, cond₁ of the block LU pivots (`lu_condition`);
- the multipliers of many states (`multipliers`).

The compiled path takes only the plain case: a chord Newton converging by the same rules
as the Python path's (`mechsim.linalg.newton`, whose constants it is handed), a
nonsingular square Φ_q D and a positive definite Schur complement; for the projection
method, a state outside the truncation band. Anything else (a stalled chord
that needs fresh Jacobians, redundant constraints, Newton failing altogether, a singular
value under the cut) returns a status and the Python path takes the evaluation from the
start, so the two agree on every decision and differ only in the rounding of their sums.

The library is built beside the cached model module on first use (`library`), from the
model's C twins and its pattern kernels (`mechsim.codegen.kernels`) linked with the engine
compiled once per cache (`engine_object`), or from both compiled together where that
object cannot serve; without a compiler, with `MECHSIM_NO_COMPILE` set, or for a model
kept in memory only, there is none and the formulations take the Python path. The
structures both sides share, and the sizes of the buffers they point to, are described
once in `layout`.
"""

from __future__ import annotations

import contextlib
import ctypes
import functools
import hashlib
import threading
import weakref
from importlib import resources
from pathlib import Path

import numpy as np

from ..linalg.dense import fall_basis
from ..linalg.newton import CHORD_CONTRACTION, STALL_RATIO, STALL_SPAN
from .cache import adopt, env_flag, verified_file
from .compiled import build_library, compiler, compiler_identity, flags_digest, shared_library
from .kernels import KERNELS_VERSION, MODEL_DECLARATIONS, pattern_kernels
from .layout import (PARTITION, PROJECTION, SEARCH, SEARCH_KEY, SEGMENT, Dims, declare,
                     pair_pattern)
from .scratch import Scratch
from .search import StepSearch

# The engine's own C (shipped beside this module), after the declarations of the model's C
# twins it calls and the structures' typedefs (`layout`).
_ENGINE_C = "engine.c"
_HEADERS = "#include <float.h>\n#include <math.h>\n#include <stdint.h>\n#include <string.h>\n\n"


@functools.cache
def source() -> str:
    """The engine's C: headers, the declarations of the model's C twins it calls, the
    typedefs of `layout.PARTITION`, `layout.PROJECTION`, `layout.SEARCH` and
    `layout.SEGMENT` (with `layout.SEARCH_KEY`), and `engine.c`."""
    text = resources.files(__package__).joinpath(_ENGINE_C).read_text(encoding="utf-8")
    return (_HEADERS + MODEL_DECLARATIONS + f"#define MECHSIM_SEARCH_KEY {SEARCH_KEY}\n" +
            PARTITION.typedef() + "\n" + PROJECTION.typedef() + "\n" +
            SEARCH.typedef() + "\n" + SEGMENT.typedef() + "\n" + text)


def engine_object(directory: Path, command: list[str]) -> list[Path]:
    """[the engine's C compiled on its own with `command`], kept in `directory` (the cache)
    as `mechsim_engine-<digest>.o`, the digest of the source and the compiler's identity,
    verified as every entry; [] where it cannot be built. Each small model's library links
    it (`library`), so that a new mechanism compiles only its own functions
    (docs/benchmarks.md has the times). Where `prepare` started its compile, waits for
    that one and takes its outcome."""
    path = _object_path(directory, command)
    with _PREPARING_LOCK:
        pending = _PREPARING.pop(path, None)
    if pending is not None:
        thread, outcome = pending
        thread.join()
        if outcome:
            return outcome[0]
    return _compile_object(path, command)


def _object_path(directory: Path, command: list[str]) -> Path:
    tag = hashlib.sha256("\0".join([source(), compiler_identity(command), *command,
                                     flags_digest()]).encode()).hexdigest()[:16]
    return directory / f"mechsim_engine-{tag}.o"


def _compile_object(path: Path, command: list[str]) -> list[Path]:
    if verified_file(path):
        return [path]
    if build_library(source(), path, command, shared=False) is not None:
        return []
    try:
        adopt(path)
    except OSError:
        return []
    return [path]


# Engine objects being compiled in a thread (`prepare`): path -> (thread, [its outcome]).
_PREPARING: dict = {}
_PREPARING_LOCK = threading.Lock()


def prepare(directory: Path) -> None:
    """Start compiling the engine object into the cache `directory` in a thread, where
    compiling is on and the cache lacks it: the caller is about to derive a small rigid
    mechanism's model with sympy, and the C compiler then runs beside it (on another
    core) instead of after it; `engine_object` waits for it and takes its outcome. A
    process's first new mechanism pays for the engine's compile so (docs/benchmarks.md)."""
    if env_flag("MECHSIM_NO_COMPILE"):
        return
    command = compiler()
    path = _object_path(directory, command)
    with _PREPARING_LOCK:
        if path in _PREPARING or verified_file(path):
            return
        outcome: list = []
        thread = threading.Thread(target=lambda: outcome.append(_compile_object(path, command)),
                                  name="mechsim engine compile", daemon=True)
        _PREPARING[path] = (thread, outcome)
    thread.start()


def _lapack(name: str) -> int:
    """The address of scipy's LAPACK routine `name` (from its Cython capsule)."""
    from scipy.linalg import cython_lapack
    capsule = cython_lapack.__pyx_capi__[name]
    get_name = ctypes.pythonapi.PyCapsule_GetName
    get_name.restype, get_name.argtypes = ctypes.c_char_p, [ctypes.py_object]
    get_pointer = ctypes.pythonapi.PyCapsule_GetPointer
    get_pointer.restype, get_pointer.argtypes = ctypes.c_void_p, [ctypes.py_object,
                                                                  ctypes.c_char_p]
    return get_pointer(capsule, get_name(capsule))


def for_problem(problem):
    """The compiled engine for a NumericProblem whose evaluations it can take: constraints,
    a constant diagonal mass (no flexible bodies) and a constraint algebra whose arithmetic
    the engine mirrors (`compiles`: the dense one, not a long chain's banded one); None
    elsewhere or where there is no library."""
    if not problem.m or not problem.constant_mass or not problem.algebra.compiles:
        return None
    return library(problem.model)


def library_path(module_path: Path) -> Path:
    """Where the compiled evaluations of the model module at `module_path` are cached: the
    model's name with `.evaluations-<digest of the engine's C, the pattern kernels' version
    and the compile's FLAGS>.so`."""
    digest = hashlib.sha256("\0".join([source(), flags_digest(), str(KERNELS_VERSION)])
                            .encode()).hexdigest()[:12]
    return module_path.with_name(f"{module_path.stem}.evaluations-{digest}.so")


def why_not(problem) -> str:
    """Why `for_problem` gives no engine for a problem it does not take ("" if it takes it)."""
    if not problem.m:
        return "the mechanism has no constraints: nothing to compile"
    if not problem.constant_mass:
        return ("flexible bodies: the compiled evaluations take rigid mechanisms "
                "(constant diagonal mass) only")
    if not problem.algebra.compiles:
        return (f"the {problem.algebra.name} constraint algebra (a long chain's banded Schur "
                "complement, or one given) runs on the Python path")
    return ""


# The engine found for each generated module (None: none serves it), for the module's life.
_LIBRARIES: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()


def library(model):
    """The compiled engine for `model` (a generated module), or None where there is none."""
    if model in _LIBRARIES:
        return _LIBRARIES[model]
    _LIBRARIES[model] = None
    model_source = getattr(model, "C_SOURCE", None)
    path = getattr(model, "__file__", None)
    if not model_source or not path:
        return None
    target = library_path(Path(path))

    def own():           # the model's C with its pattern kernels, where a build needs it
        return model_source + "\n" + pattern_kernels(model, model.M, model.N)

    lib = shared_library(lambda: own() + source(), target,
                         (own, lambda command: engine_object(target.parent, command)))
    if lib is None:
        return None
    try:
        for name, layout in (("mechsim_sizeof_lu", PARTITION),
                             ("mechsim_sizeof_projection", PROJECTION),
                             ("mechsim_sizeof_search", SEARCH),
                             ("mechsim_sizeof_segment", SEGMENT)):
            fn = getattr(lib, name)
            fn.argtypes, fn.restype = [], ctypes.c_int64
            if fn() != ctypes.sizeof(layout.structure):
                return None        # the C and ctypes layouts disagree: the Python path serves
        routines = ("dgesv", "dpotrf", "dpocon", "dpotrs", "dgesdd", "dgetrf", "dlasq1")
        lib.mechsim_engine_init.argtypes = [ctypes.c_void_p] * len(routines)
        lib.mechsim_engine_init.restype = None
        lib.mechsim_engine_init(*map(_lapack, routines))
        declare(lib)
    except (OSError, AttributeError, KeyError):
        return None
    _LIBRARIES[model] = lib
    return lib


@contextlib.contextmanager
def python_path(model):
    """Within the block, runs of `model` take the Python path, as without a compiler (for
    comparisons of the two paths)."""
    missing = object()
    before = _LIBRARIES.get(model, missing)
    _LIBRARIES[model] = None
    try:
        yield
    finally:
        if before is missing:
            del _LIBRARIES[model]
        else:
            _LIBRARIES[model] = before


class PartitionedEngine:
    """One partition's compiled evaluation (`library`): the buffers the C side reads and
    writes, and the calls. `accept` loads an accepted step's predictor and chord factor;
    `state`, `states` and `accelerations` compute what `Partitioned.full_state`, its
    samples' solve and its q̈ solve compute, for the partition whose independent and
    dependent coordinates are `independent` and `dependent`."""

    def __init__(self, lib, problem, independent, dependent, newton_tol, max_newton,
                 rheonomic, round_off=None):
        n, m, f = problem.n, problem.m, len(independent)
        r = n - f
        self.f = f
        self.p = np.ascontiguousarray(problem.p, dtype=float)
        self.q_ref = np.zeros(n)
        self.P = np.zeros((r, 3 + f))
        self.C = np.zeros((r, m))
        self.winv = np.ascontiguousarray(problem.inverse_mass_diagonal, dtype=float)
        self.ind = np.ascontiguousarray(independent, dtype=np.int64)
        self.dep = np.ascontiguousarray(dependent, dtype=np.int64)
        self.y, self.out = np.zeros(2 * f), np.zeros(2 * f)
        self.q, self.v, self.Q = np.zeros(n), np.zeros(n), np.zeros(n)
        self.J, self.J_samples = np.zeros((m, n)), np.zeros((m, n))
        self.buffers = PARTITION.buffers(Dims(n, m, f))
        arrays = {**self.buffers, **{name: getattr(self, name) for name in (
            "p", "q_ref", "P", "C", "winv", "ind", "dep", "y", "q", "v", "J", "Q", "out")}}
        self.ctx = PARTITION.make(dict(
            n=n, m=m, f=f, max_newton=max_newton, rheonomic=int(rheonomic), fresh=0,
            newton_tol=newton_tol, chord_contraction=CHORD_CONTRACTION, t_last=0.0,
            stall_ratio=STALL_RATIO,
            stall_span=0.0 if round_off is None else round_off / newton_tol), arrays)
        self.context = ctypes.addressof(self.ctx)
        self._state, self._acc = lib.mechsim_lu_state, lib.mechsim_lu_accelerations
        self._rhs = lib.mechsim_lu_rhs
        self.lib = lib
        self._states = lib.mechsim_lu_states
        self._end = lib.mechsim_lu_end
        self._predictor, self._P_at = lib.mechsim_lu_predictor, self.P.ctypes.data
        self.last_z, self.last_w = self.buffers["z_last"][:f], self.buffers["w_last"][:r]
        self._inverse, self._reduced = np.zeros((n - f, n - f)), np.zeros((n - f, f))
        self._block = np.zeros(2)
        self._end_args = (self._inverse.ctypes.data, self._reduced.ctypes.data,
                          self._block.ctypes.data)
        self._scratch = Scratch()
        self._J_samples = self.J_samples.ctypes.data
        self.rates = {}          # the compiled rates made on it (`CompiledRate.of`)
        self.ready = False

    def accept(self, t, q_ref, P, chord_inverse, z, w):
        """The last accepted step: its time, the prediction's matrix, the inverse of Φ_q D
        there (None: not available, the Python path serves until the next step) and its
        independent and dependent coordinates."""
        if chord_inverse is None:
            self.ready = False
            return
        self.q_ref[:] = q_ref
        self.P[:] = P
        self.C[:] = chord_inverse
        self.last_z[:] = z
        self.last_w[:] = w
        self.ctx.t_last = t
        self.ready = True

    def predictor(self, t, z, zd, w, wd, prev, reduced, inverse, q_ref):
        """Load an accepted step (`accept`) whose Φ_q D the engine factored (`end`: its
        inverse and A⁻¹ Φ_q B `reduced`), the prediction's matrix formed in C from the
        state (z, ż, w, ẇ) at t and `prev` = (t0, z0, w0), the accepted state before it (or
        None): the same numbers as a step taken in a segment (`mechsim.run.segment`).
        Returns that matrix."""
        self.q_ref[:] = q_ref
        first = prev is None
        t0, z0, w0 = (t, z, w) if first else prev
        args = [np.ascontiguousarray(x, dtype=float) for x in (z, zd, w, wd, z0, w0, reduced,
                                                                 inverse)]
        self._predictor(self.context, t, int(first), t0, *(x.ctypes.data for x in args),
                        self._P_at)
        self.ready = True
        return self.P.copy()

    def state(self, t, y):
        """(q, v, Φ_q, n_fresh) of y = [z; ż] (n_fresh: the Newton iterations that took a
        fresh Φ_q D, as `Partitioned.full_state` counts them), or None where the Python
        path must decide."""
        self.y[:] = y
        if self._state(self.context, t):
            return None
        return self.q.copy(), self.v.copy(), self.J.copy(), int(self.ctx.fresh)

    def end(self, t, y):
        """What the end of a step needs (`Partitioned.keeps_branch`, `after_step`): the
        state as `state` gives it, then of A = Φ_q D there its inverse, A⁻¹ Φ_q B, the sign
        of det A and cond₁ A, from one factorization: (q, v, Φ_q, n_fresh, A⁻¹, A⁻¹ Φ_q B,
        sign, cond₁), or None where the Python path must decide."""
        self.y[:] = y
        if self._end(self.context, t, *self._end_args):
            return None
        sign, condition = self._block.tolist()
        return (self.q.copy(), self.v.copy(), self.J.copy(), int(self.ctx.fresh),
                self._inverse.copy(), self._reduced.copy(), int(sign), condition)

    def rhs(self, t, y, Q):
        """[ż; z̈] of y = [z; ż] under the applied forces Q in one call (`state`, then
        `accelerations`), or None where the Python path must decide. It leaves its state
        in the buffers, as `state` does."""
        self.y[:] = y
        self.Q[:] = Q
        if self._rhs(self.context, t):
            return None
        return self.out.copy()

    def accelerations(self, t, Q):
        """[ż; z̈] at the state the last successful `state` left in the buffers, with the
        applied forces Q there; None if the Schur complement is not positive definite."""
        self.Q[:] = Q
        if self._acc(self.context, t):
            return None
        return self.out.copy()

    def states(self, ts, Y):
        """(Q, V, signs) of the output samples (rows of Y at the times ts), signs those of
        det(Φ_q D) there (the partition's dependent columns in its order), or None."""
        scratch, k, n = self._scratch, len(ts), self.q.size
        Qs, at_Q = scratch.take("Q", k, n)
        Vs, at_V = scratch.take("V", k, n)
        signs, at_signs = scratch.take("signs", k)
        if self._states(self.context, k, scratch.put("t", ts), scratch.put("Y", Y, 2 * self.f),
                        at_Q, at_V, self._J_samples, at_signs):
            return None
        return Qs.copy(), Vs.copy(), signs.copy()


class ProjectionEngine:
    """The projection method's accelerations outside the truncation band (`library`): one
    call instead of Φ_q, γ, the mass scaling, the Cholesky factor of J̃J̃ᵀ with its
    condition estimate (or the SVD of J̃) in numpy and LAPACK; the projection of a state
    onto the constraints with one such factor (`project_state`); the singularity
    monitor's measurement (`measure`) and the hybrid's LU test (`lu_condition`)."""

    def __init__(self, lib, problem):
        n, m = problem.n, problem.m
        self.p = np.ascontiguousarray(problem.p, dtype=float)
        self.winv = np.ascontiguousarray(problem.inverse_mass_diagonal, dtype=float)
        self.y, self.Q, self.out = np.zeros(2 * n), np.zeros(n), np.zeros(2 * n)
        self.q, self.v = self.y[:n], self.y[n:]
        self.buffers = PROJECTION.buffers(Dims(n, m))
        self.measured, self.Jt = np.zeros(5 + m), np.zeros((m, n))
        # Views of the SVD's buffers `measure` reads its fall from: J̃ at (q + eps v,
        # t + eps), J̃'s right singular vectors (rows: U is column-major n × m), σ.
        self._ahead = self.buffers["J1"].reshape(m, n)
        self._right = self.buffers["U"].reshape(m, n)
        self._sig = self.buffers["sig"]
        self.wsqrt = np.sqrt(self.winv)
        self.pattern = pair_pattern(problem.model, m, n)
        pairs = len(self.pattern["pair_start"]) - 1
        arrays = {**self.buffers, **self.pattern, "p": self.p, "winv": self.winv,
                  "wsqrt": self.wsqrt, "q": self.q, "v": self.v, "Q": self.Q, "out": self.out}
        self.ctx = PROJECTION.make(dict(
            n=n, m=m, count=0, lwork=self.buffers["svd_work"].size,
            stall_ratio=STALL_RATIO, stall_span=STALL_SPAN,
            pairs=pairs, chol_ops=len(self.pattern["chol_start"]) - 1,
            kernels=int(pairs > 0)), arrays)
        self.n, self.m, self.lib = n, m, lib
        self.context = ctypes.addressof(self.ctx)
        self._fn = lib.mechsim_projection_accelerations
        self._project = lib.mechsim_project_state
        self._measure = lib.mechsim_measure
        self._chords = lib.mechsim_chords
        self._extremes = lib.mechsim_extremes
        self._extreme_bounds, self._bounds_of = lib.mechsim_extreme_bounds, lib.mechsim_bounds_of
        self.steps = StepSearch(lib, self.context, n, m)   # the monitor's search in a step
        self._project_many = lib.mechsim_project_states
        self._lu_condition, self._choose = lib.mechsim_lu_condition, lib.mechsim_choose
        self._choice, self._choice_J = np.zeros(n + 1, dtype=np.int64), np.zeros((m, n))
        self._choice_at, self._choice_J_at = self._choice.ctypes.data, self._choice_J.ctypes.data
        self._multipliers = lib.mechsim_multipliers
        self._change, self._fall_rates = lib.mechsim_change, lib.mechsim_fall_rates
        self._fall_in, self._fall_out, self._fall_work = np.zeros(8), np.zeros(2), np.zeros(m * n)
        self._fall_in_at, self._fall_out_at = self._fall_in.ctypes.data, self._fall_out.ctypes.data
        self._fall_work_at = self._fall_work.ctypes.data
        self.counters = problem.counters
        self._scratch = Scratch()
        self._measured_at, self._Jt_at = self.measured.ctypes.data, self.Jt.ctypes.data
        self.rates = {}          # the compiled rates made on it (`CompiledRate.of`)

    def adams_values(self, y_n, H, nodes, F, s, rule):
        """y_n + H (w(s) · F) at each fraction s of an Adams step of H over the rates F
        (rows) at `nodes` (`mechsim.integrators.adams.integration_weights`' w by the Gauss
        `rule` (points, weights) on [0, 1]): rows, one a fraction
        (`mechsim_adams_values`)."""
        scratch, (gx, gw) = self._scratch, rule
        K, N = F.shape
        out, at_out = scratch.take("adams_out", len(s), N)
        _, at_w = scratch.take("adams_w", 2 * K)
        self.lib.mechsim_adams_values(
            N, K, scratch.put("adams_y", y_n), float(H), scratch.put("adams_nodes", nodes),
            scratch.put("adams_F", F, N), len(s), scratch.put("adams_s", s), len(gx),
            scratch.put("adams_gx", gx), scratch.put("adams_gw", gw), at_w, at_out)
        return out.copy()

    def accelerations(self, t, q, v, Q, min_rcond, cut=0.0):
        """q̈ at (t, q, v) under the forces Q by the Cholesky factor of J W Jᵀ where it is
        positive definite and (min_rcond ≥ 0) its reciprocal condition estimate is above
        min_rcond; else, with cut > 0, by the SVD of J̃ where every singular value is
        above cut σ_max (truncation drops nothing); else None."""
        self.q[:], self.v[:] = q, v
        return None if self._evaluate(t, Q, min_rcond, cut) else self.out[self.n:].copy()

    def rhs(self, t, y, Q, min_rcond, cut=0.0):
        """`accelerations` as the right-hand side [v; q̈] at y = [q; v]."""
        self.y[:] = y
        return None if self._evaluate(t, Q, min_rcond, cut) else self.out.copy()

    def _evaluate(self, t, Q, min_rcond, cut):
        """[v; q̈] into `out` at the state in the buffers; nonzero where declined."""
        self.Q[:] = Q
        return self._fn(self.context, t, min_rcond, cut)

    def project_state(self, t, q, v, tol, min_rcond=-1.0, skip_tol=-1.0, extra=0, max_iter=8):
        """`NumericProblem.project_state` compiled: (q, v) with ‖Φ‖∞ ≤ tol (or at round-off;
        then `extra` further chord iterations) and Φ_q v + Φ_t = 0, by the chord Newton
        and velocity projection on one Cholesky factor of Φ_q M⁻¹ Φ_qᵀ at the given q.
        False where ‖Φ‖∞ ≤ skip_tol already (nothing done); None where the Python path
        must decide: the factor fails, its condition estimate is not above min_rcond
        (when min_rcond ≥ 0), or the chord does not converge in max_iter iterations."""
        self.q[:], self.v[:] = q, v
        status = self._project(self.context, t, skip_tol, tol, min_rcond, extra, max_iter)
        if status == 2:
            return False
        if status:
            return None
        self.counters.projections += self.ctx.count
        return self.q.copy(), self.v.copy()

    def forget(self):
        """The next `measure` from J̃ itself, not from the last SVD's rotation (a run's start)."""
        self.ctx.jacobi_warm = 0

    def measure(self, t, q, v=None, eps=0.0, fall=True):
        """The extreme singular values of J̃ = Φ_q M^{-1/2} at (q, t) and, with eps > 0,
        their rates along v (from J̃ at (q + eps v, t + eps)): (σ_min, σ_max, σ̇_min,
        σ̇_max, left singular vector of σ_min, J̃, ‖dJ̃/dt‖_F (0 without eps), fall (with
        eps and `fall`: (dJ̃/dt, `fall_basis`), else None)); None where the SVD fails.
        Needs m ≤ n (else σ_min is 0 by count)."""
        self.q[:] = q
        if eps > 0.0:
            self.v[:] = v
        out = self.measured
        if self._measure(self.context, t, eps, self._measured_at, self._Jt_at):
            return None
        smin, smax, dmin, dmax = out[:4].tolist()
        got = None
        if fall and eps > 0.0 and smax > 0.0:
            # `ConstraintAlgebra.measure`'s `fall`, from what dgesdd (σ, V) and the rate's
            # second Jacobian (J̃ at q + eps v) left in the buffers
            rates = self._ahead - self.Jt
            rates *= 1.0 / eps
            got = (rates, fall_basis(self._sig, self._right.T, len(self._sig) - 1))
        return (smin, smax, dmin, dmax, out[4:-1].copy(), self.Jt.copy(), float(out[-1]),
                got)

    def change(self, t, q, Jm):
        """(J̃ at (q, t), ‖J̃ − Jm‖_F) for Jm of J̃'s shape (C-contiguous floats)."""
        self.q[:] = q
        change = self._change(self.context, t, Jm.ctypes.data, self._Jt_at)
        return self.Jt.copy(), change

    def fall_rates(self, a, b):
        """`mechsim.linalg.dense.fall_rates` of the ends a and b (`Fall`s whose J, D and
        P are C-contiguous floats of this mechanism's sizes), in one call."""
        inputs = self._fall_in
        inputs[:] = (a.t, b.t, a.smin, a.smax, a.rise, b.smin, b.smax, b.rise)
        self._fall_rates(self.context, self.m, self.n, a.P.shape[1], self._fall_in_at,
                         a.J.ctypes.data, a.D.ctypes.data, a.P.ctypes.data, b.J.ctypes.data,
                         b.D.ctypes.data, b.P.ctypes.data, self._fall_work_at,
                         self._fall_out_at)
        return self._fall_out[0], self._fall_out[1]

    def project_states(self, T, Q, V, tols, max_iter=8):
        """`project_state` of each state (T[i], Q[i], V[i]) to tols[i] in one call, Q and V
        (C-contiguous float arrays) changed in place: (k,) status, 0 projected, 2 within
        its tolerance already, 1 declined (left for the Python path)."""
        scratch = self._scratch
        status = np.empty(len(T), dtype=np.int64)
        self._project_many(self.context, len(T), scratch.put("T", T), Q.ctypes.data,
                           V.ctypes.data, scratch.put("tols", tols), max_iter,
                           status.ctypes.data)
        self.counters.projections += int(np.count_nonzero(status == 0))
        return status

    def chords(self, T, Q):
        """Bounds of ‖J̃ᵢ₊₁ − J̃ᵢ‖₂ between consecutive states (T[i], Q[i]), shape (k − 1,)
        (`mechsim.problem.algebra.chord_bound`)."""
        scratch, k = self._scratch, len(T)
        out, at_out = scratch.take("chords", max(k - 1, 0))
        self._chords(self.context, k, scratch.put("T", T), scratch.put("Q", Q, self.n),
                     at_out)
        return out.copy()

    def extremes(self, T, Q, k):
        """(σ_k, σ_max) of J̃ at each state (T[i], Q[i]), shape (len(T), 2); None where an
        SVD fails."""
        scratch = self._scratch
        out, at_out = scratch.take("extremes", len(T), 2)
        if self._extremes(self.context, len(T), k, scratch.put("T", T),
                          scratch.put("Q", Q, self.n), at_out):
            return None
        return out.copy()

    def extreme_bounds(self, T, Q):
        """Bounds of σ_min and σ_max of J̃ at each state (T[i], Q[i]) without an SVD, shape
        (len(T), 2): a lower bound of σ_min, an upper bound of σ_max (the passage search's
        floor anchors: from the Cholesky factor of J̃J̃ᵀ, within m^(1/8) of each); NaN
        where J̃J̃ᵀ is too ill-conditioned for them (the search measures there)."""
        scratch = self._scratch
        out, at_out = scratch.take("bounds", len(T), 2)
        self._extreme_bounds(self.context, len(T), scratch.put("T", T),
                             scratch.put("Q", Q, self.n), at_out)
        return out.copy()

    def bounds_of(self, J):
        """`extreme_bounds` of J̃ itself (C-contiguous floats of its shape), shape (2,)."""
        out = np.empty(2)
        self._bounds_of(self.context, J.ctypes.data, out.ctypes.data)
        return out

    def multipliers(self, T, Q, V, F, min_rcond, min_pivot, lam, phi_t=None):
        """λ at the states (T[i], Q[i], V[i]) under the applied forces F[i] into the rows
        of `lam` (N, m), where the Cholesky factor of S = J W Jᵀ has a condition estimate
        above min_rcond (min_rcond < 0: not estimated) and every pivot is above min_pivot
        max Sᵢᵢ; returns (N,) bool, where it did (`mechsim.problem.multipliers`). `phi_t`
        (N, m, C-contiguous floats), if given, gets Φ_t at every state."""
        T = np.ascontiguousarray(T, dtype=float)
        Q, V, F = (np.ascontiguousarray(x, dtype=float) for x in (Q, V, F))
        out = np.zeros(lam.shape)
        done = np.zeros(len(T), dtype=np.int64)
        self._multipliers(self.context, len(T), T.ctypes.data, Q.ctypes.data, V.ctypes.data,
                          F.ctypes.data, min_rcond, min_pivot, out.ctypes.data,
                          done.ctypes.data, None if phi_t is None else phi_t.ctypes.data)
        ok = done.astype(bool)
        lam[ok] = out[ok]
        return ok

    def choice(self, J, eps, rank_factor):
        """(rank, pivots) of Φ_q = J for `Partitioned.choose` in one call (`mechsim_choose`:
        `rank`'s singular values, `pivots`' LU of Jᵀ); None where a factorisation fails."""
        self._choice_J[:] = J
        at, n = self._choice_at, self.n
        failed = self._choose(self.context, self._choice_J_at, eps, rank_factor, at, at + 8 * n)
        return None if failed else (int(self._choice[n]), self._choice[:n].copy())

    def lu_condition(self, t, q):
        """cond₁ of the dependent block Φ_q D that LU partitioning (`Partitioned.choose`)
        picks at (q, t), for Φ_q of full row rank; inf where it is singular."""
        self.q[:] = q
        return self._lu_condition(self.context, t)
