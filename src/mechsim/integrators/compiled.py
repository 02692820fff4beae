"""scipy's DOP853 with its steps taken in the compiled engine where the rate is compiled.

A run's steps on a small rigid mechanism spend most of their time around the rate, not in
it: twelve stages a step, each a Python call through scipy's wrappers, the formulation and
the engine for a few microseconds of compiled work. `CompiledDOP853` is scipy's class,
with its dense output, state and interface unchanged; where the formulation says its rate
is one compiled call at every state of the step (`Formulation.compiled_rate`: rigid
bodies, the engine built, the applied forces constant), the whole step (stages, error
norm, step-size rule, rejections) runs in `mechsim_dop853`, the engine's transcription of
scipy's `_step_impl` on the coefficients and controller constants scipy's own class
holds. A stage the engine declines (a state near a passage's band, a Newton that does
not converge) is evaluated by the formulation's Python rate, called back from C, as
scipy's step would have; where that raises, nothing is kept and scipy's Python step takes
the step (and raises). The two paths sum the stages in different orders, so their numbers
agree to round-off, not bit for bit.
"""

from __future__ import annotations

import copy
import ctypes
import functools

import numpy as np
from scipy.integrate import DOP853, DenseOutput

try:            # scipy's step-size controller's constants (scipy 1.12 to 1.17 keep them here)
    from scipy.integrate._ivp.rk import MAX_FACTOR, MIN_FACTOR, SAFETY
except ImportError:                       # moved: scipy's own steps serve
    MAX_FACTOR = MIN_FACTOR = SAFETY = None
try:            # scipy's DOP853 interpolant (`Interpolant.of`)
    from scipy.integrate._ivp.rk import Dop853DenseOutput
except ImportError:                       # moved: scipy's own interpolants serve
    Dop853DenseOutput = None
try:            # scipy's first step (`CompiledDOP853.set_up`; its arguments by name)
    from scipy.integrate._ivp.common import select_initial_step
except ImportError:                       # moved: scipy's own set-up serves
    select_initial_step = None


# The Python rate the engine calls back for a stage it declines: (t, y, f) -> 0 when done.
_RATE = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_double, ctypes.POINTER(ctypes.c_double),
                         ctypes.POINTER(ctypes.c_double))


@functools.lru_cache(maxsize=None)
def extra_tableau() -> np.ndarray:
    """scipy's DOP853 dense output's extra stages as the engine reads them: their rows of
    A_EXTRA, then their nodes C_EXTRA."""
    return np.ascontiguousarray(np.concatenate([np.asarray(DOP853.A_EXTRA, float).ravel(),
                                                np.asarray(DOP853.C_EXTRA, float)]))


@functools.lru_cache(maxsize=None)
def dense_matrix() -> np.ndarray:
    """scipy's DOP853 dense output matrix D (its interpolant's coefficients from the
    stages) as the engine reads it."""
    return np.ascontiguousarray(DOP853.D, dtype=float)


@functools.lru_cache(maxsize=None)
def tableau() -> np.ndarray:
    """scipy's DOP853 tableau as the engine reads it: A (S × S), B, C, E3, E5."""
    S = DOP853.n_stages
    return np.ascontiguousarray(np.concatenate([
        np.asarray(DOP853.A, float)[:S, :S].ravel(), np.asarray(DOP853.B, float)[:S],
        np.asarray(DOP853.C, float)[:S], np.asarray(DOP853.E3, float)[:S + 1],
        np.asarray(DOP853.E5, float)[:S + 1]]))


@functools.lru_cache(maxsize=None)
def _address(table) -> int:
    """The address of the array `table()` gives (a cached tableau: it lives as long)."""
    return table().ctypes.data


