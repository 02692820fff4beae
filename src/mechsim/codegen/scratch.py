"""Float buffers the compiled engine's calls read and write, kept between calls with their
addresses (`mechsim.codegen.engine`)."""

from __future__ import annotations

import numpy as np


class Scratch:
    """Float buffers the C side reads and writes, kept between calls with their addresses
    (an array's `.ctypes.data` costs more than copying a step's few states in and out):
    `take(name, k, width)` is a C-contiguous (k,) or (k, width) view and its address."""

    def __init__(self):
        self._kept = {}

    def take(self, name, k, width=0):
        kept, address = self._kept.get(name, (None, 0))
        row = (width,) if width else ()
        if kept is None or len(kept) < k or kept.shape[1:] != row:
            rows = max(k, 16, 2 * len(kept) if kept is not None else 0)
            kept = np.empty((rows, *row))
            address = kept.ctypes.data
            self._kept[name] = (kept, address)
        return kept[:k], address

    def put(self, name, values, width=0):
        """`take` of len(values) rows, filled with `values`: its address."""
        view, address = self.take(name, len(values), width)
        view[...] = values
        return address
