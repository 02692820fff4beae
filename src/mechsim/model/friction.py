"""Coulomb–Stribeck friction in a joint, loaded by the joint's own reaction
(`mechsim.problem.friction` solves it; `mechsim.engineering.contacts` runs its stick–slip)."""

from __future__ import annotations

import math

import numpy as np

from . import parameters as dual
from .checks import ModelError, name_or_default, scalar_exact
from .joints import Joint, coordinate_joint


class Friction:
    """Dry friction in a revolute or prismatic `joint`, opposing the joint's relative motion
    with a magnitude proportional to the load the joint carries:

    - revolute: a torque μ r (‖F‖ + preload), F the pin's reaction force and r = `radius`
      (the pin's radius, m);
    - prismatic: a force μ (N + preload), N the guide's normal load: ‖F‖ where `length` is
      None, else max(‖F‖, 2‖M‖/length), the sum of the contact forces at the two ends of a
      block of that length carrying the normal force F and the couple M (contact on
      opposite faces where the couple wins).

    Each number may be a Parameter (`set_parameters` gives it a new value, no new build;
    a simulation's sensitivities carry their derivatives,
    `mechsim.problem.friction_sensitivity`). `preload` [N] presses the surfaces
    besides the reaction (a press fit, a seal). The
    coefficient in slip is `mu`, or with `transition_velocity` v_t (rad/s or m/s) the
    Stribeck curve μ + (μ_s − μ) exp(−(ṡ/v_t)²); at rest it is `mu_static` μ_s (default
    `mu`). The reaction depends on the friction force and the friction force on the
    reaction: each evaluation solves the two together (Newton on the friction forces).

    A joint whose rate reaches zero sticks while the force needed to hold it stays within
    μ_s times its load, held exactly (its rate stays zero); it slips again, in the
    direction the holding force was resisting, when that force exceeds the limit. Both
    instants are located as events of the run (`SimulationResult.friction_switches`), and
    the work the friction takes is a channel of the energy balance."""

    kind = "friction"
    # What each number must be; those that may be left out (None).
    _OPTIONAL = frozenset({"mu_static", "transition_velocity", "radius", "length"})
    _CHECKS = dict(mu={"nonnegative": True}, mu_static={"nonnegative": True},
                   preload={"nonnegative": True}, transition_velocity={"positive": True},
                   radius={"positive": True}, length={"positive": True})

    def __init__(self, joint: Joint, mu: float, mu_static: float | None = None,
                 radius: float | None = None, transition_velocity: float | None = None,
                 preload: float = 0.0, length: float | None = None, name: str | None = None):
        self.joint = coordinate_joint(joint, "friction", "rub along")
        self.name = name_or_default(name, f"friction({joint.name})", "friction")
        owner = f"friction '{self.name}'"
        # The numbers as given (Parameters kept: `exact_numbers`); `_floats` checks them.
        self._exact = dict(mu=mu, mu_static=mu_static, preload=preload,
                           transition_velocity=transition_velocity, radius=radius,
                           length=length)
        self._floats()
        if self.joint.kind == "revolute":
            if radius is None:
                raise ModelError(f"{owner}: revolute joint '{joint.name}' needs the pin's "
                                 "`radius` [m]: the friction torque is μ r ‖F‖")
            if length is not None:
                raise ModelError(f"{owner}: `length` is a prismatic guide's; revolute joint "
                                 f"'{joint.name}' takes `radius`")
        elif radius is not None:
            raise ModelError(f"{owner}: `radius` is a pin's; prismatic joint "
                             f"'{joint.name}' takes `length` (its block's contact length)")

    def _floats(self) -> None:
        """The floats of the numbers as given, checked (a ModelError naming the friction)."""
        owner = f"friction '{self.name}'"
        for key, exact in self._exact.items():
            setattr(self, key, None if exact is None and key in self._OPTIONAL else
                    scalar_exact(exact, key, owner, **self._CHECKS[key])[0])
        if self.mu_static is None:
            self.mu_static = self.mu
        if self.mu_static < self.mu:
            raise ModelError(f"{owner}: `mu_static` ({self.mu_static:g}) must not be below "
                             f"`mu` ({self.mu:g}): a joint at rest holds at least what it "
                             "takes to keep it sliding")

    def exact_numbers(self) -> list:
        """The numbers as given that are Parameters or computed from them."""
        return [x for x in self._exact.values() if isinstance(x, dual.Dual)]

    def refresh_numbers(self) -> None:
        """Their floats again, after the Parameters took new values."""
        self._floats()

    def partials(self, key: str, names) -> np.ndarray:
        """∂(number `key`)/∂k for the Parameters `names`, (K,) (zeros for a plain number)."""
        return dual.gradient([self._exact[key]], names)[0]

    def static_partials(self, names) -> np.ndarray:
        """∂μ_s/∂k (K,) (μ's where μ_s was left out)."""
        return self.partials("mu" if self._exact["mu_static"] is None else "mu_static", names)

    def coefficient_partials(self, speed: float, names):
        """(μ, ∂μ/∂ṡ, ∂μ/∂k (K,)) of `coefficient` at the speed ṡ ≥ 0, for the Parameters
        `names` (through μ, μ_s and the transition velocity)."""
        dmu = self.partials("mu", names)
        if self.transition_velocity is None:
            return self.mu, 0.0, dmu
        vt, gap = self.transition_velocity, self.mu_static - self.mu
        weight = math.exp(-(speed / vt) ** 2)
        static = self.static_partials(names)
        return (self.mu + gap * weight, -2.0 * gap * weight * speed / vt ** 2,
                dmu + (static - dmu) * weight
                + gap * weight * 2.0 * speed ** 2 / vt ** 3 * self.partials(
                    "transition_velocity", names))

    def coefficient(self, speed: float) -> float:
        """μ while sliding at the speed the speed ṡ (`speed`): the Stribeck curve with a transition
        velocity (μ_s at zero speed), else μ (μ_s only holds a joint at rest)."""
        if self.transition_velocity is None:
            return self.mu
        return self.mu + (self.mu_static - self.mu) * math.exp(
            -(speed / self.transition_velocity) ** 2)

    def __repr__(self):
        return f"Friction({self.joint.name!r}, mu={self.mu:g}, mu_static={self.mu_static:g})"
