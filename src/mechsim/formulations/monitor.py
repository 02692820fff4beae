"""Singular configurations of Φ_q, measured directly.

The measure is s = σ_min / σ_max of the mass-scaled Jacobian J̃ = Φ_q M^{-1/2} (over its m
rows, so a mechanism whose rank drops reads 0), with its rate ṡ from the singular vectors.
With `redundant` constraint equations (a rank r = m − redundant everywhere, such as a
parallelogram with a fifth bar) σ_min is the r-th singular value, the smallest one the
motion can lose. Its rate comes
σ̇ = uᵀ J̃̇ v, J̃̇ by one extra Jacobian along the velocity. Unlike the paper's symptoms
(frequent re-partitioning, energy fluctuation, collapsing steps) it sees a singularity coming
before any harm is done, and it names the joints involved: the rows that carry the left
singular vector of σ_min.

A passage is recorded while s < `enter` until s > `leave`. Large steps can jump over the
whole band, so where the rates at a step's ends change sign the minimum is located on the
integrator's dense output and, if below `enter`, recorded as a passage inside the step.

The thresholds apply to s relative to its running peak (the best-conditioned configuration
seen so far in the run), because a long chain is never well conditioned: s peaks at 0.29
for the seed's four-bar, 0.22 for the double four-bar and 0.014 for the 40-window chain,
while s/peak is nearly the same function of the crank angle for all three (0.15–0.19 at 10°
from the singular configuration, 0.03–0.04 at 2°). `enter = 0.07`, `leave = 0.14` of the
peak (hysteresis) open a band of about ±4° around each passage.

Far from the band the measurement (an SVD and a second Jacobian) is skipped for up to
`max_skip` steps when a floor f of s at the step's end keeps s above twice `enter` through
the step and a next one up to twice as long: f − 2 R h > 2 enter and (s_start + f − R h)/2
> 2 enter for a step of length h from s_start (measured, or the previous skip's floor),
with R twice the latest rate, the fastest rate seen, or the rate at the next step's end
of a fall accelerating steadily from the last measured rate to f's mean fall since then
(s at a peak has no rate; a parallelogram turning steadily falls from its peak into its
passage), times the growth of |v|∞ since then (no skip after a measurement at rest). f is
the better of two bounds from one Jacobian: Weyl's on its change since the last
measurement, |σᵢ(J̃) − σᵢ(J̃ₘ)| ≤ ‖J̃ − J̃ₘ‖, and on a small mechanism J̃'s own bounds
from J̃J̃ᵀ (`mechsim.linalg.dense.extreme_bounds`, the passage search's floor anchors;
0.84–0.95 of s on the crank-rocker and the double four-bar), which do not fade as J̃
moves on. The bounds anchor the next step's search at its start, in place of an SVD
there. Small fixed steps (a flexible mechanism at max step 5e-4 s) and the long steps of
a small mechanism far from the band then pay for one SVD in a few steps.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..linalg import sparse
from ..linalg.dense import Fall
from ..records import SingularPassage
from .intervals import bisect, dips, fresh_nodes, lowest, minimum_of, uncleared


# Mechanisms that are not small (`ConstraintAlgebra.small`) bound the search for passages
# inside a step by the rates of σ_min/σ_max seen, not by ‖dJ̃/dt‖ (whose Frobenius norm grows
# with the rows and made the 40-window chain's 20 s search every step), and search more
# briefly.
# Where σ_min/σ_max of J̃ never rises above BLIND while Φ_q's own ratio is above PLAIN_OK
# (a rod 1e100 times heavier than the crank: 1e-53), the measure is round-off and the
# monitor watches no passage (`blind`); the run's message says so.
BLIND = 1e-13
PLAIN_OK = 1e-6
# The passage search's bound on |d(σ_min/σ_max)/dt| inside a step: Weyl's, but at most this
# many times the fastest rate seen (`SingularityMonitor._hidden_passages`).
WEYL_SPAN = 100.0
# The rates of σ_min, σ_max: from J̃ this much motion ahead (`SingularityMonitor._measure`).
RATE_STEP = 1e-7
# The passage search inside a step (`SingularityMonitor._anchored`): the intervals of its
# first grid, and the margin of J̃'s path between two grid nodes over their chord.
GRID = 8
CHORD = 0.25
# The margin of the rate at which σ_min/σ_max can fall along a step, bounded on the cubic
# through J̃'s values and rates at the step's ends (`mechsim.linalg.dense.fall_rates`),
# for J̃'s departure from that cubic.
HERMITE_MARGIN = 1.25
# The skip evaluates J̃ (and its own bounds, below Weyl's) only where it could clear the
# step with s/peak at most this many times its value at the step's start or the last
# measurement (`SingularityMonitor._may_skip`).
SKIP_RISE = 1.25
# A passage's minimum inside a step is located to this fraction of the interval searched
# (`intervals.minimum_of`, `mechsim_passage_minimum`).
REFINE_TOL = 1e-5


@dataclass
class OpenPassage:
    """The singular passage the monitor is inside: where it began, its lowest σ_min/σ_max
    (not normalized) so far and where, the joints of that singular vector, and whether the
    passage bridge crossed it."""
    t_start: float
    t_min: float
    s_min: float
    joints: tuple
    bridged: bool = False


@dataclass(frozen=True)
class Dip:
    """A dip of σ_min/σ_max under `enter` inside a step: its minimum (t_min, s_min, not
    normalized) and the joints of that singular vector, its estimated span, and whether it
    holds the step's start (the open passage going on) or its end (still open there)."""
    t_min: float
    s_min: float
    joints: tuple
    t_start: float
    t_end: float
    at_start: bool
    at_end: bool