class CompiledDOP853(DOP853):
    """scipy's DOP853; `rate` (set by the run: a callable giving the formulation's
    `CompiledRate` for the next step, or None) moves a step into the engine (module
    docstring)."""

    rate = None

    def __init__(self, fun, t0, y0, t_bound, f0=None, **options):
        """scipy's DOP853; `f0`: fun(t0, y0) where the caller has it (bit for bit what fun
        gives there), taken instead of evaluating it again."""
        if not (_SET_UP.verified() and self.set_up(fun, t0, y0, t_bound, f0=f0,
                                                   **options)):
            super().__init__(fun, t0, y0, t_bound, **options)
        self._atol = np.empty(self.n)           # the engine's copy of atol (`atol_array`)
        self._atol[:] = self.atol
        self._step_args = None                  # the engine's buffers, made on first use
        self._raised = None
        self._taken = None          # the rate the last step was taken on (None: scipy's)

    def _buffers(self) -> None:
        """The buffers the engine reads and writes when it takes this integrator's own
        steps or dense output: views of one array, whose address is taken once (an
        array's `.ctypes.data` costs more than copying a small state in and out). Made on
        first use: an integrator is made at every restart and crossing, and most of them
        step only in segments or in the bridge's history, which hold their own."""
        n = self.n
        buffer = np.zeros(25 + 5 * n)
        self._in, self._extra_in, self._out = buffer[:13], buffer[13:20], buffer[20:25]
        self._work, self._y, self._f, self._y_new, self._f_new = buffer[25:].reshape(5, n)
        self._fallback = _RATE(self._python_rate)
        base, stages = buffer.ctypes.data, self.K_extended.ctypes.data   # K: its first rows
        fallback = ctypes.cast(self._fallback, ctypes.c_void_p)
        at = [base + 8 * (25 + i * n) for i in range(5)]       # work, y, f, y_new, f_new
        self._step_args = (_address(tableau), base, at[1], at[2], self._atol.ctypes.data,
                           stages, at[3], at[4], at[0], base + 8 * 20, fallback)
        self._extra_args = (_address(extra_tableau), base + 8 * 13, at[1], stages, at[0],
                            base + 8 * 20, fallback)

    def set_up(self, fun, t0, y0, t_bound, rtol=1e-3, atol=1e-6, max_step=np.inf,
                first_step=None, f0=None) -> bool:
        """scipy's own set-up (`OdeSolver`, `RungeKutta`, `DOP853`: the same attributes,
        the same numbers; `_SET_UP` checked it against the installed scipy) without its
        argument checks, for what a run passes: a finite float64 state, a scalar rtol
        above scipy's floor, a non-negative scalar atol, a positive max_step and a first
        step within the interval. False where anything else is asked (scipy's own set-up
        then checks it, warns and raises as it does): an integrator is made at every
        restart and crossing, and the checks cost as much as the rest of it. `f0`: the rate
        at (t0, y0), where the caller has it."""
        if type(y0) is not np.ndarray or y0.dtype != np.float64 or y0.ndim != 1 or \
                not isinstance(rtol, float) or not rtol >= 100 * np.finfo(float).eps or \
                not isinstance(atol, float) or not atol >= 0.0 or not max_step > 0.0 or \
                not (first_step is None or 0.0 < first_step <= abs(t_bound - t0)) or \
                not np.isfinite(y0).all():
            return False
        self.t_old, self.t, self.y, self.t_bound = None, t0, y0, t_bound

        def wrapped(t, y):                     # check_arguments' wrapper
            return np.asarray(fun(t, y), dtype=float)

        def vectorized(t, y):
            f = np.empty_like(y)
            for i, yi in enumerate(y.T):
                f[:, i] = self._fun(t, yi)
            return f

        def counted(t, y):
            self.nfev += 1
            return self.fun_single(t, y)
        self._fun, self.vectorized = wrapped, False
        self.fun, self.fun_single, self.fun_vectorized = counted, wrapped, vectorized
        self.direction = np.sign(t_bound - t0) if t_bound != t0 else 1
        self.n, self.status = y0.size, "running"
        self.nfev = self.njev = self.nlu = 0
        self.y_old, self.max_step = None, max_step
        self.rtol, self.atol = rtol, np.asarray(atol)
        self.f = self.fun(t0, y0) if f0 is None else np.array(f0, dtype=float)
        if first_step is None:
            self.h_abs = _SET_UP.first_step(self, t_bound, max_step)
        else:
            self.h_abs = first_step
        self.K_extended = np.empty((_SET_UP.stages, self.n))
        self.K = self.K_extended[:self.n_stages + 1]
        self.error_exponent = -1 / (self.error_estimator_order + 1)
        self.h_previous = None
        return True

    @property
    def atol_array(self) -> np.ndarray:
        """atol for every component, as the engine reads it (its address is stable)."""
        return self._atol

    def stepped_in_engine(self, compiled, t, t_old, h_abs, h_previous, y, f, y_old, K,
                          evaluations) -> None:
        """Steps taken in the engine elsewhere on `compiled` (`mechsim.run.segment`): the
        state after the last of them, as `step` would leave it (finished at `t_bound`), its
        stages K (the dense output's included), and the rates they evaluated counted."""
        self.t, self.t_old, self.h_abs, self.h_previous = t, t_old, h_abs, h_previous
        self.y, self.f, self.y_old = y, f, y_old
        self.K_extended[:] = K
        self._taken = compiled
        self._after(evaluations, compiled)
        if self.direction * (self.t - self.t_bound) >= 0:
            self.status = "finished"

    def tolerances_changed(self):
        """Renew the engine's copy of atol after `atol` was set (`adapters.retune`)."""
        self._atol[:] = np.broadcast_to(np.asarray(self.atol, float), self.y.shape)

    def _python_rate(self, t, y, f):
        """The callback: scipy's own call of the rate (counted in nfev) at a state the
        engine declined; 1 where it raised (kept for `_after`)."""
        try:
            np.ctypeslib.as_array(f, (self.n,))[:] = self.fun(
                t, np.ctypeslib.as_array(y, (self.n,)).copy())
            return 0
        except BaseException as exc:            # noqa: BLE001 (re-raised after the call)
            self._raised = exc
            return 1

    def _after(self, engine_evaluations, compiled) -> None:
        """Count the engine's evaluations; re-raise an interrupt the callback caught (an
        error is left to the Python step, which takes the step again and raises it)."""
        self.nfev += engine_evaluations
        compiled.counted(engine_evaluations)
        raised, self._raised = self._raised, None
        if isinstance(raised, (KeyboardInterrupt, SystemExit)):
            raise raised

    def step(self):
        """scipy's `step`, the step taken in the engine where `rate` gives it (module
        docstring); scipy's own where not, or where the Python rate raised in it."""
        self._taken = None
        compiled = self.rate() if self.rate is not None else None
        if compiled is None or SAFETY is None or self.status != "running" or self.n == 0 or \
                self.t == self.t_bound or self.y.dtype != np.float64:
            return super().step()
        t, y = self.t, self.y
        if self._step_args is None:
            self._buffers()
        self._y[:] = y
        self._f[:] = self.f
        self._in[:] = (DOP853.n_stages, t, self.h_abs, self.t_bound, self.direction,
                       self.max_step, self.rtol, compiled.min_rcond, compiled.cut,
                       SAFETY, MIN_FACTOR, MAX_FACTOR, self.error_exponent)
        status = compiled.step(compiled.context, compiled.kind, self.n, *self._step_args)
        self._after(int(self._out[3]), compiled)
        if status == 1:
            return super().step()
        if status == 2:
            self.status = "failed"
            return self.TOO_SMALL_STEP
        t_new, h, h_abs = self._out[:3].tolist()
        self._taken = compiled
        self.h_previous, self.y_old, self.t_old = h, y, t
        self.t, self.y, self.h_abs, self.f = t_new, self._y_new.copy(), h_abs, \
            self._f_new.copy()
        if self.direction * (self.t - self.t_bound) >= 0:
            self.status = "finished"
        return None

    def dense_output(self):
        """scipy's interpolant of the step just taken (`Interpolant`), where that step was
        taken in the engine (on its rate) with its three extra stages and its coefficients
        formed there too (`mechsim_dense_coefficients`: scipy's formulas, their sums in
        another order), by scipy's own construction where not."""
        compiled = self._taken
        if compiled is None or self.t == self.t_old:
            return Interpolant.of(super().dense_output())
        if self._step_args is None:
            self._buffers()
        rows, width = DOP853.A_EXTRA.shape
        self._extra_in[:] = (self.n_stages + 1, rows, width, self.t_old, self.h_previous,
                             compiled.min_rcond, compiled.cut)
        self._y[:] = self.y_old
        failed = compiled.extra(compiled.context, compiled.kind, self.n, *self._extra_args)
        self._after(int(self._out[0]), compiled)
        if failed:
            return Interpolant.of(super().dense_output())
        rows, cols = self.D.shape
        F = np.empty((rows + 3, self.n))
        y_old, y, f = (np.ascontiguousarray(x, dtype=float) for x in (self.y_old, self.y,
                                                                       self.f))
        compiled.coefficients(self.n, rows, cols, dense_matrix().ctypes.data,
                              self.K_extended.ctypes.data, y_old.ctypes.data, y.ctypes.data,
                              f.ctypes.data, self.h_previous, F.ctypes.data)
        return Interpolant(self.t_old, self.t, y_old, F, compiled.interpolate)


