"""Crossing a singular passage in one Adams step whose evaluations all lie outside it.

On the branch a mechanism follows through a singular configuration the motion is smooth, but
an evaluation of q̈ close to the configuration is not: within the band where σ_min of
J̃ = Φ_q M^{-1/2} is a few times the projection method's truncation cut or less, q̈ is either
truncated (a jump of order one where each singular value crosses the cut) or amplifies any
inconsistency of the state by 1/σ_min. A Runge–Kutta step that straddles the band evaluates
inside it, and where its stages land decides whether the step size collapses; a long chain
(forty windows lose forty directions one after another) collapses at almost every passage.

An Adams step evaluates only at its ends. The bridge lands the integrator a distance d
before the singular instant t* (predicted from σ_min/σ_max, its rate and the rate's change),
then takes one Adams step of length H = 2.4 d to a point as far past it:

- the history is up to `order` states spaced H/2 back from the landing point, integrated
  backwards from it (away from the configuration) at a hundredth of the run's tolerances,
  projected onto the constraints to round-off and given their exact accelerations;
- the predictor (Adams–Bashforth on that history) gives the end state, which is projected
  onto the constraints (mass metric): the branch the motion was on is the nearer one, the
  other being a distance of order H away and the predictor's error many orders less;
- the corrector (Adams–Moulton with the end point) is iterated, the end state projected
  before each evaluation there; the order is chosen by the differences between correctors
  of successive orders, which also estimate the error.

d starts at 1/14 of the step the integrator took freely before the approach (an Adams step
needs a few times shorter steps than an eighth-order Runge–Kutta step at equal error), and
never so close that σ_min/σ_max at the landing point falls under 1.6 `EDGE` cuts. Spacing
H/2 keeps the history's extrapolation well conditioned: on the double four-bar at rtol 3e-9
spacings H/3 and H/4 read 2–10× larger estimates. A bridge whose estimate misses the
tolerance is not taken: d shrinks by the estimate's (order+1)-th root and the integrator
lands again. Where landing closer makes the estimate no better (it is then the round-off of
q̈ near the configuration, not truncation), or at the floor of 1.2 `EDGE` cuts, the best
declined bridge is taken: one with an estimate up to `FLOOR_ACCEPT` tolerances (or 1e-8
relative) as within the run's accuracy, one up to `LAST_RESORT_RELATIVE` (1e-6 relative) as
a last resort that the run's message reports (`beyond`). Without one, or if a landing falls
inside the band, the bridge stands down and the formulation steps through the passage on
its own.
"""

from __future__ import annotations

from typing import Callable, NamedTuple

import numpy as np

from ..integrators.adams import QUADRATURE, error_norm, integration_weights, step_weights
from ..integrators.adapters import proposed_step
from ..integrators.compiled import CompiledDOP853
from ..tolerances import Tolerances
from .bridge_engine import HISTORY_BUDGET, EngineCrossing, step_nodes

# The band's edge, in multiples of the truncation cut (σ_min/σ_max = rcond).
EDGE = 3.0
# Landing distance before t* as a fraction of the free step, and bridge length per distance.
LANDING = 1.0 / 14.0
SPAN = 2.4
# The largest error estimate taken at the landing floor rather than stepping through, in
# tolerances, or relative (`FLOOR_ACCEPT_RELATIVE`) where that is more: a bridge's estimate
# there is the round-off of q̈ near the configuration, about 1e-9 relative
# (docs/design-notes.md, passage bridge).
FLOOR_ACCEPT = 10.0
FLOOR_ACCEPT_RELATIVE = 1e-8
# Where the estimates grow as the landing closes in, or the floor is reached, above
# `FLOOR_ACCEPT`: the best bridge with an estimate up to this relative error is still taken
# (and the run's message says so), since stepping through the band is then both slower and
# no more accurate (the 100-window chain at rtol 1e-10: estimates 108, 450, 2140 tolerances,
# then steps of 1e-7 s with a 602 × 603 SVD in each evaluation, no end in 15 minutes).
LAST_RESORT_RELATIVE = 1e-6
# A conservative mechanism's bridge ends with the energy it started with (`_energy_kept`)
# where that moves its velocities by at most this many tolerances (relative), or
# `LAST_RESORT_RELATIVE`: more would not be the bridge's error but a change of branch, which
# the energy balance must show.
ENERGY_KEPT = 100.0
# A landing at half the distance or less gains at least 2^(k+1) (k ≥ 3: 16) on a
# truncation error of order k; where the estimate fell by less than this factor the
# estimate is the round-off of q̈ near the configuration, which a still closer landing only
# amplifies: the best bridge so far is taken (docs/design-notes.md, passage bridge).
ROUND_OFF_GAIN = 0.1
# The fewest history points a crossing is built on (its corrector orders start at 3).
MIN_HISTORY = 5


