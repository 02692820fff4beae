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
        self.projection = projection
        self._minimum, self._anchored = lib.mechsim_passage_minimum, lib.mechsim_anchored
        self.buffers = SEARCH.buffers(Dims(n, m))
        self._out = np.zeros(1)                           # F, y_old: set per call
        self.search = SEARCH.make({"n": n, "m": m, "nodes_cap": NODES, "floors": 1},
                                  {**self.buffers, "F": self._out, "y_old": self._out})
        self._address = ctypes.addressof(self.search)
        self._ends, self._minimum_out = np.zeros(4), np.zeros(2)
        self._ends_at, self._minimum_at = self._ends.ctypes.data, self._minimum_out.ctypes.data

    def _on(self, dense, k):
        """The structure, pointed at the step's dense output `dense` (`Interpolant`:
        its `coefficients`) for σ_k."""
        t_old, h, y_old, F = dense.coefficients
        w = self.search
        w.kk, w.N, w.rows = k, F.shape[1], F.shape[0]
        w.t_old, w.h, w.F, w.y_old = t_old, h, F.ctypes.data, y_old.ctypes.data
        return w

    def passage_minimum(self, lu_context, dense, ta, tb, k, xatol):
        """(t, s) at the least of s = σ_k/σ_max of J̃ over [ta, tb] inside a step (Brent's
        bounded search, `mechsim_passage_minimum`), the states from `dense` (an
        `Interpolant`: its `coefficients` over the step), the positions solved on the
        partition whose engine context is `lu_context`, or q = y[:n] where it is None;
        None where a state or an SVD declined (the caller searches in Python)."""
        self._on(dense, k)
        if self._minimum(lu_context, self.projection, self._address, ta, tb, xatol,
                         self._minimum_at):
            return None
        t, s = self._minimum_out.tolist()
        return t, s

    def anchored(self, lu_context, dense, ends, budget, known, k, search):
        """`SingularityMonitor._anchored` in one call (`mechsim_anchored`): {t: (σ_k, σ_max)}
        measured over the step `ends` = (t0, t1) of `dense` (as `passage_minimum`), `known`
        the ends' measurements (time -> (σ_k, σ_max)), `search` = (grid, chord, enter,
        leave, apart, open at the start) as the monitor's; None where a state or an SVD
        declined or the grid outgrew `layout.NODES` nodes (the caller searches in
        Python)."""
        t0, t1 = ends
        grid, chord, enter, leave, apart, open_at_start = search
        w = self._on(dense, k)
        w.grid, w.chord, w.enter, w.leave, w.apart = grid, chord, enter, leave, apart
        w.open_at_start = int(open_at_start)
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