@dataclass
class Observation:
    """What the monitor carries from one observation to the next (`SingularityMonitor.
    observation`): the steps skipped since the last measurement and the bound of the
    latest skip (t, σ_min/σ_max floor), the last measured (t, s/peak, ṡ/peak), `last` and
    `rate`, the peak and the fastest rate seen, the last measurement (J̃, σ_min, σ_max, |v|∞),
    its bound on |d(σ_min/σ_max)/dt|, its `Fall` (or None), the measurements at the
    latest step's ends (time -> (σ_min, σ_max)) and the latest measurement's (t, left
    singular vector of σ_min), or None."""
    skipped: int
    floor: tuple | None
    prev: tuple | None
    last: float
    rate: float
    peak: float
    peak_rate: float
    measured: tuple | None
    ratio_speed: float
    fall: object
    known: dict
    vector: tuple | None = None


class SingularityMonitor:
    """Records singular passages; `last` and `rate` are s/peak and its rate after the latest
    observation, `inside` tells whether a passage is open."""

    max_skip = 4

    def __init__(self, problem, enter: float = 0.07, leave: float = 0.14, redundant: int = 0):
        if not 0.0 < enter < leave:
            raise ValueError(f"singularity thresholds need 0 < enter < leave, got {enter}, {leave}")
        self.problem = problem
        self.enter, self.leave = enter, leave
        self.redundant = int(redundant)     # equations of Φ that are redundant everywhere
        self.passages: list[SingularPassage] = []
        self.open_passage: OpenPassage | None = None     # the passage it is inside
        self.last, self.rate = 1.0, 0.0  # s/peak and its rate at the last observation
        self.peak = 0.0
        self._prev = None            # (t, s/peak, ṡ/peak) at the previous observation
        self._skipped = 0            # steps skipped since that observation
        self._floor = None           # (t, lower bound of σ_min/σ_max) at the latest skip
        self.peak_rate = 0.0         # fastest |ṡ|/peak seen
        self._measured = None        # (J̃, σ_min, σ_max, |v|∞) at the last observation measured
        self._known = {}             # time -> (σ_min, σ_max) measured at the latest step's ends
        self._vector = None          # (t, left singular vector of σ_min) of the latest measurement
        self._ratio_speed = 0.0      # the bound on |d(σ_min/σ_max)/dt| there (`_speed`)
        self._fall = None            # `Fall` at the latest measured observation, or None
        self.t_first = -np.inf       # the first observation's time
        # Whether σ_min/σ_max of J̃ is below round-off for the masses' sake (`BLIND`): then
        # no passage is watched, and the run says so.
        self.blind = False
        self._hidden_by_masses = None

    def _jacobian(self, q, t):
        """J̃ = Φ_q L⁻ᵀ, the mass-scaled Jacobian (CSR for a long chain: `mechsim.linalg.sparse`)."""
        return self.problem.algebra.scaled_jacobian(q, t)

    def measure(self, q, t, v=None):
        """(s, ṡ, left singular vector of σ_min); ṡ = 0 when v is None."""
        return self._measure(q, t, v)[:3]

    @property
    def ratio_row(self):
        """k where `ratio` is σ_k/σ_max by the algebra's `singular_extremes` (a small
        mechanism), else None (`measure`'s)."""
        algebra, m = self.problem.algebra, self.problem.m
        return m - 1 - self.redundant if m and algebra.batched else None

    def ratio(self, q, t) -> float:
        """σ_min/σ_max of J̃ at (q, t), not normalized: where the algebra measures many
        states together (a small mechanism), its singular values alone, as the passage
        search's values are (`singular_extremes`, no singular vectors); elsewhere
        `measure`'s."""
        row = self.ratio_row
        if row is None:
            return self.measure(q, t)[0]
        smin, smax = self.problem.algebra.singular_extremes([t], [q], row)[0].tolist()
        return smin / smax if smax > 0.0 else 0.0

    def _measure(self, q, t, v, J=None, speed=None):
        """`measure`, also returning σ_min, σ_max (σ_max = 0: rank lost), J̃ = J̃(q)
        (`J`, and `speed` |v|∞, where the caller has them), ‖dJ̃/dt‖_F along v (0 without v) and the algebra's
        `fall` (dJ̃/dt, P) where it gives one."""
        if speed is None:
            speed = float(np.max(np.abs(v))) if v is not None and v.size else 0.0
        eps = RATE_STEP / speed if speed > 0.0 else 0.0
        m = self.problem.m
        if m == 0:
            return (1.0, 0.0, np.zeros(0), 1.0, 1.0,
                    self._jacobian(q, t) if J is None else J, 0.0, None)
        smin, smax, d_min, d_max, u_min, J, rate_norm, fall = self.problem.algebra.measure(
            q, t, v, eps, m - 1 - self.redundant, J)
        if not smax > 0.0:
            return 0.0, 0.0, u_min, 0.0, 0.0, J, 0.0, None
        rate = float((d_min * smax - smin * d_max) / smax ** 2) if eps else 0.0
        return float(smin / smax), rate, u_min, float(smin), float(smax), J, rate_norm, fall

    def _masses_hide(self, q, t) -> bool:
        """Do unequal masses, not the configuration, make σ_min/σ_max of J̃ that small?
        (Φ_q's own ratio is above `PLAIN_OK`; decided once: the masses do not change.)"""
        if self._hidden_by_masses is None:
            sig = np.linalg.svd(sparse.dense(self.problem.phi_q(q, t)), compute_uv=False)
            k = sig.size - 1 - self.redundant
            self._hidden_by_masses = bool(k >= 0 and sig[0] > 0.0 and
                                          sig[k] > PLAIN_OK * sig[0])
        return self._hidden_by_masses

    def joints_of(self, u) -> tuple[str, ...]:
        """The joints and drivers owning the rows where the singular vector u is above a
        fifth of its largest entry, in row order."""
        owners = self.problem.constraint_owners
        size = [abs(x) for x in u.tolist()]      # a few rows: plain Python is faster
        cut = 0.2 * max(size, default=0.0)
        return tuple(dict.fromkeys(owners[i] for i, x in enumerate(size) if x > cut))

    def predicted_within(self, h: float) -> bool:
        """Will s fall below `enter` within the next `h` seconds at its present rate?"""
        return self.last < self.enter or (self.rate < 0.0 and self.last + self.rate * h < self.enter)

    def _may_skip(self, q, t, t_old, speed):
        """(skip?, J̃(q) if it was computed for the bounds)."""
        prev = self._prev
        measured = self._measured
        if self.open_passage is not None or prev is None or t_old is None or not t > t_old or \
                self._skipped >= self.max_skip or measured is None or not measured[3] > 0.0:
            return False, None
        last = self._floor                          # the step's start: measured, or skipped
        if prev[0] != t_old and not (self._skipped and last is not None and last[0] == t_old):
            return False, None
        start = prev[1] if prev[0] == t_old else last[1] / self.peak
        Jm, smin, smax, speed_then = measured
        growth, likely = speed / speed_then, SKIP_RISE * max(prev[1], start) * self.peak
        if not self._skip_clears(t, t_old, growth, start, likely):
            return False, None                  # not even where s has risen that much
        algebra = self.problem.algebra
        J, E = algebra.change(q, t, Jm)
        bounds = (max(smin - E, 0.0), smax + E)        # σ_min from below, σ_max from above
        floor = bounds[0] / bounds[1]
        most = (smin + E) / (smax - E) if smax - E > 0.0 else math.inf    # s from above
        likely = min(most, likely)
        if algebra.small and not self.redundant and \
                self._skip_clears(t, t_old, growth, start, likely):
            own = algebra.extreme_bounds(J)                        # J̃'s own
            if own is not None and own[0] / own[1] > floor:
                bounds, floor = own, own[0] / own[1]
        if self._skip_clears(t, t_old, growth, start, floor):
            self._floor = (t, floor)
            self._known = {t: bounds}          # the next search's anchor at its start
            return True, J
        return False, J

    def _skip_clears(self, t, t_old, growth, start, floor) -> bool:
        """Does `floor` (σ_min/σ_max at t, not normalized) keep s above 2 `enter` through
        the step from t_old (s/peak `start` there) and a next one up to twice as long?"""
        h, f, prev = t - t_old, floor / self.peak, self._prev
        span = t - prev[0]                          # since the last measurement
        fall, was = max(prev[1] - f, 0.0) / span, max(-prev[2], 0.0)     # mean, and then
        ahead = was + 2.0 * (fall - was) * (1.0 + 2.0 * h / span)     # at t + 2h, accelerating
        bound = max(2.0 * abs(prev[2]), self.peak_rate, ahead) * max(1.0, growth)
        return f - 2.0 * h * bound > 2.0 * self.enter and start + f - h * bound > 4.0 * self.enter

    def observation(self) -> Observation:
        """The state the next observation starts from (for steps observed in the engine,
        `mechsim.run.segment`)."""
        return Observation(self._skipped, self._floor, self._prev, self.last, self.rate,
                           self.peak, self.peak_rate, self._measured, self._ratio_speed,
                           self._fall, dict(self._known), self._vector)

    def resume(self, o: Observation) -> None:
        """Go on from `o`, the state after observations made elsewhere (the engine's)."""
        self._skipped, self._floor, self._prev = o.skipped, o.floor, o.prev
        self.last, self.rate, self.peak, self.peak_rate = o.last, o.rate, o.peak, o.peak_rate
        self._measured, self._ratio_speed, self._fall = o.measured, o.ratio_speed, o.fall
        self._known = dict(o.known)
        self._vector = o.vector

    def took(self, closed, still_open) -> None:
        """The passages observed elsewhere (the engine's segments) since `observation`:
        `closed` recorded in order, then `still_open` (an `OpenPassage`, or None) the
        passage the monitor is inside."""
        self.passages.extend(closed)
        self.open_passage = still_open

    def observe(self, t, q, v=None, state_at=None, t_old=None, positions_at=None,
                on_step=None) -> float:
        """Take the state at an accepted step that began at `t_old`. `state_at(t) -> (q, v)`
        evaluates the step's dense output, used to confirm a minimum hidden inside the
        step; `positions_at(times) -> Q` (k, n), where given, the configurations at many
        times at once, which the search measures together; `on_step`, where given, lets
        the compiled engine search the step (`_hidden_passages`). Returns s/peak (the
        latest measured value when this step was skipped)."""
        if self._prev is None:
            self.t_first = t
        floor = self._floor if self._skipped else None
        speed = float(np.max(np.abs(v))) if v is not None and v.size else 0.0
        skip, J = self._may_skip(q, t, t_old, speed)
        if skip:
            self._skipped += 1
            return self.last
        raw, rate, u, smin, smax, J, rate_norm, fall = self._measure(q, t, v, J, speed)
        self._measured = (J, smin, smax, speed) if smax > 0.0 else None
        vectors = {t: u}             # the singular vectors measured at the step's ends
        if self._vector is not None and self._vector[0] == t_old:
            vectors[t_old] = self._vector[1]
        self._vector = (t, u)
        self._known = {tk: x for tk, x in self._known.items() if tk == t_old}
        self._known[t] = (smin, smax)
        speed_before, self._ratio_speed = self._ratio_speed, self._speed(rate_norm, smax)
        fall_before, self._fall = self._fall, None
        if fall is not None:
            self._fall = Fall(t, sparse.dense(J), fall, smin, smax, rate_norm)
        self.peak = max(self.peak, raw)
        if self.peak < BLIND and self._masses_hide(q, t):
            # Below round-off, s/peak is noise: no passage can be told from it.
            self.blind = True
            self.last, self.rate, self._prev = 1.0, 0.0, None
            return 1.0
        s, rate = (raw / self.peak, rate / self.peak) if self.peak > 0 else (0.0, 0.0)
        self.peak_rate = max(self.peak_rate, abs(rate))
        prev, self._prev = self._prev, (t, s, rate)
        if prev is not None and t_old is not None and prev[0] != t_old:
            # The step follows skipped ones: it starts where the last skip bounded s from
            # below (a step longer than the skip foresaw may hide a passage).
            prev = (t_old, floor[1] / self.peak, 0.0) \
                if floor is not None and floor[0] == t_old else None
        self._skipped = 0
        self.last, self.rate = s, rate
        if prev is not None and state_at is not None:
            # From the latest measured observation: the step's start, or before the
            # measurements skipped since.
            falls = (fall_before, self._fall) if fall_before is not None else None
            for dip in self._hidden_passages(prev, (t, s, rate), state_at,
                                             max(speed_before, self._ratio_speed),
                                             positions_at, falls, on_step, vectors):
                here = self.open_passage
                if here is not None and dip.at_start:          # the open passage goes on
                    if dip.s_min < here.s_min:
                        here.t_min, here.s_min, here.joints = dip.t_min, dip.s_min, dip.joints
                    if not dip.at_end:
                        self.close(dip.t_end)
                elif dip.at_end:                                # the step ends inside it
                    self.open_passage = OpenPassage(dip.t_start, dip.t_min, dip.s_min,
                                                    dip.joints)
                else:
                    self.passages.append(SingularPassage(dip.t_start, dip.t_end, dip.s_min,
                                                         dip.joints, dip.t_min))
        here = self.open_passage
        if here is not None:
            if raw < here.s_min:
                here.t_min, here.s_min, here.joints = t, raw, self.joints_of(u)
            if s > self.leave:
                self.close(t)
        elif s < self.enter:
            self.open_passage = OpenPassage(t, t, raw, self.joints_of(u))
        return s

    def crossed(self, t0, t1, tm, qm):
        """A passage was crossed in one step from t0 to t1 without observations inside
        (`mechsim.formulations.bridge`), its singular instant predicted at tm where the
        configuration is qm: recorded with the open passage, or opened as a passage of its
        own, which the next observation closes once s is above `leave` (closing it at t1
        counted the rest of the same dip, observed after the bridge, a second time)."""
        sm, _, um = self.measure(qm, tm)
        if self.open_passage is not None:
            here = self.open_passage
            here.t_min, here.s_min, here.joints, here.bridged = tm, sm, self.joints_of(um), True
        elif sm < self.enter * self.peak:
            self.open_passage = OpenPassage(t0, tm, sm, self.joints_of(um), True)

    def _speed(self, rate_norm, smax) -> float:
        """A bound on how fast σ_min/σ_max can change where ‖dJ̃/dt‖_F is `rate_norm` (from
        the measurement, along the velocity): every singular value of J̃ moves at most
        ‖dJ̃/dt‖ (Weyl), so |d(σ_min/σ_max)/dt| ≤ 2 ‖dJ̃/dt‖_F / σ_max. Unlike the rates of
        s seen so far it holds near a passage, where s turns sharply. 0 for an algebra that
        is not small (its search is bounded by the rates seen)."""
        if not smax > 0.0 or not self.problem.algebra.small:
            return 0.0
        return 2.0 * rate_norm / smax

    def _hidden_passages(self, a, b, state_at, ratio_speed=0.0,
                         positions_at=None, falls=None, on_step=None, vectors=None) -> list[Dip]:
        """The dips of s inside the step from a = (t0, s0/peak, rate) to b, in time order
        (s0 may be a lower bound of s at t0, with rate 0); a dip that holds t0 continues
        the open passage.

        |ṡ| is at most R (twice the larger of the ends' bounds from `_speed`, or of the
        rates seen), so s ≥ (s_a + s_b − R (t_b − t_a))/2 between two values. Every
        interval of the step's dense output this does not keep above `enter` is bisected,
        also beside a value found under it: two passages are apart by a stretch where s
        exceeds `leave`, which takes at least (leave − enter)/R to climb to and as long to
        leave, so no other passage comes within twice that of a value under `enter`, and
        an interval that near one needs no search. The values under `enter` then fall into
        dips (runs not parted by a value above `leave`), each refined to its minimum.
        A step that crosses several passages (a partitioned method striding through a
        uniformly turning parallelogram) reports every one, wherever its midpoints fall.
        Steps clear of any passage cost nothing: their ends already exclude it, by that bound
        or by `_fall_clears` (`falls`). Where the algebra measures many states together (a
        small mechanism) the values come from `_anchored` (Weyl's inequality along J̃'s
        path), elsewhere from `intervals.bisect` on the rate bound, one `measure` each.
        `on_step() -> (positions context, dense output) or None`, where given, lets the
        compiled engine search the step and locate a dip's minimum
        (`ConstraintAlgebra.anchored`, `passage_minimum`); where it declines, the search
        is Python's. `vectors`: time -> the left singular vector of σ_min measured there
        (the step's ends), for the joints of a dip whose least value is there."""
        t0, s0, d0 = a
        t1, s1, d1 = b
        h = t1 - t0
        peak, enter, leave = self.peak, self.enter * self.peak, self.leave * self.peak
        observed = peak * max(self.peak_rate, abs(d0), abs(d1))
        # Weyl's bound holds where s turns sharply, but where unequal masses make σ_min
        # tiny against ‖dJ̃/dt‖ it exceeds every rate seen many million times (a slider-crank
        # with a 1e10 kg rod: 4000 evaluations a step, 0.24 s each): it is taken up to
        # `WEYL_SPAN` times the rates seen.
        rate_bound = 2.0 * max(observed, min(ratio_speed, WEYL_SPAN * observed)
                               if observed > 0.0 else ratio_speed)
        if not h > 0.0 or not rate_bound > 0.0 or \
                (s0 + s1) * peak - rate_bound * h >= 2.0 * enter:
            return []
        if self._fall_clears(falls, observed):
            return []

        def s_at(tk):
            return self.ratio(state_at(tk)[0], tk)

        kk = self.problem.m - 1 - self.redundant
        step = None if on_step is None else on_step()

        def refine(ta, tb):
            found = None if step is None else self.problem.algebra.passage_minimum(
                *step, ta, tb, kk, REFINE_TOL * (tb - ta))
            return minimum_of(s_at, ta, tb, REFINE_TOL * (tb - ta)) if found is None else found

        # Enough evaluations to cover the step with intervals the bound can clear (a
        # large mechanism's SVD costs milliseconds: there the rates seen bound the search).
        budget = int(min(4000, 16 + 4 * rate_bound * h / max((s0 + s1) * peak, enter)))
        if not self.problem.algebra.small:
            budget = min(budget, 64)
        apart = 2.0 * (leave - enter) / rate_bound
        if positions_at is not None and self.problem.algebra.batched:
            seen = self._anchored((t0, t1), positions_at, budget, apart, self._known, step)
        else:
            seen = bisect((t0, s0 * peak, t1, s1 * peak), s_at, rate_bound, budget, apart,
                          enter)
        return self._dips_seen(seen, (t0, t1), enter / (rate_bound / 2.0), refine, s_at,
                               state_at, vectors or {})

    def _dips_seen(self, seen, ends, width, refine, s_at, state_at, vectors) -> list[Dip]:
        """The `Dip`s of the values `seen` ({t: s}, not normalized) over the step `ends`:
        runs under `enter` not parted by a value above `leave` (`intervals.dips`), each at
        its least value refined by `refine(ta, tb) -> (t, s)` between its neighbours, its
        span `width` either side of it within the step; its joints from the singular
        vector there, `vectors[t]` where that was measured already."""
        t0, t1 = ends
        enter, leave = self.enter * self.peak, self.leave * self.peak
        times = sorted(seen)
        values = [seen[tk] for tk in times]
        last = len(times) - 1
        found = []
        for run, closed in dips(values, enter, leave, self.open_passage is not None):
            k = min(run, key=values.__getitem__)
            tm, sm = times[k], values[k]
            if 0 < k < last:
                tr, sr = refine(times[k - 1], times[k + 1])
                if sr < sm:
                    tm, sm = tr, sr
            elif last > 0:
                # The least value at an end of the step: the bisection stops beside it
                # (`apart`), yet s may still fall into the step from there, its minimum
                # between the end and its neighbour. One value just inside tells.
                j = 1 if k == 0 else last - 1
                inside = times[k] + 1e-3 * (times[j] - times[k])
                if s_at(inside) < sm:
                    tr, sr = refine(*sorted((times[k], times[j])))
                    if sr < sm:
                        tm, sm = tr, sr
            um = vectors.get(tm)
            if um is None:
                _, _, um = self.measure(state_at(tm)[0], tm)
            at_start, at_end = run[0] == 0, not closed
            found.append(Dip(tm, sm, self.joints_of(um),
                             t0 if at_start else max(t0, tm - width),
                             t1 if at_end else min(t1, tm + width), at_start, at_end))
        return found

    def _fall_clears(self, falls, observed) -> bool:
        """Do the lines s_a − R_a |t − t_a| keep s above `enter` over the span of `falls`,
        the `Fall`s of the latest measured observation (the step's start, or one before
        the measurements skipped since) and of the step's end? R_a is `fall_rates`' bound (`mechsim.linalg.dense`)
        on how fast σ_min/σ_max can fall from end a (J̃'s cubic through its values and rates
        at the ends, seen in a's own singular directions) times `HERMITE_MARGIN`, at least
        twice `observed` (the rates seen, not normalized). Not where a passage is open at
        the start: there the search finds where it closes."""
        if falls is None or falls[1] is None or self.open_passage is not None:
            return False
        fa, fb = falls
        enter, least = self.enter * self.peak, 2.0 * observed
        ends = (fa.smin / fa.smax, fb.smin / fb.smax, fb.t - fa.t)
        if least > 0.0 and lowest(*ends, least, least) < enter:
            return False                        # no faster fall can clear it either
        r0, r1 = (max(HERMITE_MARGIN * r, least) for r in self.problem.algebra.fall_rates(fa, fb))
        return lowest(*ends, r0, r1) >= enter

    def _anchored(self, ends, positions_at, budget, apart, known=None, step=None) -> dict:
        """{t: s} over the step `ends` = (t0, t1) (not normalized), measured where the
        changes of J̃ along the step cannot keep s above `enter`. Weyl's inequality bounds
        every singular value at t by its value at a measured state a (an anchor: one SVD)
        within ‖J̃(t) − J̃ₐ‖₂, at most the length of J̃'s path from a to t, which a grid of
        the step bounds by the sum of its chords (J̃ at the nodes, no SVD: the problem's
        algebra's `chords`), each enlarged by `CHORD` for the arc. An interval that neither
        neighbouring anchor keeps above `enter`, and that is not joined to a passage found
        (`intervals.uncleared`), has its nodes measured, then is halved;
        near a value under `enter` the search stops as `intervals.bisect` does (`apart`). At most
        `budget` SVDs; `known`: time -> (σ_k, σ_max) measured already (the step's ends).
        Of a run of uncleared intervals one node is measured at a time, the run's middle
        one not measured yet (`intervals.fresh_nodes`): on the slope into a passage the
        anchors it gives clear much of the run (every node of it cost a tenth more SVDs).
        `step`: (positions context, dense output), where the compiled engine may search
        (`ConstraintAlgebra.anchored`: the same search in one call)."""
        t0, t1 = ends
        algebra, k = self.problem.algebra, self.problem.m - 1 - self.redundant
        enter, leave = self.enter * self.peak, self.leave * self.peak
        anchors = None if step is None else algebra.anchored(
            *step, ends, budget, known or {}, k,
            (GRID, 1.0 + CHORD, enter, leave, apart, self.open_passage is not None))
        if anchors is not None:
            return {tk: (sm / sx if sx > 0.0 else 0.0) for tk, (sm, sx) in anchors.items()}
        times = np.linspace(t0, t1, GRID + 1).tolist()
        Q = list(positions_at(np.array(times)))
        chords = ((1.0 + CHORD) * algebra.chords(times, Q)).tolist()
        anchors = {}                                    # node time -> (σ_k, σ_max)

        def measure(nodes):
            if not nodes:
                return
            got = algebra.singular_extremes([times[i] for i in nodes], [Q[i] for i in nodes], k)
            for i, (smin, smax) in zip(nodes, got.tolist()):
                anchors[times[i]] = (smin, smax)

        for i in (0, GRID):
            if known and times[i] in known:
                anchors[times[i]] = known[times[i]]
        measure([i for i in (0, GRID) if times[i] not in anchors])
        spent = 2
        joined = self.open_passage is not None
        while spent < budget:
            todo = uncleared(times, chords, anchors, enter, leave, apart, t1 - t0, joined)
            if not todo:
                break
            fresh = fresh_nodes(todo, lambda i: times[i] not in anchors)
            if fresh:
                fresh = fresh[:budget - spent]
                measure(fresh)
                spent += len(fresh)
                continue
            mids = [0.5 * (times[j] + times[j + 1]) for j in todo]
            middle = positions_at(np.array(mids))
            triples = [x for j, qm in zip(todo, middle) for x in (Q[j], qm, Q[j + 1])]
            at = [x for j, tm in zip(todo, mids) for x in (times[j], tm, times[j + 1])]
            pieces = ((1.0 + CHORD) * algebra.chords(at, triples)).tolist()
            for n, (j, tm, qm) in enumerate(reversed(list(zip(todo, mids, middle)))):
                c = 3 * (len(todo) - 1 - n)
                times.insert(j + 1, tm)
                Q.insert(j + 1, qm)
                chords[j:j + 1] = [pieces[c], pieces[c + 1]]
        return {tk: (sm / sx if sx > 0.0 else 0.0) for tk, (sm, sx) in anchors.items()}

    @property
    def clear_since(self) -> float:
        """Since when the motion has met no passage: the end of the last one recorded, or
        the first observation."""
        return self.passages[-1].t_end if self.passages else self.t_first

    @property
    def inside(self) -> bool:
        return self.open_passage is not None

    def close(self, t):
        here = self.open_passage
        if here is not None:
            self.passages.append(SingularPassage(here.t_start, t, here.s_min, here.joints,
                                                 here.t_min, here.bridged))
            self.open_passage = None