class Crossing(NamedTuple):
    """A bridge over a passage: the end state, the step's interpolant (t -> [q; v] and
    the extension's numbers), the predicted singular instant and the states the step was
    built on, (t, q, v) oldest first, up to the landing point (consistent, outside the
    band: an Adams solver started at t_b can take them as its history), with the step's
    length and the order its error estimate found reliable there, the extension's numbers
    at the end (None without an extension) and the rate there (of [q; v] and the
    extension's numbers, as the bridge's accelerations give it)."""
    t_b: float
    q_b: np.ndarray
    v_b: np.ndarray
    interpolant: Callable
    t_star: float
    history: list
    step: float
    order: int
    extra: np.ndarray | None = None
    rate: np.ndarray | None = None

    def rate_at(self, y):
        """The rate at the end where y is the end's state [q; v] as it stands (the
        projection method's state: its rate is the formulation's own), else None."""
        n = self.q_b.size
        same = self.extra is None and y.size == 2 * n and \
            np.array_equal(y[:n], self.q_b) and np.array_equal(y[n:], self.v_b)
        return self.rate if same else None


class PassageBridge(EngineCrossing):
    """Plans the approach to a passage and crosses it.

    `accelerations(t, q, v)` must be exact outside the band (the projection method's);
    `cut()` gives its truncation cut (relative to σ_max); `compiled`: states may be
    projected onto the constraints by the problem's algebra compiled (`project_state`),
    where it has the engine. `extension`: more numbers carried over with the motion
    (the sensitivities of `mechsim.formulations.tangent`), an object with `width`,
    `rates(t, q, v, a, x)` (their derivative at a consistent state with accelerations a)
    and `consistent(t, q, v, x)`; the states are then [q; v; x].
    """

    def __init__(self, problem, accelerations, cut, rtol, atol, order=10, compiled=False,
                 extension=None, rate=None):
        self.problem = problem
        self.rate = rate           # () -> the engine's rate as `accelerations` (or None)
        self.extension = extension
        self.accelerations = accelerations
        self.compiled = compiled
        self._cut = cut
        self.rtol, self.atol = rtol, atol
        self.tol = Tolerances(rtol, atol)
        self._inner = self.tol.inner()          # the history's tolerances
        self._atols = {}                        # (inner, size) -> atol of every entry
        self.order = order
        self.free_step = None                   # step size before the approach
        self.landing = None                     # distance d before t* while approaching
        self.standing_down = False              # this passage is left to the formulation
        self._prev = None                       # (t, rate) at the previous plan
        self._planned = None                    # (t, predicted time to t*) of the last plan
        self._rate = 0.0                        # |rate| of σ_min/σ_max at the last plan
        self._free_bound = False                # the free step was the run's max_step
        self.last_estimate = None
        self._declined = None                   # (estimate, crossing) of the best declined
        self.evaluations = 0                    # right-hand sides evaluated by the bridge
        self.over_tolerance = 0                 # bridges taken at the floor with estimate > 1
        self.beyond = []                        # (t*, relative estimate) of bridges taken
                                                # over `FLOOR_ACCEPT` (the last resort)
        self._conservative = None               # no work channels (decided on first use)

    def extended(self, extension) -> "PassageBridge":
        """A new bridge with this one's settings that carries `extension` over too."""
        return PassageBridge(self.problem, self.accelerations, self._cut, self.rtol,
                             self.atol, self.order, self.compiled, extension, self.rate)

    def plain_start(self):
        """(`edge`, `LANDING`, the previous plan's (t, rate), the landing distance and the
        free step (each None where there is none), whether that step was the run's
        max_step) where the bridge is not standing down: steps may be taken elsewhere
        (`mechsim.run.segment`) while `plan` lands or plans nothing, and their plans
        replayed; else None."""
        if self.standing_down:
            return None
        return self.edge, LANDING, self._prev, self.landing, self.free_step, self._free_bound

    def note_step(self, h_next, max_step_bound=False):
        """Keep the longest step proposed since the last passage (also while another
        formulation integrates, e.g. the hybrid's LU phase): right after a restart the
        integrator's steps ramp up from a small first step and say nothing of the motion."""
        if self.free_step is None or h_next >= self.free_step:
            self.free_step, self._free_bound = h_next, max_step_bound

    def planned_in_engine(self, prev, landing, free, free_bound, planned, reset) -> None:
        """The state `plan` leaves after the plans the compiled engine made (nothing, or a
        landing: `mechsim.run.segment`): its previous step's (t, rate) `prev`, `landing`,
        the longest free step `free` (its `free_bound`), the latest prediction `planned`
        ((t, time to the configuration), the rate of fall) where one was made, and
        whether s rose at a step since (`reset`: a declined crossing is forgotten)."""
        self._prev, self.landing = prev, landing
        self.free_step, self._free_bound = free, free_bound
        if planned is not None:
            self._planned, self._rate = planned
        if reset:
            self.standing_down, self._declined = False, None

    def plan(self, s, rate, t, h_next, max_step_bound=False):
        """What to do after a step ending at t with σ_min/σ_max = s falling at `rate` and a
        next step of h_next proposed (`max_step_bound`: h_next is the run's max_step): None
        (go on), ("land", h) (take a step of h to the landing point), or ("cross", t*)."""
        replan = self._planned is not None and self._planned[0] == t    # after a decline
        prev = None if replan else self._prev
        if not replan:
            self._prev = (t, rate)
        if rate >= 0.0:
            self.landing, self.standing_down, self._prev = None, False, None
            self._declined = None
            self.free_step = None
        if not rate < 0.0 or self.standing_down:
            return None
        if s < self.edge:                # landed in the band: the formulation steps through
            self.landing, self.standing_down = None, True
            return None
        self._rate = -rate
        # s falls faster than its tangent where the motion accelerates into the
        # configuration: with the rate's change since the previous step, the instant is the
        # root of s + ṡ τ + ½ s̈ τ² (the linear prediction when there is no curvature yet).
        if replan:
            to_star = self._planned[1]
        else:
            curv = (rate - prev[1]) / (t - prev[0]) if prev is not None and t > prev[0] else 0.0
            disc = rate * rate - 2.0 * curv * s
            to_star = 2.0 * s / (-rate + np.sqrt(disc)) if disc > 0.0 else s / -rate
            self._planned = (t, to_star)
        if self.landing is None:
            if to_star > 3.0 * h_next:
                self.note_step(h_next, max_step_bound)
                return None
            # Start and end clear of the band (s ≈ |rate| (t* − t) near the configuration);
            # twice as far when the free step was the run's max_step, which says nothing of
            # how long a step the motion allows: closer, the round-off of q̈ declines the
            # bridge (docs/design-notes.md, passage bridge).
            floor = (3.2 if self._free_bound else 1.6) * self.edge / -rate
            self.landing = max(LANDING * (self.free_step or h_next), floor)
        if to_star <= 1.5 * self.landing and not replan:
            return "cross", t + to_star
        # From far off the prediction may be short by tens of percent (double four-bar):
        # go three quarters of the way first, then land.
        h = to_star - max(self.landing, 0.25 * to_star)
        if h <= 0.0:                     # declined already closer than the landing point
            self.landing, self.standing_down = None, True
            return None
        return ("land", h) if h < h_next else None

    def _consistent(self, q, v, t):
        prob = self.problem
        # Close to the configuration a residual of Φ is amplified by 1/σ_min² in q̈: one
        # Newton step past 1e-13 takes it to round-off.
        done = prob.algebra.project_state(t, q, v, 1e-13, extra=1) if self.compiled else None
        if done is None:
            done = prob.project_state(q, v, t, 1e-13, extra=1)
        if done is not None:
            return done
        q, _, _ = prob.project_positions(q, t, tol=1e-13)
        q, _, _ = prob.project_positions(q, t, tol=0.0, max_iter=1)
        return q, prob.project_velocities(q, v, t)

    def _f(self, t, y):
        """The rate of the state y = [q; v] (and the extension's numbers)."""
        self.problem.counters.rhs += 1
        self.evaluations += 1
        n = self.problem.n
        q, v = y[:n], y[n:2 * n]
        a = self.accelerations(t, q, v)
        if self.extension is None:
            return np.concatenate([v, a])
        return np.concatenate([v, a, self.extension.rates(t, q, v, a, y[2 * n:])])

    def _settled(self, y, t):
        """The state y put on the constraints (and the extension's numbers with it)."""
        n = self.problem.n
        q, v = self._consistent(y[:n], y[n:2 * n], t)
        if self.extension is None:
            return np.concatenate([q, v])
        return np.concatenate([q, v, self.extension.consistent(t, q, v, y[2 * n:])])

    def _history(self, t_n, y_n, ts, engine):
        """Consistent states at the times `ts` (decreasing) before t_n on the trajectory
        through y_n: integrated backwards, away from the configuration, at a hundredth of
        the run's tolerances (DOP853, its steps compiled where `rate` gives the engine's
        rate); None if that integration fails or grinds (`HISTORY_BUDGET` evaluations a
        point: a configuration it cannot resolve). With them the rates at t_n and at
        them where the engine computed those too (`_history_in_engine` on `engine`,
        `_engine_steps()`), else None."""
        inner = self._inner
        if self.rate is not None and self.extension is None:
            done = self._history_in_engine(t_n, y_n, ts, inner, engine)
            if done is not None:
                return done or None
        start = {}
        if self.rate is not None and self.extension is None:
            start = self._history_start(t_n, y_n, ts, inner, engine)
        solver = CompiledDOP853(self._f, t_n, y_n, ts[-1], rtol=inner.rtol, atol=inner.atol,
                                **start)
        if self.rate is not None and self.extension is None:
            solver.rate = self._history_rate
            solver.nfev += bool(start)      # the starting step's rate, as the engine counts
        states, k = [], 0
        while k < len(ts):
            solver.step()
            if solver.status == "failed" or solver.nfev > HISTORY_BUDGET * len(ts):
                return None
            passed = []
            while k < len(ts) and solver.direction * (solver.t - ts[k]) >= 0.0:
                passed.append(ts[k])
                k += 1
            if passed:
                interpolant = solver.dense_output()
                states += [self._settled(interpolant(tk), tk) for tk in passed]
        return states, None

    @property
    def edge(self) -> float:
        """The band's edge: `EDGE` truncation cuts."""
        return EDGE * self._cut()

    def stand_down(self):
        """Leave the present passage to the formulation (a crossing would end past the
        run's end)."""
        self.landing, self.standing_down, self._declined = None, True, None

    def _norm(self, e, a, b):
        return error_norm(e, a, b, self.rtol, self.atol)

    def cross(self, t_n, q_n, v_n, t_star, measure, iterations=4, t_floor=-np.inf,
              extra=None, ratio_row=None):
        """One Adams step from (q_n, v_n) at t_n over t*; `measure(q, t)` gives σ_min/σ_max
        (`ratio_row`: σ_k/σ_max of J̃'s singular values alone, the monitor's `ratio_row`,
        else None). Its history reaches back no further than `t_floor` (the end of the
        previous passage, or the start of the run): integrated backwards through an
        earlier passage it would grind through that configuration. `extra`: the
        extension's numbers at t_n. Returns the `Crossing`, or None: then the approach
        goes on with a shorter landing distance, or the bridge stands down for this
        passage."""
        n = self.problem.n
        y_n = np.concatenate([q_n, v_n] + ([] if extra is None else [extra]))
        step = self._step(t_n, y_n, SPAN * (t_star - t_n), t_floor, measure, ratio_row,
                          iterations)
        if step is None:
            return None
        y_n, F, history, H, nodes, ys, errs = step
        t_b = t_n + H
        # The order: correctors on the end point and the k − 1 newest history points for
        # k = 3 …; the difference between orders k + 1 and k estimates the error of order k,
        # and the order with the smallest estimate is kept with its extrapolation to k + 1
        # (as Adams codes choose their order). Close to the configuration the estimates stop
        # falling with the order: the accelerations there carry round-off amplified by
        # 1/σ_min² (measured on the double four-bar: a consistent state re-projected moves
        # q̈ by 5e-8 at σ_min/σ_max = 7e-4), and a shorter bridge would only be noisier.
        # Milne's ‖y_c − y_p‖ is not used: the predictor's extrapolation amplifies that
        # noise (on the double four-bar at rtol 1e-9 it read 20× the corrector difference,
        # which itself read 6–100× the true error of the crank's rate).
        best = int(np.argmin(errs))
        err = self.last_estimate = errs[best]
        # At the floor the only alternative is stepping through the band (on the 40-window
        # chain at rtol 3e-9, one passage so cost 110 s): there an estimate up to
        # `FLOOR_ACCEPT` (or `FLOOR_ACCEPT_RELATIVE`) is taken, and counted, since it
        # bounds the error of the order below the kept one (measured 6–100× the true error).
        at_floor = self.landing is not None and self.landing <= 1.01 * self._floor()
        accept = max(FLOOR_ACCEPT, FLOOR_ACCEPT_RELATIVE / self.rtol)
        if err > 1.0 and not (at_floor and err <= accept):
            declined = self._declined
            if declined is not None and err >= declined[0]:
                # Closer was no better: the estimate is the round-off of q̈ near the
                # configuration, which a still closer landing only amplifies
                # (docs/design-notes.md, passage bridge). The best bridge declined so far is
                # taken instead; its end lies past the present landing point.
                return self._take_declined(accept)
            if err <= max(accept, LAST_RESORT_RELATIVE / self.rtol):
                self._declined = (err, self._finish(n, t_n, t_b, H, y_n, ys, best, nodes, F,
                                                    t_star, history))
            if self._declined is not None and (
                    at_floor or declined is not None and err > ROUND_OFF_GAIN * declined[0]):
                return self._take_declined(accept)
            return self._decline(err)
        if err > 1.0:
            self.over_tolerance += 1
        self.landing = self._declined = None
        return self._finish(n, t_n, t_b, H, y_n, ys, best, nodes, F, t_star, history)

    def _step(self, t_n, y_n, H, t_floor, measure, ratio_row, iterations):
        """The Adams step over the passage from y_n at t_n, first H long (`cross`'s
        arguments): y_n put onto the constraints, the rates F of its history, the history's
        states in time order, the step's length (lengthened until its end lies out of the
        band), its nodes, and the orders' ends and estimates; None where the bridge
        declines or stands down."""
        engine = self._engine_steps()
        ts = self._times(t_n, 0.5 * H, t_floor)
        if ts is None:
            return None
        nodes = step_nodes(ts, H)
        attempt = self._attempt_in_engine(ts, nodes, y_n, H, ratio_row, iterations, engine)
        if attempt is False:
            self.landing, self.standing_down = None, True
            return None
        if attempt is None:
            start = self._start(ts, y_n, engine)
            if start is None:
                return None
            y_n, F, history = start
            done, tried = None, 0
        else:
            y_n, F, history, done = attempt
            tried = 1
        if done is None:
            H = self._out_of_band(y_n, F, ts, t_n, H * 1.3 if tried else H, measure,
                                  6 - tried)
            if H is None:
                return self._decline(np.inf)
            nodes = step_nodes(ts, H)
        t_b = t_n + H
        if done is None:
            done = self._corrector_in_engine(y_n, F, nodes, t_b, H, iterations, engine)
        if done is not None:
            _, ys, errs = done
        else:
            Fb = np.vstack([self._corrected_end(y_n, F, nodes, t_b, H, iterations), F])
            ys = [y_n + H * (step_weights(nodes[:k]) @ Fb[:k])
                  for k in range(3, nodes.size + 1)]
            errs = [self._norm(hi - lo, y_n, hi) for lo, hi in zip(ys, ys[1:])]
        return y_n, F, history, H, nodes, ys, errs

    def _times(self, t_n, D, t_floor):
        """The times of a step's history from t_n: newest first, D apart, back no further
        than t_floor; None where that is too short (the bridge declines)."""
        span = t_n - t_floor
        points = self.order if not span < np.inf else min(self.order, int(span / D) + 1)
        if points < MIN_HISTORY:
            self._decline(np.inf)
            return None
        return t_n - D * np.arange(points)

    def _start(self, ts, y_n, engine):
        """The history of the step from y_n at ts[0] at the times ts: y_n put onto the
        constraints, the rates F at ts, and the states (t, q, v) in time order; None
        where it cannot be integrated (the bridge stands down). `engine`:
        `_engine_steps()`."""
        t_n = ts[0]
        y_n = self._settled(y_n, t_n)
        done = self._history(t_n, y_n, ts[1:], engine)
        if done is None:
            self.landing, self.standing_down = None, True
            return None
        states, F = done
        if F is None:
            F = np.array([self._f(tk, y) for tk, y in zip(ts, [y_n] + states)])
        return y_n, F, self._states(ts, y_n, states)

    def _states(self, ts, y_n, states):
        """The history's states (t, q, v) in time order, y_n at ts[0] the last."""
        n = self.problem.n
        return [(tk, y[:n], y[n:2 * n]) for tk, y in zip(ts[::-1], list(states[::-1]) + [y_n])]

    def _out_of_band(self, y_n, F, ts, t_n, H, measure, tries=6):
        """The step's length, from H lengthened by 1.3 (`tries` lengths in all) until the
        predicted end lies out of the band (σ_min/σ_max above twice its edge); None where
        it does not."""
        n = self.problem.n
        for _ in range(tries):
            y_p = y_n + H * (step_weights((ts - t_n) / H) @ F)
            if measure(y_p[:n], t_n + H) > 2.0 * self.edge:
                return H
            H *= 1.3
        return None

    def _corrected_end(self, y_n, F, nodes, t_b, H, iterations):
        """The rate at the step's end t_b, from corrector iterations of the full order
        started at the prediction, until they settle (1 % of the tolerance)."""
        y_c = y_n + H * (step_weights(nodes[1:]) @ F)
        w = step_weights(nodes)
        for _ in range(iterations):
            f_b = self._f(t_b, self._settled(y_c, t_b))
            y_new = y_n + H * (w @ np.vstack([f_b, F]))
            settled = self._norm(y_new - y_c, y_c, y_new) < 1e-2
            y_c = y_new
            if settled:
                break
        return f_b

    def _finish(self, n, t_n, t_b, H, y_n, ys, best, nodes, F, t_star, history):
        """The `Crossing` with the corrector of order `best`."""
        k = best + 4                            # nodes of the kept corrector
        y_b = self._energy_kept(y_n, self._settled(ys[best + 1], t_b))
        Fc = np.vstack([self._f(t_b, y_b), F[:k - 1]])
        nodes = nodes[:k]
        engine = getattr(self.problem.algebra, "engine", None) if self.compiled else None

        def interpolant(tk):
            s = (np.atleast_1d(tk) - t_n) / H
            y = engine.adams_values(y_n, H, nodes, Fc, s, QUADRATURE) if engine is not None \
                else y_n[None, :] + H * (integration_weights(nodes, s) @ Fc)
            return y[0] if np.ndim(tk) == 0 else y.T

        return Crossing(t_b, y_b[:n], y_b[n:2 * n], interpolant, t_star, history, H, k - 1,
                        None if self.extension is None else y_b[2 * n:], Fc[0])

    def _energy_kept(self, y_n, y_b):
        """The bridge's end y_b with its velocities scaled so that a conservative
        mechanism's energy (kinetic, gravity's, the springs' and the beams' strain) is that
        of the start y_n: v ↦ k v is the smallest such change in the mass metric and keeps
        Φ_q v = 0. Where nothing but those forces does work, the exact motion keeps its
        energy over the bridge, so this takes out of the bridge's error the part that
        changes the energy, which a mechanism turning over again and again turns into a
        phase error growing with every turn (a chain over its top: relative errors of the
        energy grow ~45× in its speed there); the bridge's round-off near the
        configuration is mostly that part. Unchanged where something else does work
        (loads, damping, friction, drivers: their work over the bridge is not known to
        its accuracy), where the kinetic energy vanishes, or where k − 1 exceeds
        `ENERGY_KEPT` tolerances (or `LAST_RESORT_RELATIVE`): such an energy change is not
        the bridge's error and stays visible in the energy balance."""
        p = self.problem
        if self._conservative is None:
            self._conservative = not p.work_channels
        if not self._conservative:
            return y_b
        n = p.n
        q_n, v_n, q_b, v_b = y_n[:n], y_n[n:2 * n], y_b[:n], y_b[n:2 * n]
        kinetic = float(p.kinetic_energy(q_b, v_b))
        wanted = float(p.kinetic_energy(q_n, v_n) + p.stored_energy(q_n) - p.stored_energy(q_b))
        if not (kinetic > 0.0 and wanted > 0.0):
            return y_b
        k = np.sqrt(wanted / kinetic)
        if not abs(k - 1.0) <= max(ENERGY_KEPT * self.rtol, LAST_RESORT_RELATIVE):
            return y_b
        y_b = y_b.copy()
        y_b[n:2 * n] *= k
        return y_b

    def _take_declined(self, accept):
        """The best declined crossing, taken (counted over tolerance, and among `beyond`
        where its estimate exceeds `accept`)."""
        err, crossing = self._declined
        self._declined, self.landing = None, None
        self.over_tolerance += 1
        if err > accept:
            self.beyond.append((crossing.t_star, err * self.rtol))
        return crossing

    def _floor(self):
        """The closest landing distance: σ_min/σ_max of 1.2 `EDGE` cuts at the present rate."""
        return 1.2 * self.edge / self._rate if self._rate > 0.0 else 0.0

    def _decline(self, err):
        """Not crossed: land closer while the band allows (the error falls as d^(k+1) where
        it is truncation; where it is the round-off of the accelerations near the
        configuration it does not, and the floor ends the attempts), else stand down for
        this passage."""
        if self.landing is None:         # called outside a planned approach
            return None
        floor = self._floor()
        if self.landing <= 1.01 * floor:
            self.landing, self.standing_down = None, True
        else:
            self.landing = max(floor, self.landing * min(0.5, (0.5 / err) ** (1.0 / (self.order + 1))))
        return None


