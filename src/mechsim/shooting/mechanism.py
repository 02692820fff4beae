"""Periodic steady states of driven mechanisms by shooting.

The unknowns are the independent coordinates and velocities (q_v, v_v), chosen by LU
pivoting of Φ_q at the start; the dependent ones follow from Φ(q, t₀) = 0 (Newton) and
Φ_q v + Φ_t = 0 (`mechsim.engineering.reduced`), so every flow starts from a consistent
state. The flow over one period is
an ordinary constrained simulation (any method of the registry), or for a mechanism with
stops or friction the sequence of runs between its events (`mechsim.engineering.impacts`).
"""

from __future__ import annotations

import numbers

import numpy as np

from ..records import Status
from .oscillators import PeriodicProblem, Trajectory


class MechanismPeriodicProblem(PeriodicProblem):
    def __init__(self, mechanism, period: float, t0: float = 0.0, **simulate_options):
        if not (isinstance(period, numbers.Real) and period > 0 and np.isfinite(period)):
            raise ValueError(f"steady_state: `period` must be positive, got {period!r}")
        from ..engineering.reduced import ReducedCoordinates
        self.mech, self.period, self.t0 = mechanism, float(period), float(t0)
        self.problem = mechanism.problem()
        report = mechanism.assemble(t=t0)
        self.reduced = ReducedCoordinates(self.problem, report.q, t0)
        self.ind = self.reduced.ind
        if self.ind.size == 0:
            raise ValueError(f"steady_state: mechanism '{mechanism.name}' has no degree of "
                             "freedom; its motion is fully prescribed")
        self.n = 2 * self.ind.size
        self.options = {"rtol": 1e-10, "atol": 1e-12, **simulate_options}
        self.guess0 = np.concatenate([report.q[self.ind], report.v[self.ind]])

    def initial_state(self, u):
        """The consistent (q, v) whose independent coordinates and velocities are u."""
        u = self.check(u)
        f, reduced = self.ind.size, self.reduced
        try:
            q = reduced.positions(u[:f] - reduced.q_ref[self.ind])
        except ValueError:
            raise ValueError("steady_state: the independent coordinates "
                             f"{np.round(u[:f], 6).tolist()} admit no assembled configuration"
                             ) from None
        return q, reduced.velocities(q, u[f:])

    def period_map(self, u):
        """x(T) from x(0) = u: a flow recording its end alone (the differences of the
        Jacobians and the monodromy need no samples inside the period)."""
        return self.flow(u, samples=1).x[-1]

    def flow(self, u, samples=200):
        from ..run.solver import simulate
        q, v = self.initial_state(u)
        # The flow is evaluated many times per Newton iteration: the work of its dampers
        # and drivers is integrated only where the caller asks for it.
        options = {"work": False, **self.options}
        if self.mech.stops or self.mech.frictions:
            from ..engineering.impacts import PiecewiseRun      # impacts, stick and slip
            res = PiecewiseRun(self.mech, q, v, self.t0 + self.period, options.pop(
                "method", None), dict(options, t_start=self.t0,
                                      output_step=self.period / samples)).run()
        else:
            res = simulate(self.problem, q, v, t_start=self.t0, t_end=self.t0 + self.period,
                           output_step=self.period / samples, **options)
        if res.status != Status.SUCCESS:
            raise ValueError(f"steady_state: the flow over one period failed: {res.message}")
        x = np.hstack([res.q[:, self.ind], res.v[:, self.ind]])
        traj = Trajectory(res.t, x)
        traj.result = res
        return traj
