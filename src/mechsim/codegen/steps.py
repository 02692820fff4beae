"""The engine's side of consecutive plain steps (`mechsim_lu_segment`,
`mechsim_projection_segment`, `mechsim.run.segment`).

`PlainSteps` holds the structure `layout.SEGMENT` describes and the buffers it points to,
for one mechanism and one count of independent coordinates (all n of them for the
projection method's state [q; v]); `run` takes steps on a partition's and the monitor's
compiled contexts, `run_projection` the projection method's on its own. The dense algebra builds it
(`DenseAlgebra.plain_steps`); the run reads and writes its fields by name.
"""

from __future__ import annotations

import ctypes

import numpy as np
from scipy.integrate import DOP853

from ..integrators.compiled import MAX_FACTOR, MIN_FACTOR, SAFETY
from .layout import PASSAGES, SEGMENT, Dims

# Steps one call takes at most before Python looks in (progress, the stream).
BUDGET = 256
# DOP853's stages, its dense output's extra stages (rows, width) and matrix (rows,
# columns) and its error estimator's order, as scipy's class holds them.
_DOP853_SHAPE = (DOP853.n_stages, DOP853.A_EXTRA.shape, DOP853.D.shape,
                 DOP853.error_estimator_order)


class PlainSteps:
    """The structure (`s`, its fields by their C names), its buffers (`buffers`), the
    steps' log (`log`: t, h, |v|∞, the next step proposed, and for the projection method
    σ_min/σ_max and its rate as the passage bridge reads them, a row per step) and a step's
    samples' scratch (`Y`, at most `sample_rows` samples a step); `search`: the passage
    search's structure (`layout.SEARCH`) it shares with the engine."""

    def __init__(self, lib, n, m, f, sample_rows, tableaus, search):
        self.lib, self.shape = lib, (n, m, f)
        self.buffers = SEGMENT.buffers(Dims(n, m, f))
        self.log = np.zeros((BUDGET, 6))
        # the passage search's grid and scratch: the engine's (`StepSearch.search`),
        # so that the loop's search of a step a segment declined takes the segment's
        self.search = search
        self.Y = np.zeros((max(int(sample_rows), 1), 2 * f))
        coef, extra, dense = tableaus
        self._arrays = {**self.buffers, "coef": coef, "extra_coef": extra, "dense": dense,
                        "atol": np.zeros(1), "ts": np.zeros(1), "rows": np.zeros(1),
                        "Y": self.Y, "log": self.log}
        self.s = SEGMENT.make({"budget": BUDGET, "y_rows": len(self.Y), "passages_cap": PASSAGES,
                               "search": ctypes.addressof(self.search)}, self._arrays)
        self._address = ctypes.addressof(self.s)

    def point(self, name, array) -> None:
        """Point the structure's field `name` at `array` (kept alive here)."""
        self._arrays[name] = array
        setattr(self.s, name, array.ctypes.data)

    @property
    def declined(self) -> bool:
        """Whether the last call stopped on a step it declined (not on its budget or a
        step the runaway rule looks at after)."""
        return self.s.reason != 0

    def run(self, partition, projection) -> int:
        """Steps on the partition's and the monitor's compiled contexts (their addresses):
        how many were committed (`mechsim_lu_segment`)."""
        return int(self.lib.mechsim_lu_segment(partition, projection, self._address))

    def load_integrator(self, solver) -> None:
        """The state and settings of `solver` (a `CompiledDOP853`) into the structure: its
        tableau's sizes, t, h, bound, direction, max_step, tolerances, controller, y and
        f (its state's entries first in `y`, `fy`)."""
        b, N = self.buffers, solver.n
        self._integrator(solver.t, solver.h_abs, solver.t_bound, solver.direction,
                         solver.max_step, solver.rtol, solver.atol_array)
        b["y"][:N] = solver.y
        b["fy"][:N] = solver.f

    def start_integrator(self, t, t_bound, rtol, atol) -> None:
        """A DOP853 integrator at t towards t_bound with tolerances rtol and `atol` (an
        array of its state's size, kept alive here), no step limit, into the structure as
        `load_integrator` loads one that `CompiledDOP853` made, without its state, its
        rate there and its first step: the engine puts the state there and, for h_abs 0,
        finds the rate and the step (`mechsim_history`)."""
        self._integrator(t, 0.0, t_bound, 1.0 if t_bound >= t else -1.0, np.inf, rtol, atol)

    def _integrator(self, t, h_abs, t_bound, direction, max_step, rtol, atol) -> None:
        """A DOP853 integrator's settings (scipy's tableau's sizes and controller) into the
        structure, `atol` kept alive here."""
        s = self.s
        self.point("atol", atol)
        s.stages, (s.extra_rows, s.extra_width), (s.dense_rows, s.dense_cols), order = \
            _DOP853_SHAPE
        s.t, s.h_abs, s.t_bound, s.direction = t, h_abs, t_bound, direction
        s.max_step, s.rtol, s.exponent = max_step, rtol, -1.0 / (order + 1)
        s.safety, s.min_factor, s.max_factor = SAFETY, MIN_FACTOR, MAX_FACTOR

    def _rate(self, rate) -> None:
        """The bridge's compiled rate's min_rcond and cut into the structure."""
        s = self.s
        s.rate_rcond = s.min_rcond = rate.min_rcond
        s.cut = rate.cut

    def history(self, projection, rate, y, ts, budget):
        """The passage bridge's history in the engine (`mechsim_history`) on the
        projection context `projection` (its address) with `rate`'s min_rcond and cut,
        from the integrator `start_integrator` loaded, at the state y: (states (k, 2n) at
        the k times `ts`, the rates F (k + 1, 2n) at the integrator's start and at them,
        the rates the engine evaluated for the steps (and the first step), the chord
        iterations of the projections); None where the engine declined a stage, a
        projection or a rate (the caller's Python path takes the history), False where
        the integration failed or spent more than `budget` evaluations."""
        s, N = self.s, 2 * self.shape[0]
        self._rate(rate)
        s.evaluations = 0
        self.buffers["y"][:N] = y
        ts = np.ascontiguousarray(ts, dtype=float)
        states, F = np.empty((len(ts), N)), np.empty((len(ts) + 1, N))
        done = self.lib.mechsim_history(projection, self._address, len(ts), ts.ctypes.data,
                                        float(budget), states.ctypes.data, F.ctypes.data)
        if done < 0:
            return None if done == -1 else False
        return states, F, s.evaluations, s.projections

    def history_start(self, projection, rate, y):
        """The rate at y and the first step of the integrator `start_integrator` loaded,
        as `history` starts it (`mechsim_history_start`): (first step, rate (2n,), the
        rates evaluated), or None where the engine declined a rate."""
        s, N = self.s, 2 * self.shape[0]
        self._rate(rate)
        s.evaluations = 0
        self.buffers["y"][:N] = y
        f0 = np.empty(N)
        if self.lib.mechsim_history_start(projection, self._address, f0.ctypes.data):
            return None
        return s.h_abs, f0, s.evaluations + 1

    def corrector(self, projection, rate, y_n, F, weights, H, t_b, tolerances, iterations):
        """The passage bridge's corrector and order estimates in the engine
        (`mechsim_bridge_corrector`) on the projection context `projection` (its address)
        with `rate`'s min_rcond and cut: from y_n and the history's rates F (K x N), the
        step of H to t_b; `weights` = (prediction (K,), correction (K + 1,), the orders'
        (L, K + 1)), `tolerances` = (rtol, atol for each of the N entries). (f_b, the
        orders' ends (L, N), the norms of their differences (L − 1,), the rates evaluated,
        the chord iterations); None where the engine declined a projection or a rate."""
        w_pred, w_corr, W = (np.ascontiguousarray(w, dtype=float) for w in weights)
        F = np.ascontiguousarray(F, dtype=float)
        y_n = np.ascontiguousarray(y_n, dtype=float)
        rtol, atol = tolerances
        atol = np.ascontiguousarray(atol, dtype=float)
        K, N = F.shape
        L = len(W)
        work, counts, f_b = np.empty(3 * N), np.empty(2), np.empty(N)
        Y, errs = np.empty((L, N)), np.empty(max(L - 1, 1))
        if self.lib.mechsim_bridge_corrector(
                projection, N, K, y_n.ctypes.data, F.ctypes.data, w_pred.ctypes.data,
                w_corr.ctypes.data, L, W.ctypes.data, float(H), float(t_b), float(rtol),
                atol.ctypes.data, int(iterations), rate.min_rcond, rate.cut, work.ctypes.data,
                counts.ctypes.data, f_b.ctypes.data, Y.ctypes.data, errs.ctypes.data):
            return None
        return f_b, Y, errs[:L - 1].tolist(), int(counts[0]), int(counts[1])

    def attempt(self, projection, rate, ts, y, H, budget, row, edge2, weights, tolerances,
                iterations):
        """A passage bridge's attempt in the engine (`mechsim_bridge_attempt`) on the
        projection context `projection` (its address) with `rate`'s min_rcond and cut, the
        integrator `start_integrator` set up (its state left to the engine): the landing
        state y at ts[0] put onto the constraints, its history at ts[1:] (at most `budget`
        rates), and where σ_row/σ_max at the prediction of the step of H exceeds `edge2`
        the corrector and its orders' estimates, `weights` and `tolerances` as `corrector`
        takes them. (y settled, the states (k, 2n) at ts[1:], the rates F (k + 1, 2n) at
        ts, (f_b, the orders' ends, their estimates) or None where the prediction lies in
        the band, the counts: the landing state's chord iterations, the history's rates
        and chord iterations, the corrector's rates and chord iterations); -1 where the
        engine declines (the Python path takes the attempt), -2 where the history fails
        or grinds."""
        N = 2 * self.shape[0]
        self._rate(rate)
        w_pred, w_corr, W = (np.ascontiguousarray(w, dtype=float) for w in weights)
        ts = np.ascontiguousarray(ts, dtype=float)
        y = np.array(y, dtype=float)
        rtol, atol = tolerances
        atol = np.ascontiguousarray(atol, dtype=float)
        K, L = len(ts), len(W)
        work, counts, f_b = np.empty(3 * N), np.empty(5), np.empty(N)
        states, F = np.empty((K - 1, N)), np.empty((K, N))
        Y, errs = np.empty((L, N)), np.empty(max(L - 1, 1))
        done = self.lib.mechsim_bridge_attempt(
            projection, self._address, K, ts.ctypes.data, y.ctypes.data, float(H),
            float(budget), int(row), float(edge2), w_pred.ctypes.data, w_corr.ctypes.data, L,
            W.ctypes.data, float(rtol), atol.ctypes.data,
            int(iterations), work.ctypes.data, counts.ctypes.data, states.ctypes.data,
            F.ctypes.data, f_b.ctypes.data, Y.ctypes.data, errs.ctypes.data)
        if done < 0:
            return int(done)
        corrected = (f_b, Y, errs[:L - 1].tolist()) if done == 0 else None
        return y, states, F, corrected, counts.astype(int).tolist()

    def run_projection(self, projection) -> int:
        """Steps of the projection method on its compiled context (its address): how many
        were committed (`mechsim_projection_segment`)."""
        return int(self.lib.mechsim_projection_segment(projection, self._address))
