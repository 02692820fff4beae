"""Runs that cannot end: a motion that speeds up without bound (a driver law with a pole,
an unstable load) is stopped once the trend of its steps shows it cannot reach t_end
(`Runaway`, used by `mechsim.run.loop`)."""

from __future__ import annotations

import numpy as np

# A run whose motion speeds up without bound stops once the trend of its steps shows it
# cannot reach t_end (`Runaway`): checked every RUNAWAY_EVERY accepted steps from the
# RUNAWAY_FROM-th, where the speeds grew RUNAWAY_SPEEDUP times over the last half of the
# steps and t_end lies beyond the steps' limit or RUNAWAY_STEPS steps away, twice running.
RUNAWAY_FROM = 1000
RUNAWAY_EVERY = 250
RUNAWAY_SPEEDUP = 1.5
RUNAWAY_STEPS = 1e8


class Runaway:
    """Tells a motion that outruns its integrator (a driver law with a pole, 1/(t − 0.1);
    one that grows as exp(1000 t); a load that does so) from one that merely speeds up.

    The accepted steps' lengths h_j, j the step's index, are kept thinned to at most
    `keep` evenly spaced in j. Over the last half of the run they are fitted by a power,
    h_j ≈ h_k (j/k)^(−p) (log–log least squares), and the steps still needed to reach
    t_end follow from the sum of that power: for p > 1 the steps add up to no more than
    k h_k/(p − 1), so the motion blows up near t* = t + k h_k/(p − 1) if that comes
    first; otherwise the count N with Σ_{j=k..N} h_j = t_end − t. A crank driven at
    100 t rad/s has h ∝ j^(−1/2) and N a few times k; 1/(t − 0.1) has p ≈ 2 and t*
    near 0.1; exp(1000 t) has p ≈ 1 and N ≈ k e^((t_end − t)/(k h_k)). Only where the
    largest speed also grew `RUNAWAY_SPEEDUP` times over that half, the steps shrank no
    more than its cube (a run whose steps collapse at a singular configuration, speeds
    bounded, is the stall rule's), and the verdict holds at two checks running."""

    keep = 512

    def __init__(self):
        self.rows = np.empty((self.keep + 1, 3))       # [j, h, speed] of the steps kept
        self.count = 0
        self.stride = 1
        self.strikes = 0

    def note(self, j, h, v) -> None:
        """The j-th accepted step, of length h, ending at velocities v."""
        if not j % self.stride:
            self.note_speed(j, h, np.max(np.abs(v), initial=0.0))

    def note_speeds(self, first, hs, speeds) -> None:
        """`note_speed` of the steps first, first + 1, … of lengths `hs` and speeds
        `speeds` (arrays: the steps a segment took), kept in slices between the thinnings."""
        i, total = 0, len(hs)
        while i < total:
            start = i + (-(first + i)) % self.stride
            if start >= total:
                return
            taken = np.arange(start, total, self.stride)[:self.keep + 1 - self.count]
            rows = self.rows[self.count:self.count + len(taken)]
            rows[:, 0], rows[:, 1], rows[:, 2] = first + taken, hs[taken], speeds[taken]
            self.count += len(taken)
            if self.count <= self.keep:
                return
            self._thin()
            i = int(taken[-1]) + 1

    def note_speed(self, j, h, speed) -> None:
        """`note` of a step whose largest speed |v|∞ is `speed`."""
        if j % self.stride:
            return
        self.rows[self.count] = j, h, speed
        self.count += 1
        if self.count > self.keep:
            self._thin()

    def _thin(self) -> None:
        """Every other kept step, the stride doubled (the rows are full)."""
        self.stride *= 2
        kept = self.rows[:self.count:2]
        self.count = len(kept)
        self.rows[:self.count] = kept.copy()

    def verdict(self, k, t, t_end) -> str:
        """"" while the run may go on; else why it cannot reach t_end."""
        if k < RUNAWAY_FROM or k % RUNAWAY_EVERY or self.count < 16:
            return ""
        j, h, speed = self.rows[:self.count].T
        half = j >= j[-1] / 2
        j, h, speed = j[half], h[half], speed[half]
        why = ""
        growth = speed[-1] / speed[0] if speed[0] > 0.0 else 0.0
        fit = np.polyfit(np.log(j), np.log(h), 1) if np.all(h > 0.0) else None
        p = -fit[0] if fit is not None else 0.0
        # The steps shrink because the motion speeds up (h ∝ 1/speed resolves its turns;
        # a pole gives h ∝ speed^-1.5): not many times faster, as where they collapse at
        # a singular configuration the formulation cannot pass (the stall rule's).
        if growth >= RUNAWAY_SPEEDUP and p * np.log(j[-1] / j[0]) <= 3.0 * np.log(growth):
            hk = float(np.exp(np.polyval(fit, np.log(k))))
            a = (t_end - t) / (k * hk)
            if p > 1.0 and a * (p - 1.0) >= 1.0:
                why = (f"the motion runs away: over the last {k - int(j[0])} steps its "
                       f"speeds grew from {speed[0]:.3g} to {speed[-1]:.3g} while its steps "
                       f"shrank as j^-{p:.2f}, which add up to no more than "
                       f"t ≈ {t + k * hk / (p - 1.0):.9g}: t_end is out of reach")
            else:
                log_n = np.log(k) + (a if abs(p - 1.0) < 1e-9 else
                                     np.log1p(a * (1.0 - p)) / (1.0 - p))
                if log_n > np.log(RUNAWAY_STEPS):
                    why = (f"the motion runs away: over the last {k - int(j[0])} steps its "
                           f"speeds grew from {speed[0]:.3g} to {speed[-1]:.3g} while its "
                           f"steps shrank as j^-{p:.2f}; at that rate t_end is about "
                           f"1e{log_n / np.log(10):.0f} steps away")
        self.strikes = self.strikes + 1 if why else 0
        return why if self.strikes >= 2 else ""
