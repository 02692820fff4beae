"""Stick and slip of joints with friction (`mechsim.model.friction.Friction`), for the runs
of `mechsim.engineering.impacts`: which way each joint slides or whether it sticks, the
events that end a piece of the run (a sliding joint's rate reaching zero, a stuck joint's
holding force reaching μ_s times its load), and the switches a result lists.

Within a piece every joint keeps its mode, so the right-hand side is smooth there and the
integrator keeps its order; the forces themselves are solved with the reactions at every
evaluation (`mechsim.problem.friction`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..problem.friction import BACKWARD, FORWARD, FREE, STUCK, FrictionError
from ..problem.geometry import joint_gradient, joint_path_rates

MODE_NAMES = {FORWARD: "slipping forwards", BACKWARD: "slipping backwards", STUCK: "stuck"}


@dataclass(frozen=True)
class FrictionSwitch:
    """A joint with friction changing its mode at time `t` [s]: `before` and `after` are
    "slipping forwards", "slipping backwards" or "stuck" (forwards: its coordinate
    growing); `force` is the friction force or torque there (N or N·m, on body_b along the
    joint's coordinate) and `limit` μ_s times the joint's load. A run carrying
    sensitivities keeps the switch time's to each Parameter ({name: dt/dk})."""
    t: float
    friction: str
    before: str
    after: str
    force: float
    limit: float
    time_sensitivity: dict = field(default_factory=dict)


def initial_modes(problem, t, q, v, held=()) -> np.ndarray:
    """The mode of every element of the problem's `FrictionModel`: the stops' elements
    `held` (indices) hold their joints (`STUCK`), the other stops none (`FREE`); a joint's
    friction is `FREE` while its stop holds it, else goes the way its joint moves, or at
    rest, sticks or slips as `decide` says."""
    model = problem.friction
    elements = model.elements
    holding = {elements[k].geometry.joint.name for k in held}
    modes = np.full(len(elements), FREE)
    modes[list(held)] = STUCK
    resting = []
    for k in model.frictions:
        if elements[k].geometry.joint.name in holding:
            continue
        rate = joint_gradient(elements[k].geometry, q) @ v
        modes[k] = FORWARD if rate > 0.0 else BACKWARD if rate < 0.0 else STUCK
        if rate == 0.0:
            resting.append(k)
    for k in resting:
        modes[k], _ = decide(problem, modes, k, t, q, v)
    return modes


def stop_element(problem, stop) -> int:
    """The index of `stop`'s element in the problem's `FrictionModel`."""
    return next(k for k, e in enumerate(problem.friction.elements) if e.friction is stop)


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
        force, limit = state.forces[k], state.static_limit(problem.friction, k)
        if abs(force) <= limit:
            return STUCK, (force, limit)
        return (BACKWARD if force > 0.0 else FORWARD), (force, limit)
    trial[k] = FORWARD if modes[k] != FORWARD else BACKWARD
    state = problem.friction_state(t, q, v, trial)
    J, gamma = problem.dynamics_terms(q, v, t)
    Q = problem.load_model.forces(t, q, v) + state.generalized()
    qdd = problem.accelerations(J, Q, gamma, q)[0]
    g, path = state.gradients[k], joint_path_rates(element.geometry, q, v)[2][0]
    sdd = g @ qdd + path
    # At rest and not accelerated but for round-off (against what the loads would give
    # the joint alone), it turns: the other way than before.
    scale = np.abs(g) @ np.abs(qdd) + abs(path) + \
        float(np.abs(g) @ (problem.inverse_mass_diagonal * np.abs(Q)))
    still = abs(sdd) <= 1e-10 * scale
    mode = trial[k] if still else FORWARD if sdd > 0.0 else BACKWARD
    return mode, (state.forces[k], state.static_limit(problem.friction, k))


class FrictionEvents:
    """The events of a piece in which the joints keep `modes`, one per friction element: a
    sliding joint's σ ṡ (≥ 0 while it slides its way), a stuck joint's μ_s L − ‖f‖ (≥ 0
    while it holds); 1 for one whose stop holds it."""

    def __init__(self, problem, modes):
        self.problem, self.modes = problem, np.asarray(modes, int)
        self.indices = problem.friction.frictions

    @property
    def size(self) -> int:
        return len(self.indices)

    def values(self, t, q, v):
        model, modes = self.problem.friction, self.modes
        if np.any(modes[self.indices] == STUCK):
            state = self.problem.friction_state(t, q, v)
            rates = state.rates
        else:
            state = None
            rates = {k: joint_gradient(model.elements[k].geometry, q) @ v
                     for k in self.indices if modes[k] != FREE}
        out = []
        for k in self.indices:
            if modes[k] == FREE:
                out.append(1.0)
            elif modes[k] == STUCK:
                out.append(state.static_limit(model, k) - abs(state.forces[k]))
            else:
                out.append(modes[k] * rates[k])
        return np.array(out)

    def describe(self, i) -> str:
        k = self.indices[i]
        name = self.problem.friction.elements[k].name
        if self.modes[k] == STUCK:
            return f"friction '{name}' let its joint slip"
        return f"the joint of friction '{name}' came to rest"


def stop_moving(problem, k, t, q, v):
    """v with joint k's rate exactly zero (the nearest such velocity in the mass metric)."""
    g = joint_gradient(problem.friction.elements[k].geometry, q)
    return problem.project_velocities(q, v, t, extra=(g[None], np.zeros(1)))
