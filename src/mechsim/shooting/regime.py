"""Impact-mode regime map of the impact pair over excitation amplitude × frequency (seed 002,
Fig. 8): each point is a periodic steady state found by shooting, continued from its
neighbour, with its stability from the Floquet multipliers; rows of constant amplitude run
in parallel, as a parameter study's samples (`mechsim.study.run_tasks`).

Where continuation finds no periodic state, the map says what the pair does there instead:
it simulates `SETTLE` periods from the nearest state found and looks for a motion that
repeats after k ≤ `MAX_PERIOD` periods (a subharmonic, or a period-1 state continuation
missed, which is then shot). A motion that repeats after none is irregular. Only the
relative motion is compared: x1 − x2 and ẋ2 − ẋ1 form a closed system (the forcing
prescribes m1's acceleration and an impact reverses the relative velocity), while the pair
as a whole may drift.

Measured on the example's 30 × 30 map (A 0.10–0.30 in, ω 35–65 rad/s): most period-1
states are unstable, with a multiplier between −20 and +20; only (3, 3) around
A = 0.155–0.176 in is stable. Between the (2, 2) and (2, 3) bands (A = 0.121 and 0.128 in)
no periodic state exists within 8 periods, and a simulation wanders between (2, 2), (3, 2)
and (2, 3) periods for a thousand periods.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..files import save_figure
from ..study import run_tasks
from .oscillators import ImpactPair
from .solve import solve

# Quasi-Newton (forward-difference Jacobian of the residual, Broyden updates, minimum-norm
# steps for the free shift x1(0)). Measured on a 9 × 9 grid around Table 3's point: Newton
# found 79 of 81 points, Warner's secant method (the paper's) 6, its secant system being
# degenerate along the free shift.
METHOD = "newton"
MAX_ITER = 12
# Where continuation fails: periods simulated before looking, the longest repetition looked
# for, and how closely the relative state (x1 − x2 in clearances, ẋ2 − ẋ1 in A ω) must repeat
# over 2 · MAX_PERIOD periods.
SETTLE = 200
MAX_PERIOD = 8
REPEAT_TOL = 1e-6


@dataclass
class RegimeMap:
    amplitudes: np.ndarray      # (na,)
    omegas: np.ndarray          # (nw,)
    modes: np.ndarray           # (na, nw, 2) impacts per period on each wall; −1: not found
    x0: np.ndarray              # (na, nw, 4) the steady states (nan where not found)
    wall_time: float = 0.0
    stable: np.ndarray | None = None     # (na, nw) the periodic state is stable
    # Where no periodic state was found: the period k (in forcing periods) of the motion a
    # simulation settles to, 0 if it repeats after no k ≤ MAX_PERIOD (irregular); 1 at the
    # periodic states. `cycle_modes` (na, nw, 2): the impacts on each wall in those k
    # periods (−1 where irregular).
    periods: np.ndarray | None = None
    cycle_modes: np.ndarray | None = None

    def plot(self, path=None, ax=None):
        """Mode map: one colour per (n, m), hatched where the periodic state is unstable; a
        subharmonic's colour is its impacts in k periods, labelled "/kT"; grey where the
        motion is irregular."""
        from ..results.plots import new_axes
        fig, ax = new_axes(ax, size=(8.5, 5.0))
        periods = self.periods if self.periods is not None else \
            np.where(self.modes[:, :, 0] >= 0, 1, -1)
        cycles = self.cycle_modes if self.cycle_modes is not None else self.modes
        keys = np.full(periods.shape, None, object)
        for i, j in np.ndindex(periods.shape):
            k = int(periods[i, j])
            if k >= 1:
                keys[i, j] = (tuple(int(x) for x in cycles[i, j]), k)
            elif k == 0:
                keys[i, j] = "irregular"
        labels = sorted({key for key in keys.flat if key is not None and key != "irregular"})
        labels += ["irregular"] if any(key == "irregular" for key in keys.flat) else []
        index = {key: k for k, key in enumerate(labels)}
        grid = np.full(periods.shape, np.nan)
        for (i, j), key in np.ndenumerate(keys):
            if key is not None:
                grid[i, j] = index[key]
        mpl = __import__("matplotlib")
        # tab20 without its greys, which mean "irregular" here.
        palette = [c for k, c in enumerate(mpl.colormaps["tab20"].colors) if k not in (14, 15)]
        colours = [palette[k % len(palette)] if key != "irregular" else (0.6, 0.6, 0.6)
                   for k, key in enumerate(labels)]
        cmap = mpl.colors.ListedColormap(colours or [(1.0, 1.0, 1.0)])
        ax.pcolormesh(self.omegas, self.amplitudes, grid, cmap=cmap, shading="nearest",
                      vmin=-0.5, vmax=max(len(labels), 1) - 0.5)
        for key, k in index.items():
            text = key if key == "irregular" else \
                f"({key[0][0]},{key[0][1]})" + ("" if key[1] == 1 else f"/{key[1]}T")
            ax.plot([], [], "s", color=colours[k], label=text)
        if self.stable is not None and np.any((periods == 1) & ~self.stable):
            unstable = ((periods == 1) & ~self.stable).astype(float)
            ax.contourf(self.omegas, self.amplitudes, unstable, levels=[0.5, 1.5],
                        colors="none", hatches=["//"])
            ax.fill([], [], hatch="//", fill=False, label="unstable")
        ax.set(xlabel="ω [rad/s]", ylabel="A [in]", title="Impact modes (n, m) per period")
        ax.legend(fontsize="small", loc="upper left", bbox_to_anchor=(1.01, 1.0))
        if path is not None:
            save_figure(fig, path)
        return fig


def _solve_point(params, A, w, guess, floquet=True):
    """(x0, mode, stable) of the periodic state at (A, ω) by shooting from `guess`, or
    (None, None, None); stable is None without `floquet`."""
    pair = ImpactPair(amplitude=A, omega=w, **params)
    try:
        sol = solve(pair, guess, method=METHOD, tol=1e-6, max_iter=MAX_ITER, scale=1.001,
                    floquet=floquet, max_halvings=6)
    except ValueError:
        return None, None, None
    if not sol.converged:
        return None, None, None
    return sol.x0, sol.mode, sol.stable


def settle(pair: ImpactPair, u, periods=SETTLE, max_period=MAX_PERIOD, tol=REPEAT_TOL):
    """Simulate the pair from the state of unknowns `u` (x1, ẋ1, ẋ2, φ) for `periods` periods
    and look for a repetition of its relative motion: (k, impacts (n, m) in those k periods,
    the state y = (x1, ẋ1, x2, ẋ2) at the end, its phase φ) for the smallest k ≤
    `max_period` that repeats to `tol` over 2 · max_period periods; k = 0 and no impacts
    if none does."""
    u = np.asarray(u, float)
    y, phi = pair.initial_state(u), float(u[3])
    scale = np.array([pair.r, pair.A * pair.omega])
    watch = 2 * max_period
    rel, events = [], []
    for k in range(periods + watch):
        tr = pair.state_flow(y, phi, samples=3)
        y = tr.x[-1]
        if k >= periods:
            rel.append(np.array([y[0] - y[2], y[3] - y[1]]) / scale)
            events.append([kind for _, kind in tr.events])
    rel = np.array(rel)
    for k in range(1, max_period + 1):
        if np.max(np.abs(rel[k:] - rel[:-k])) < tol:
            kinds = [kind for ev in events[-k:] for kind in ev]
            return k, (kinds.count("impact+"), kinds.count("impact-")), y, phi
    return 0, None, y, phi


def _unknowns(pair: ImpactPair, y, phi):
    """Shooting unknowns (x1, ẋ1, ẋ2, φ) of the motion from state y at phase φ: its state
    where x1 − x2 first changes sign, the phase moved along (linear interpolation between
    samples; Newton polishes it)."""
    tr = pair.state_flow(y, phi, samples=2000)
    D = tr.x[:, 0] - tr.x[:, 2]
    k = np.flatnonzero(np.sign(D[:-1]) * np.sign(D[1:]) < 0)
    if not k.size:
        return None
    k = k[0]
    a = D[k] / (D[k] - D[k + 1])
    t = tr.t[k] + a * (tr.t[k + 1] - tr.t[k])
    x = tr.x[k] + a * (tr.x[k + 1] - tr.x[k])
    return np.array([x[0], x[1], x[3], phi + pair.omega * t])


def _row(args):
    """Continue along ω from the row's seed at column j0, to the right and to the left; then
    simulate where no periodic state was found."""
    params, A, omegas, j0, seed = args
    nw = len(omegas)
    x0 = np.full((nw, 4), np.nan)
    modes = np.full((nw, 2), -1)
    stable = np.zeros(nw, bool)
    x, m, st = _solve_point(params, A, omegas[j0], seed)
    if x is not None:
        x0[j0], modes[j0], stable[j0] = x, m, st
    first = x if x is not None else np.asarray(seed, float)
    for direction in (range(j0 + 1, nw), range(j0 - 1, -1, -1)):
        trail = [first]                # solutions along this direction, newest last
        for j in direction:
            # Secant predictor from the last two solutions (equal steps in ω), falling back
            # to the last solution itself.
            starts = [trail[-1]] if len(trail) < 2 else [2 * trail[-1] - trail[-2], trail[-1]]
            for start in starts:
                x, m, st = _solve_point(params, A, omegas[j], start)
                if x is not None:
                    break
            if x is None:
                trail = trail[-1:]
                continue
            x0[j], modes[j], stable[j] = x, m, st
            trail = [trail[-1], x]
    periods = np.where(modes[:, 0] >= 0, 1, -1)
    cycles = modes.copy()
    for j in np.flatnonzero(periods < 0):
        found = np.flatnonzero(periods == 1)
        start = x0[found[np.argmin(np.abs(found - j))]] if found.size else \
            np.asarray(seed, float)
        pair = ImpactPair(amplitude=A, omega=omegas[j], **params)
        k, cycle, y, phi = settle(pair, start)
        if k == 1:
            guess = _unknowns(pair, y, phi)
            x, m, st = (None, None, None) if guess is None else \
                _solve_point(params, A, omegas[j], guess)
            if x is not None:
                x0[j], modes[j], stable[j] = x, m, st
                cycle = m
            else:
                stable[j] = True       # the simulation settled onto it; x0 stays nan
        periods[j] = k
        cycles[j] = cycle if cycle is not None else (-1, -1)
    return x0, modes, stable, periods, cycles


def regime_map(amplitudes, omegas, seed, seed_amplitude, seed_omega, m1=0.2799,
               m2=0.000545, clearance=0.028, restitution=0.7, processes=None, client=None,
               progress=False) -> RegimeMap:
    """Modes over `amplitudes` × `omegas`, continued from `seed` (a steady state
    (x1, ẋ1, ẋ2, φ) at (seed_amplitude, seed_omega)): first down the column of the seed's
    frequency, then along every row in parallel, as the samples of a parameter study run
    (`mechsim.study.run_tasks`): on `processes` local processes (None: every core; 1: in
    this process) or on a dask.distributed `client`; `progress`: a bar of finished rows."""
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
            x, _, _ = _solve_point(params, amplitudes[i], omegas[j0], guess,
                                   floquet=False)
            if x is not None:
                guess = x
            seeds[i] = guess
    tasks = [(params, A, omegas, j0, seeds[i]) for i, A in enumerate(amplitudes)]
    rows = run_tasks(_row, tasks, client=client, workers=processes, progress=progress,
                     desc="regime map rows")
    failed = next((r for r in rows if isinstance(r, BaseException)), None)
    if failed is not None:
        raise failed
    x0, modes, stable, periods, cycles = (np.array([r[k] for r in rows]) for k in range(5))
    return RegimeMap(amplitudes, omegas, modes, x0, time.perf_counter() - start, stable,
                     periods, cycles)