def bridge_passage(form, bridge, monitor, solver, bound, t, q, v, t_end, extra=None):
    """Approach and cross a singular passage ahead with the formulation's bridge
    (`mechsim.formulations.bridge`): its `Crossing` when crossed, else None, with the next
    step limited to the landing point (`StepBound.land`) while approaching. A crossing
    that would end after t_end is not taken: the formulation steps to the end on its own.
    `extra`: the numbers the bridge's extension carries, at t."""
    s, rate = monitor.last * monitor.peak, monitor.rate * monitor.peak
    h_free = proposed_step(solver)
    if not h_free:                   # a restarted integrator that has not stepped yet
        return None
    max_step = bound.max_step
    h_next = min(h_free, max_step)
    plan = bridge.plan(s, rate, t, h_next, max_step_bound=h_free >= max_step)
    if plan is not None and plan[0] == "cross":
        if t + SPAN * (plan[1] - t) >= t_end:
            bridge.stand_down()
            return None
        crossed = bridge.cross(t, q, v, plan[1], monitor.ratio,
                               t_floor=monitor.clear_since, extra=extra,
                               ratio_row=monitor.ratio_row)
        if crossed is not None and crossed.t_b >= t_end:
            bridge.stand_down()
            return None
        if crossed is not None:
            return crossed
        plan = bridge.plan(s, rate, t, h_next, h_free >= max_step)   # land closer, or stand down
    if plan is not None and plan[0] == "land":
        bound.land(solver, plan[1])
    return None
