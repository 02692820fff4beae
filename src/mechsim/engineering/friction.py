"""Stick and slip of joints with friction (`mechsim.model.friction.Friction`), for the runs
of `mechsim.engineering.impacts`: which way each joint slides or whether it sticks, the
events that end a piece of the run (a sliding joint's rate reaching zero, a stuck joint's
holding force reaching μ_s times its load), and the switches a result lists.

Within a piece every joint keeps its mode, so the right-hand side is smooth there and the
integrator keeps its order; the forces themselves are solved with the reactions at every
evaluation (`mechsim.problem.friction`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..problem.friction import BACKWARD, FORWARD, STUCK, FrictionError
from .geometry import joint_gradient, joint_path_rates

MODE_NAMES = {FORWARD: "slipping forwards", BACKWARD: "slipping backwards", STUCK: "stuck"}


@dataclass(frozen=True)
class FrictionSwitch:
    """A joint with friction changing its mode at time `t` [s]: `before` and `after` are
    "slipping forwards", "slipping backwards" or "stuck" (forwards: its coordinate
    growing); `force` is the friction force or torque there (N or N·m, on body_b along the
    joint's coordinate) and `limit` μ_s times the joint's load."""
    t: float
    friction: str
    before: str
    after: str
    force: float
    limit: float


def initial_modes(problem, t, q, v) -> np.ndarray:
    """Each joint's mode at the start: the way it moves, or where it is at rest, whether
    it sticks (`decide`)."""
    model = problem.friction
    rates = np.array([joint_gradient(e.geometry, q) @ v for e in model.elements])
    modes = np.where(rates > 0.0, FORWARD, BACKWARD)
    for k in np.flatnonzero(rates == 0.0):
        modes[k] = STUCK
    for k in np.flatnonzero(rates == 0.0):
        modes[k], _ = decide(problem, modes, k, t, q, v)
    return modes


def decide(problem, modes, k, t, q, v):
    """(mode, (force, limit)) of joint k at a state where its rate is zero: stuck where the
    force that holds it still is within μ_s times its load, else slipping against that
    force; a joint whose motion the other constraints prescribe (no force of its own can
    hold it) goes the way its acceleration takes it."""
    element = problem.friction.elements[k]
    trial = np.array(modes, int)
    trial[k] = STUCK
    try:
        state = problem.friction_state(t, q, v, trial)
    except FrictionError:
        state = None
    if state is not None:
        force, limit = state.forces[k], element.friction.mu_static * state.loads[k]
        if abs(force) <= limit:
            return STUCK, (force, limit)
        return (BACKWARD if force > 0.0 else FORWARD), (force, limit)
    trial[k] = FORWARD if modes[k] != FORWARD else BACKWARD
    state = problem.friction_state(t, q, v, trial)
    J, gamma = problem.dynamics_terms(q, v, t)
    qdd = problem.accelerations(J, problem.load_model.forces(t, q, v) + state.generalized(),
                                gamma, q)[0]
    sdd = state.gradients[k] @ qdd + joint_path_rates(element.geometry, q, v)[2][0]
    mode = FORWARD if sdd > 0.0 else BACKWARD if sdd < 0.0 else trial[k]
    return mode, (state.forces[k], element.friction.mu_static * state.loads[k])


class FrictionEvents:
    """The events of a piece in which the joints keep `modes`: a sliding joint's σ ṡ
    (≥ 0 while it slides its way), a stuck joint's μ_s L − ‖f‖ (≥ 0 while it holds)."""

    def __init__(self, problem, modes):
        self.problem, self.modes = problem, np.asarray(modes, int)

    def values(self, t, q, v):
        model = self.problem.friction
        if np.any(self.modes == STUCK):
            state = self.problem.friction_state(t, q, v)
            rates = state.rates
        else:
            state = None
            rates = np.array([joint_gradient(e.geometry, q) @ v for e in model.elements])
        out = self.modes * rates
        for k in np.flatnonzero(self.modes == STUCK):
            out[k] = model.elements[k].friction.mu_static * state.loads[k] - \
                abs(state.forces[k])
        return out

    def describe(self, k) -> str:
        name = self.problem.friction.elements[k].name
        if self.modes[k] == STUCK:
            return f"friction '{name}' let its joint slip"
        return f"the joint of friction '{name}' came to rest"


def stop_moving(problem, k, t, q, v):
    """v with joint k's rate exactly zero (the nearest such velocity in the mass metric)."""
    g = joint_gradient(problem.friction.elements[k].geometry, q)
    return problem.project_velocities(q, v, t, extra=(g[None], np.zeros(1)))
