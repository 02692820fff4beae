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

from .layout import SEGMENT, Dims

# Steps one call takes at most before Python looks in (progress, the stream).
BUDGET = 256


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
        self.s = SEGMENT.make({"budget": BUDGET, "y_rows": len(self.Y),
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

    def run_projection(self, projection) -> int:
        """Steps of the projection method on its compiled context (its address): how many
        were committed (`mechsim_projection_segment`)."""
        return int(self.lib.mechsim_projection_segment(projection, self._address))
