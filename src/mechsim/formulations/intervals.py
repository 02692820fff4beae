"""The interval rules of the singularity monitor's passage search inside a step
(`mechsim.formulations.monitor.SingularityMonitor._hidden_passages`; the compiled engine's
`mechsim_anchored` follows them in C): the least of two falling lines, the intervals a
search's anchors do not clear, the times near a value found under the band, and the dips
a row of values makes under the monitor's hysteresis."""

from __future__ import annotations

import math

import numpy as np


def lowest(sa, sb, h, ra, rb) -> float:
    """The least over a span of length h of max(sa − ra τ, sb − rb (h − τ)), the lines
    falling from its two ends at rates ra, rb (−inf unless both are positive): it only
    falls as either rate grows."""
    if not (ra > 0.0 and rb > 0.0):
        return -math.inf
    tau = min(max((sa - sb + rb * h) / (ra + rb), 0.0), h)
    return max(sa - ra * tau, sb - rb * (h - tau))


def uncleared(times, chords, anchors, enter, leave, apart, h, open_at_start=False) -> list:
    """The grid intervals (indices j of [times[j], times[j+1]]) that neither the nearest
    anchor before nor the one after keeps above `enter` (its σ_k less, its σ_max plus, the
    path length `chords` from it to the interval's far end), nor the anchors at both its
    ends together (their average less, or plus, half its path length), that lie farther
    than `apart` from a value under `enter`, and that are not joined to one.

    Joined: the same anchors keep s under `leave` in the interval (σ_k plus, σ_max less)
    and in every interval between it and a value under `enter` (or the step's start, with
    `open_at_start`: a passage open there). A dip hidden there is part of that value's
    passage, as no value above `leave` can part them (the monitor's hysteresis, `dips`),
    so it adds no passage; the passage's minimum is refined from its lowest value found."""
    count = len(times) - 1
    marks = [anchors.get(tk) for tk in times]
    under = [mark is not None and mark[0] < enter * mark[1] for mark in marks]
    lows = [tk for tk, below in zip(times, under) if below]
    low, high = [-np.inf] * count, [np.inf] * count
    # (Plain loops over the few nodes of a step: the search asks this several times a
    # step, and numpy's per-call cost on arrays this short is larger.)
    for order, side in ((range(count), 0), (range(count - 1, -1, -1), 1)):
        anchor, reach = None, 0.0
        for j in order:
            mark = marks[j + side]
            if mark is not None:
                anchor, reach = mark, 0.0
            reach += chords[j]
            if anchor is not None:
                bound = (anchor[0] - reach) / (anchor[1] + reach)
                if bound > low[j]:
                    low[j] = bound
                if anchor[1] > reach:
                    top = (anchor[0] + reach) / (anchor[1] - reach)
                    if top < high[j]:
                        high[j] = top
    # An interval with values at both ends: at a point of it the paths from either end add
    # up to at most its own, so σ_k there is at least the ends' average less half of it
    # and at most their average plus half (σ_max likewise), for the joins below.
    for j in range(count):
        a, b = marks[j], marks[j + 1]
        if a is not None and b is not None and low[j] < enter:
            both = (a[0] + b[0] - chords[j]) / (a[1] + b[1] + chords[j])
            if both > low[j]:
                low[j] = both
            if a[1] + b[1] > chords[j]:
                top = (a[0] + b[0] + chords[j]) / (a[1] + b[1] - chords[j])
                if top < high[j]:
                    high[j] = top
    joined = [False] * count
    j = 0
    while j < count:
        k = j
        while k < count and high[k] < leave:
            k += 1
        if k > j and ((open_at_start and j == 0) or any(under[j:k + 1])):
            joined[j:k] = [True] * (k - j)
        j = k + 1
    shortest = 1e-9 * h
    return [j for j in range(count) if low[j] < enter and not joined[j]
            and times[j + 1] - times[j] >= shortest
            and not (lows and covered(times[j], times[j + 1], lows, apart))]


def fresh_nodes(todo, free) -> list:
    """The nodes to measure next for the uncleared intervals `todo` (ascending): of each
    run of consecutive intervals, the middle one of its nodes not measured yet (`free(i)`),
    in order; none for a run whose nodes are all measured (it is halved)."""
    fresh, run = [], []
    for j in list(todo) + [None]:
        if run and (j is None or j != run[-1] + 1):
            nodes = [i for i in range(run[0], run[-1] + 2) if free(i)]
            if nodes:
                fresh.append(nodes[len(nodes) // 2])
            run = []
        if j is not None:
            run.append(j)
    return fresh


def covered(ta, tb, lows, reach) -> bool:
    """Does [ta, tb] lie within `reach` of the times `lows` (in their union)?"""
    near = sorted(tk for tk in lows if ta - reach <= tk <= tb + reach)
    edge = ta
    for tk in near:
        if tk - reach > edge:
            return False
        edge = max(edge, tk + reach)
        if edge >= tb:
            return True
    return False


def dips(values, enter, leave, open_at_start=False):
    """The runs of indices of `values` under `enter`, two runs joined unless a value
    above `leave` parts them (the monitor's hysteresis), each with whether such a value
    closed it; with `open_at_start`, the first value opens a run whatever it is."""
    dips, run = [], [0] if open_at_start and values else []
    for k, value in enumerate(values):
        if value < enter and k not in run[:1]:
            run.append(k)
        elif value > leave and run:
            dips.append((run, True))
            run = []
    if run:
        dips.append((run, False))
    return dips



def bisect(ends, s_at, rate_bound, budget, apart, enter) -> dict:
    """{t: s} over the step `ends` = (t0, s0, t1, s1), halving every interval the bound
    `rate_bound` on |ds/dt| does not keep above `enter` and that lies farther than `apart`
    from a value under it, breadth first, each midpoint measured by `s_at(t)`, at most
    `budget` of them in all (the search of a mechanism whose algebra measures one state
    at a time)."""
    t0, s0, t1, s1 = ends
    h = t1 - t0
    seen = {t0: s0, t1: s1}
    lows = [tk for tk, sk in seen.items() if sk < enter]
    level = [ends]
    while level and budget > 0:
        todo = [(ta, sa, tb, sb) for ta, sa, tb, sb in level
                if not ((sa + sb) - rate_bound * (tb - ta) >= 2.0 * enter or
                        tb - ta < 1e-9 * h or covered(ta, tb, lows, apart))][:budget]
        mids = [0.5 * (ta + tb) for ta, _, tb, _ in todo]
        budget -= len(mids)
        level = []
        for (ta, sa, tb, sb), tm, sm in zip(todo, mids, map(s_at, mids)):
            seen[tm] = sm
            if sm < enter:
                lows.append(tm)
            level += [(ta, sa, tm, sm), (tm, sm, tb, sb)]
    return seen


def minimum_of(s_at, ta, tb, xatol):
    """(t, s) at the minimum of s on [ta, tb] to `xatol`: a bounded scalar search on s²
    (s is V-shaped where a singular value passes through zero, s² smooth there: about ten
    evaluations where s itself takes twenty)."""
    from scipy.optimize import minimize_scalar
    found = minimize_scalar(lambda tk: s_at(tk) ** 2, bounds=(ta, tb), method="bounded",
                            options={"xatol": xatol})
    return float(found.x), math.sqrt(float(found.fun))
