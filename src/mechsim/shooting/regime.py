"""Impact-mode regime map of the impact pair over excitation amplitude × frequency (seed 002,
Fig. 8): each point is a periodic steady state found by shooting, continued from its
neighbour; rows of constant amplitude run in parallel on a process pool.
"""

from __future__ import annotations

import os
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass

import numpy as np

from ..oscillators import ImpactPair
from .solve import solve

# Quasi-Newton (forward-difference Jacobian of the residual, Broyden updates, minimum-norm
# steps for the free shift x1(0)). Measured on a 9 × 9 grid around Table 3's point: Newton
# found 79 of 81 points, Warner's secant method (the paper's) 6, its secant system being
# degenerate along the free shift.
METHOD = "newton"
MAX_ITER = 12


@dataclass
class RegimeMap:
    amplitudes: np.ndarray      # (na,)
    omegas: np.ndarray          # (nw,)
    modes: np.ndarray           # (na, nw, 2) impacts per period on each wall; −1: not found
    x0: np.ndarray              # (na, nw, 4) the steady states (nan where not found)
    wall_time: float = 0.0

    def plot(self, path=None, ax=None):
        """Mode map: one colour per (n, m); white where no periodic motion was found."""
        from ..results.plots import _new_axes
        fig, ax = _new_axes(ax, size=(7.0, 5.0))
        labels = sorted({tuple(m) for m in self.modes.reshape(-1, 2).tolist() if m[0] >= 0})
        index = {m: k for k, m in enumerate(labels)}
        grid = np.full(self.modes.shape[:2], np.nan)
        for i in range(grid.shape[0]):
            for j in range(grid.shape[1]):
                m = tuple(self.modes[i, j])
                if m in index:
                    grid[i, j] = index[m]
        cmap = __import__("matplotlib").colormaps["tab20"].resampled(max(len(labels), 1))
        ax.pcolormesh(self.omegas, self.amplitudes, grid, cmap=cmap, shading="nearest",
                      vmin=-0.5, vmax=len(labels) - 0.5)
        for m, k in index.items():
            ax.plot([], [], "s", color=cmap(k), label=f"({m[0]},{m[1]})")
        ax.set(xlabel="ω [rad/s]", ylabel="A [in]", title="Impact modes (n, m) per period")
        ax.legend(fontsize="small", loc="upper left", ncols=2)
        if path is not None:
            fig.savefig(path, dpi=120)
        return fig


def _solve_point(params, A, w, guess):
    pair = ImpactPair(amplitude=A, omega=w, **params)
    try:
        sol = solve(pair, guess, method=METHOD, tol=1e-6, max_iter=MAX_ITER, scale=1.001,
                    floquet=False, max_halvings=6)
    except ValueError:
        return None, None
    if not sol.converged:
        return None, None
    return sol.x0, sol.mode


def _row(args):
    """Continue along ω from the row's seed at column j0, to the right and to the left."""
    params, A, omegas, j0, seed = args
    nw = len(omegas)
    x0 = np.full((nw, 4), np.nan)
    modes = np.full((nw, 2), -1)
    x, m = _solve_point(params, A, omegas[j0], seed)
    if x is not None:
        x0[j0], modes[j0] = x, m
    first = x if x is not None else np.asarray(seed, float)
    for direction in (range(j0 + 1, nw), range(j0 - 1, -1, -1)):
        trail = [first]                # solutions along this direction, newest last
        for j in direction:
            # Secant predictor from the last two solutions (equal steps in ω), falling back
            # to the last solution itself.
            starts = [trail[-1]] if len(trail) < 2 else [2 * trail[-1] - trail[-2], trail[-1]]
            for start in starts:
                x, m = _solve_point(params, A, omegas[j], start)
                if x is not None:
                    break
            if x is None:
                trail = trail[-1:]
                continue
            x0[j], modes[j] = x, m
            trail = [trail[-1], x]
    return x0, modes


def regime_map(amplitudes, omegas, seed, seed_amplitude, seed_omega, m1=0.2799,
               m2=0.000545, clearance=0.028, restitution=0.7, processes=None) -> RegimeMap:
    """Modes over `amplitudes` × `omegas`, continued from `seed` (a steady state
    (x1, ẋ1, ẋ2, φ) at (seed_amplitude, seed_omega)): first down the column of the seed's
    frequency, then along every row in parallel."""
    import time
    start = time.perf_counter()
    params = dict(m1=m1, m2=m2, clearance=clearance, restitution=restitution)
    amplitudes, omegas = np.asarray(amplitudes, float), np.asarray(omegas, float)
    j0 = int(np.argmin(np.abs(omegas - seed_omega)))
    i0 = int(np.argmin(np.abs(amplitudes - seed_amplitude)))
    seeds = [None] * len(amplitudes)
    for direction in (range(i0, len(amplitudes)), range(i0 - 1, -1, -1)):
        guess = np.asarray(seed, float)
        for i in direction:
            x, _ = _solve_point(params, amplitudes[i], omegas[j0], guess)
            if x is not None:
                guess = x
            seeds[i] = guess
    tasks = [(params, A, omegas, j0, seeds[i]) for i, A in enumerate(amplitudes)]
    workers = processes or os.cpu_count() or 1
    if workers > 1:
        with ProcessPoolExecutor(max_workers=workers) as pool:
            rows = list(pool.map(_row, tasks))
    else:
        rows = [_row(t) for t in tasks]
    x0 = np.array([r[0] for r in rows])
    modes = np.array([r[1] for r in rows])
    return RegimeMap(amplitudes, omegas, modes, x0, time.perf_counter() - start)
