"""The compiled engine's side of a passage bridge's crossing
(`mechsim.formulations.bridge`): its history, its corrector, or a whole attempt in one call
of the engine where the engine takes them (`mechsim.codegen.steps.PlainSteps`: its
projections and rates compiled, no sensitivities carried), their rates and projections
counted as the bridge's own Python ones count theirs."""

from __future__ import annotations

import numpy as np

from ..integrators.adams import order_weights, step_weights
from ..integrators.compiled import SAFETY, dense_matrix, extra_tableau, tableau

# The most right-hand sides a history's backward integration may spend, per point.
HISTORY_BUDGET = 400


def step_nodes(ts, H):
    """The nodes of a bridge's Adams step of H from ts[0] over its history at the times ts,
    in units of the step: its end 1, then (ts − ts[0]) / H."""
    return np.concatenate([[1.0], (ts - ts[0]) / H])


def corrector_weights(nodes):
    """The weights the engine's corrector takes on a step's `nodes` (`step_nodes`): the
    prediction's, the full order's correction and every order's from 3 (its last row the
    full order's)."""
    orders = order_weights(nodes, 3)
    return step_weights(nodes[1:]), orders[-1], orders


class EngineCrossing:
    """The engine's crossing for `PassageBridge`, whose attributes it reads: `problem`,
    `rate` (() -> the engine's rate, or None), `compiled`, `extension`, `rtol`, `atol`,
    `_inner` (the history's tolerances), `edge`, `_states` (a history's states in time
    order), `evaluations` (which it adds to) and `_atols` (a dict it fills)."""

    def _engine_steps(self):
        """(the engine's rate, its `PlainSteps`) where the engine takes the bridge's
        history and corrector (its projections and rates compiled, no sensitivities
        carried), else (rate or None, None)."""
        rate = self.rate() if self.compiled and self.extension is None else None
        steps = self.problem.algebra.plain_steps(
            self.problem.n, 1, (tableau(), extra_tableau(), dense_matrix())) \
            if rate is not None and SAFETY is not None else None
        return rate, steps

    def _history_in_engine(self, t_n, y_n, ts, inner, engine):
        """`_history` taken in the engine where it has the steps (`mechsim_history`: the
        same steps, states and rates, its integrator's start too): (states, the rates at
        t_n and at them), False where the integration fails or grinds, None where the
        engine does not take it (the Python loop does); `engine`: `_engine_steps()`."""
        rate, steps = engine
        if steps is None:
            return None
        steps.start_integrator(t_n, ts[-1], inner.rtol, self._atol(y_n.size, True))
        done = steps.history(rate.context, rate, y_n, ts, HISTORY_BUDGET * len(ts))
        if not done:
            return done
        states, F, evaluations, projections = done
        self._counted_history(rate, evaluations, len(F), projections)
        return list(states), F

    def _history_start(self, t_n, y_n, ts, inner, engine) -> dict:
        """The first step and the rate at y_n as `_history_in_engine` starts, for the
        history the Python loop integrates: {first_step, f0} for `CompiledDOP853`, their
        two rates counted as the bridge's, or {} (scipy's start) where the engine has no
        steps or declines a rate. (scipy's start sums its norms in another order: a first
        step an ulp apart, which a history at a hundredth of the run's tolerances turns
        into other steps.)"""
        rate, steps = engine
        if steps is None:
            return {}
        steps.start_integrator(t_n, ts[-1], inner.rtol, self._atol(y_n.size, True))
        done = steps.history_start(rate.context, rate, y_n)
        if done is None:
            return {}
        h, f0, evaluations = done
        self._history_rate().counted(evaluations)
        return {"first_step": h, "f0": f0}

    def _attempt_in_engine(self, ts, nodes, y_n, H, ratio_row, iterations, engine):
        """`_start`, `_out_of_band`'s first length and `_corrector_in_engine` in one call of
        the engine (`mechsim_bridge_attempt`: the same projections, steps, rates and
        corrections, counted as they count theirs) where it takes the history and the
        corrector and the monitor's ratio is σ_{m−1}/σ_max (`ratio_row`); `nodes`: the
        step's (`step_nodes`). (y_n put onto
        the constraints, the rates F at ts, the states (t, q, v) in time order, the
        corrector's (f_b, the orders' ends, their estimates) or None where the prediction
        at H lies in the band); False where the history fails or grinds; None where the
        engine does not take the attempt (`_start` and the rest take it)."""
        rate, steps = engine
        p = self.problem
        if steps is None or ratio_row != p.m - 1 or p.m > p.n:
            return None
        steps.start_integrator(ts[0], ts[-1], self._inner.rtol, self._atol(y_n.size, True))
        done = steps.attempt(rate.context, rate, ts, y_n, H, HISTORY_BUDGET * (len(ts) - 1),
                             ratio_row, 2.0 * self.edge, corrector_weights(nodes),
                             (self.rtol, self._atol(y_n.size)), iterations)
        if done == -1:
            return None
        if done == -2:
            return False
        y_n, states, F, corrected, counts = done
        settle, evaluations, projections, rates, corrections = counts
        self._counted_history(rate, evaluations, len(F), projections + settle)
        if corrected is not None:
            self._counted(rates, corrections)
            f_b, Y, errs = corrected
            corrected = f_b, list(Y), errs
        return y_n, F, self._states(ts, y_n, states), corrected

    def _corrector_in_engine(self, y_n, F, nodes, t_b, H, iterations, engine):
        """`_corrected_end` and the orders' ends and estimates of `cross` in the engine
        (`mechsim_bridge_corrector`: the same iterations and orders in its own arithmetic),
        their rates and projections counted as `_f` and `_settled` count them: (f_b, the
        orders' ends, their estimates); None where the engine does not take it (no engine,
        sensitivities carried, a projection or a rate declined: the Python corrector);
        `engine`: `_engine_steps()`."""
        rate, steps = engine
        if steps is None:
            return None
        done = steps.corrector(rate.context, rate, y_n, F, corrector_weights(nodes), H, t_b,
                               (self.rtol, self._atol(y_n.size)), iterations)
        if done is None:
            return None
        f_b, Y, errs, rates, projections = done
        self._counted(rates, projections)
        return f_b, list(Y), errs

    def _history_rate(self):
        """The engine's rate for the history's steps (`rate`), its evaluations counted as
        the bridge's."""
        rate = self.rate()
        if rate is None:
            return None
        counted = rate.counted

        def both(evaluations):
            counted(evaluations)
            self.evaluations += evaluations
        return rate.counting(both)

    def _atol(self, size, inner=False) -> np.ndarray:
        """atol (the history's, with `inner`) for each of `size` entries, as the engine
        reads it (made once)."""
        atol = self._atols.get((inner, size))
        if atol is None:
            atol = self._atols[inner, size] = np.empty(size)
            atol[:] = self._inner.atol if inner else self.atol
        return atol

    def _counted_history(self, rate, evaluations, rates, projections) -> None:
        """A history the engine integrated: its steps' `evaluations` counted on the engine's
        `rate` and as the bridge's, its `rates` at the history's states and their chord
        iterations as `_f` and `_settled` count theirs."""
        rate.counted(evaluations)
        self.evaluations += evaluations
        self._counted(rates, projections)

    def _counted(self, rates, projections) -> None:
        """Rates and chord iterations the engine took for the bridge, counted as `_f` and
        `_settled` count theirs."""
        counters = self.problem.counters
        counters.projections += projections
        counters.rhs += rates
        counters.factorizations += rates
        self.evaluations += rates
