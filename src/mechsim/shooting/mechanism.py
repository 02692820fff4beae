"""Periodic steady states of driven mechanisms by shooting.

The unknowns are the independent coordinates and velocities (q_v, v_v), chosen by LU
pivoting of Φ_q at the start; the dependent ones follow from Φ(q, t₀) = 0 (Newton) and
Φ_q v + Φ_t = 0, so every flow starts from a consistent state. The flow over one period is
an ordinary constrained simulation (any method of the registry).
"""

from __future__ import annotations

import numpy as np

from ..newton import newton
from .oscillators import PeriodicProblem, Trajectory


class MechanismPeriodicProblem(PeriodicProblem):
    def __init__(self, mechanism, period: float, t0: float = 0.0, **simulate_options):
        if not (isinstance(period, (int, float)) and period > 0 and np.isfinite(period)):
            raise ValueError(f"steady_state: `period` must be positive, got {period!r}")
        from ..formulations.partitioned import Partitioned
        self.mech, self.period, self.t0 = mechanism, float(period), float(t0)
        self.problem = mechanism.problem()
        report = mechanism.assemble(t=t0)
        self.q_ref = report.q
        J = self.problem.phi_q(report.q, t0)
        chooser = Partitioned(self.problem, 1e-8, 1e-10)
        basis = chooser.choose(J)
        self.ind, self.dep = basis.ind, basis.dep
        if self.ind.size == 0:
            raise ValueError(f"steady_state: mechanism '{mechanism.name}' has no degree of "
                             "freedom; its motion is fully prescribed")
        self.n = 2 * self.ind.size
        self.options = {"rtol": 1e-10, "atol": 1e-12, **simulate_options}
        self.guess0 = np.concatenate([report.q[self.ind], report.v[self.ind]])

    def initial_state(self, u):
        u = self.check(u)
        f = self.ind.size
        prob, t = self.problem, self.t0
        q = self.q_ref.copy()
        q[self.ind] = u[:f]

        def correct(q, phi, J, slow):
            q = q.copy()
            q[self.dep] -= np.linalg.lstsq(J[:, self.dep], phi, rcond=None)[0]
            return q

        done = newton(q, lambda q: prob.position_terms(q, t), correct, 1e-13, 30)
        q = done.x
        if not done.converged:
            raise ValueError("steady_state: the independent coordinates "
                             f"{np.round(u[:f], 6).tolist()} admit no assembled configuration")
        J = prob.phi_q(q, t)
        v = np.zeros_like(q)
        v[self.ind] = u[f:]
        v[self.dep] = np.linalg.lstsq(J[:, self.dep], -(J[:, self.ind] @ u[f:])
                                      - prob.phi_t(q, t), rcond=None)[0]
        return q, v

    def flow(self, u, samples=200):
        from ..solver import simulate
        q, v = self.initial_state(u)
        # The flow is evaluated many times per Newton iteration: the work of its dampers
        # and drivers is integrated only where the caller asks for it.
        options = {"work": False, **self.options}
        res = simulate(self.problem, q, v, t_start=self.t0, t_end=self.t0 + self.period,
                       output_step=self.period / samples, **options)
        if res.status != "success":
            raise ValueError(f"steady_state: the flow over one period failed: {res.message}")
        x = np.hstack([res.q[:, self.ind], res.v[:, self.ind]])
        traj = Trajectory(res.t, x)
        traj.result = res
        return traj