class _ScipySetUp:
    """Whether `CompiledDOP853.set_up` sets an integrator up as the installed scipy's
    DOP853 does: decided once, on a probe made both ways (the same attributes, the same
    values, the same evaluations counted; with scipy's first step and with a given one),
    else scipy's own set-up serves every integrator. `first_step`: scipy's
    `select_initial_step`, its arguments passed by name (their order differs between
    scipy versions)."""

    def __init__(self):
        self._verified = None
        self.stages = 0

    def first_step(self, solver, t_bound, max_step) -> float:
        known = {"fun": solver.fun, "t0": solver.t, "y0": solver.y, "t_bound": t_bound,
                 "max_step": max_step, "f0": solver.f, "direction": solver.direction,
                 "order": solver.error_estimator_order, "rtol": solver.rtol,
                 "atol": solver.atol}
        return select_initial_step(**{name: known[name] for name in self._names})

    def verified(self) -> bool:
        if self._verified is None:
            self._verified = False
            try:
                self._verified = self._check()
            except Exception:                   # noqa: BLE001 (any difference: scipy's)
                self._verified = False
        return self._verified

    def _check(self) -> bool:
        import inspect
        if select_initial_step is None:
            return False
        self._names = list(inspect.signature(select_initial_step).parameters)
        known = {"fun", "t0", "y0", "t_bound", "max_step", "f0", "direction", "order",
                 "rtol", "atol"}
        if not set(self._names) <= known:
            return False
        self.stages = DOP853(lambda t, y: y, 0.0, np.ones(1), 1.0).K_extended.shape[0]
        rates = np.array([-1.0, 2.0, -0.5, 3.0])
        for options in ({"rtol": 1e-6, "atol": 1e-9, "max_step": 0.05},
                        {"rtol": 1e-4, "atol": 1e-7, "first_step": 0.01}):
            y0 = np.array([1.0, -2.0, 0.5, 4.0])
            ours = object.__new__(CompiledDOP853)
            if not ours.set_up(lambda t, y: rates * y + t, 0.0, y0, 2.0, **options):
                return False
            theirs = DOP853(lambda t, y: rates * y + t, 0.0, y0.copy(), 2.0, **options)
            a, b = vars(ours), vars(theirs)
            if set(a) != set(b):
                return False
            for key, value in b.items():
                mine = a[key]
                if callable(value):
                    continue
                if isinstance(value, np.ndarray):
                    if not (isinstance(mine, np.ndarray) and mine.shape == value.shape and
                            mine.dtype == value.dtype and
                            (key in ("K", "K_extended") or np.array_equal(mine, value))):
                        return False
                elif type(mine) is not type(value) or not (mine == value or
                                                           (mine is None and value is None)):
                    return False
        return True


