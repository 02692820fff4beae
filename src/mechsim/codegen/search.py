"""The singularity monitor's search for a passage inside a step, in the compiled engine
(`mechsim_anchored`, `mechsim_passage_minimum`): `StepSearch` holds the search's
structure (`layout.SEARCH`), which the engine's segments share (`mechsim.codegen.steps`),
so that the loop's search of a step a segment declined takes the segment's.
"""

from __future__ import annotations

import ctypes

import numpy as np

from .layout import NODES, SEARCH, Dims


class StepSearch:
    """The search on the projection context `projection` (its address) of a mechanism of
    n coordinates and m constraint equations; `search` the structure."""

    def __init__(self, lib, projection, n, m):
        self.projection, self.n = projection, n
        self._minimum, self._anchored = lib.mechsim_passage_minimum, lib.mechsim_anchored
        self.buffers = SEARCH.buffers(Dims(n, m))
        self._out = np.zeros(1)                           # F, y_old: set per call
        self.search = SEARCH.make({"n": n, "m": m, "nodes_cap": NODES},
                                  {**self.buffers, "F": self._out, "y_old": self._out})
        self._address = ctypes.addressof(self.search)
        self._ends = np.zeros(4)
        self._ends_at = self._ends.ctypes.data

    def passage_minimum(self, lu_context, dense, ta, tb, k, xatol):
        """(t, s) at the least of s = σ_k/σ_max of J̃ over [ta, tb] inside a step (Brent's
        bounded search, `mechsim_passage_minimum`), the states from `dense` (an
        `Interpolant`: its `coefficients` over the step), the positions solved on the
        partition whose engine context is `lu_context`, or q = y[:n] where it is None;
        None where a state or an SVD declined (the caller searches in Python)."""
        t_old, h, y_old, F = dense.coefficients
        N = F.shape[1]
        work = np.empty(N + self.n)
        out = np.empty(2)
        if self._minimum(lu_context, self.projection, N, F.shape[0], F.ctypes.data,
                         float(t_old), float(h), y_old.ctypes.data, k,
                         float(ta), float(tb), float(xatol), work.ctypes.data, out.ctypes.data):
            return None
        return float(out[0]), float(out[1])

    def anchored(self, lu_context, dense, ends, budget, known, k, search):
        """`SingularityMonitor._anchored` in one call (`mechsim_anchored`): {t: (σ_k, σ_max)}
        measured over the step `ends` = (t0, t1) of `dense` (as `passage_minimum`), `known`
        the ends' measurements (time -> (σ_k, σ_max)), `search` = (grid, chord, enter,
        leave, apart, open at the start) as the monitor's; None where a state or an SVD
        declined or the grid outgrew `layout.NODES` nodes (the caller searches in
        Python)."""
        t0, t1 = ends
        t_old, h, y_old, F = dense.coefficients
        grid, chord, enter, leave, apart, open_at_start = search
        w = self.search
        w.grid, w.kk, w.N, w.rows, w.open_at_start = grid, k, F.shape[1], F.shape[0], \
            int(open_at_start)
        w.chord, w.enter, w.leave, w.apart = chord, enter, leave, apart
        w.t_old, w.h, w.F, w.y_old = t_old, h, F.ctypes.data, y_old.ctypes.data
        which = 0
        for j, tk in enumerate(ends):
            if tk in known:
                self._ends[2 * j:2 * j + 2] = known[tk]
                which |= 1 << j
        if self._anchored(lu_context, self.projection, self._address, t0, t1, budget,
                          self._ends_at, which):
            return None
        rows = self.buffers["out"][:3 * w.found].reshape(-1, 3).tolist()
        return {t: (smin, smax) for t, smin, smax in rows}