_SET_UP = _ScipySetUp()


class Interpolant(DenseOutput):
    """scipy's DOP853 interpolant (coefficients F over the step from t_old to t), evaluated
    in the same operations in the same order as scipy's (the same numbers to the bit)
    without its zeroed start and per-term bookkeeping: the samples, the work integral,
    the passage search and the bridge's history call it several times a step. `kernel`,
    where given, is the engine's `mechsim_interpolate`, which evaluates it in C (the same
    operations in the same order: the same numbers) in one call for all the times."""

    @classmethod
    def of(cls, dense):
        """The interpolant `dense` (scipy's DOP853 one as `Interpolant`; any other as is)."""
        if Dop853DenseOutput is None or type(dense) is not Dop853DenseOutput:
            return dense
        return cls(dense.t_old, dense.t, dense.y_old, dense.F)

    def __init__(self, t_old, t, y_old, F, kernel=None):
        super().__init__(t_old, t)
        self.h, self.F, self.y_old = t - t_old, F, y_old
        self._reversed = F[::-1]
        self._kernel = None
        # Whether C may read it as it stands (`mechsim_interpolate`, `coefficients`).
        self._in_c = isinstance(F, np.ndarray) and F.ndim == 2 and F.dtype == np.float64 and \
            F.flags.c_contiguous and isinstance(y_old, np.ndarray) and \
            y_old.dtype == np.float64 and y_old.flags.c_contiguous and \
            y_old.shape == F.shape[1:] and self.h != 0.0
        if kernel is not None and self._in_c:
            # Its arguments' addresses taken once (kept alive by this object's F, y_old).
            self._kernel = (kernel, F.shape[1], F.shape[0], F.ctypes.data, float(t_old),
                            float(self.h), y_old.ctypes.data)

    @property
    def coefficients(self):
        """(t_old, h, y_old, F): the interpolant as the engine evaluates it
        (`mechsim_interpolate`), for searches over the step in C; None where C cannot read
        its arrays as they stand."""
        return (self.t_old, self.h, self.y_old, self.F) if self._in_c else None

    def _call_impl(self, t):
        """y at t (0-d: shape (n,)) or at each of the times t (1-d: shape (n, len(t)))."""
        if self._kernel is not None:
            kernel, n, rows, at_F, t_old, h, at_y_old = self._kernel
            ts = np.ascontiguousarray(t, dtype=np.float64)
            Y = np.empty((ts.size, n))
            kernel(n, rows, at_F, t_old, h, at_y_old, ts.size, ts.ctypes.data, Y.ctypes.data)
            return Y.T if t.ndim else Y[0]
        x = (t - self.t_old) / self.h
        if t.ndim:
            x = x[:, None]
        u, R = 1 - x, self._reversed
        y = (R[0] + 0.0) * x                 # scipy's: y = 0; y += F[-1]; y *= x
        for i in range(1, len(R)):
            y += R[i]
            y *= u if i % 2 else x
        y += self.y_old
        return y.T


class CompiledRate:
    """What `mechsim_dop853` needs of a formulation for one step: the engine's step
    function (`step`) and its dense output's (`extra`, `coefficients`, `interpolate`), the context (its
    address) and `kind` (0 projection, 1 partition), the projection's `min_rcond` and
    `cut`, and `counted(evaluations)`, which books the stages as the formulation's own
    right-hand sides."""

    __slots__ = ("step", "extra", "coefficients", "interpolate", "context", "kind",
                 "min_rcond", "cut", "counted")

    def __init__(self, lib, context: int, kind: int, counted, min_rcond=-1.0, cut=0.0):
        self.step, self.extra = lib.mechsim_dop853, lib.mechsim_dop853_extra
        self.coefficients = lib.mechsim_dense_coefficients
        self.interpolate = lib.mechsim_interpolate
        self.context, self.kind, self.counted = context, kind, counted
        self.min_rcond, self.cut = float(min_rcond), float(cut)

    @classmethod
    def of(cls, engine, kind: int, counted, min_rcond=-1.0, cut=0.0) -> "CompiledRate":
        """The rate on `engine` (its `lib` and `context`) with these settings: one object
        per engine and settings, kept in the engine's `rates` (a run asks for it at every
        step), so shared: never changed (`counting` gives a changed copy)."""
        key = (kind, counted, float(min_rcond), float(cut))
        rate = engine.rates.get(key)
        if rate is None:
            rate = engine.rates[key] = cls(engine.lib, engine.context, kind, counted,
                                           min_rcond, cut)
        return rate

    def counting(self, counted) -> "CompiledRate":
        """A copy of this rate whose evaluations `counted` books instead."""
        other = copy.copy(self)
        other.counted = counted
        return other


__all__ = ["CompiledDOP853", "CompiledRate"]
