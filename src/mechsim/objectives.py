"""The ready objectives and constraints of `mechsim.design.optimize`, each with its exact
gradient from the analysis's sensitivities: path, function and motion generation
(`PathPoints`, `FunctionPoints`), a driver's effort and a joint's load (`EffortNorm`,
`JointForceNorm`), a four-bar's transmission angle and a crank that turns fully
(`TransmissionAngle`, `GrashofCrank`). `mechsim.design` says what an objective and a
constraint are; these are found there too.
"""

from __future__ import annotations

import numpy as np


class DesignError(ValueError):
    """An objective could not be evaluated at a design."""


class PathPoints:
    """Path generation: the point `local` of `body` (a body of the mechanism, or its name)
    should pass through `targets[i]` when `driver` (a driver, or its name) has moved its
    joint by `values[i]` from where it starts. Its value is the mean squared distance to
    the targets [m²]; its gradient is exact (the point's kinematic sensitivities).

    Motion generation: with `angles` (one per target [rad]) the body's angle should take
    them too, each radian weighing as `length` metres (the value adds the mean squared
    angle error times length²).

    With `free_timing`, the timing is not prescribed: the driver's advances between
    successive points, values[i] − values[i − 1] (the first value stays), are the
    objective's own variables ("advance 1", …), each of the sign the given values advance
    by and of size between `min_advance` and 2π, with exact derivatives too (the point's
    velocity over the driver's rate)."""

    def __init__(self, body, local, targets, driver, values, free_timing=False,
                 min_advance=1e-3, angles=None, length=1.0):
        self.body, self.driver = body, driver
        self.angles = None if angles is None else np.asarray(angles, float).ravel()
        self.length = float(length)
        if self.angles is not None and self.angles.shape != np.shape(values):
            raise ValueError(f"PathPoints: `angles` must be one per value "
                             f"({np.size(values)}), got {self.angles.size}")
        self.local = tuple(float(x) for x in np.asarray(local, float).ravel())
        self.targets = np.asarray(targets, float)
        self.values = np.asarray(values, float).ravel()
        self.free_timing = bool(free_timing)
        self.min_advance = float(min_advance)
        steps = np.diff(self.values)
        self.sign = 1.0 if steps.size and steps[0] > 0 else -1.0
        if self.free_timing and not (steps.size and
                                     np.all(self.sign * steps >= self.min_advance)):
            raise ValueError("PathPoints: free timing needs `values` increasing or "
                             "decreasing, each at least `min_advance` "
                             f"({self.min_advance:g}) past the one before")
        if len(self.local) != 2:
            raise ValueError(f"PathPoints: `local` must be a 2-vector, got {local!r:.60}")
        if self.targets.ndim != 2 or self.targets.shape[1] != 2 or \
                len(self.targets) != len(self.values):
            raise ValueError(f"PathPoints: `targets` must be {len(self.values)} points (one "
                             f"per value), shape ({len(self.values)}, 2); got "
                             f"{self.targets.shape}")

    @property
    def variables(self) -> list[str]:
        """The objective's own variables: the driver's advances with free timing."""
        return [f"advance {i}" for i in range(1, len(self.values))] if self.free_timing \
            else []

    def variable_values(self) -> np.ndarray:
        return np.diff(self.values) if self.free_timing else np.zeros(0)

    def variable_bounds(self) -> list:
        low, high = sorted((self.sign * self.min_advance, self.sign * 2.0 * np.pi))
        return [(low, high)] * len(self.variables)

    def set_variables(self, advances) -> None:
        """The driver's advances between successive points (free timing)."""
        advances = np.asarray(advances, float).ravel()
        if len(advances) != len(self.variables):
            raise ValueError(f"PathPoints: {len(self.variables)} advances expected, got "
                             f"{len(advances)}")
        if len(advances):
            self.values = self.values[0] + np.concatenate([[0.0], np.cumsum(advances)])

    def __call__(self, mech, names):
        return _squares(self.residuals(mech, names))

    def residuals(self, mech, names):
        """(r, J): the errors r scaled so that r·r is the value (each target's distance
        components over √N, then the angle errors times `length` over √N), and their
        exact Jacobian over `names` and the objective's own variables ((len(r), 0) when
        `names` is empty): for a least-squares search (`optimize(method=
        "least_squares")`)."""
        body = mech.body(self.body) if isinstance(self.body, str) else self.body
        kin = mech.kinematics(over=(self.driver, self.values),
                              sensitivities=list(names) or None)
        if not kin.success or len(kin.t) != len(self.values):
            raise DesignError(f"the path's points could not be reached: {kin.message}")
        root = np.sqrt(len(self.values))
        d = kin.point(body, self.local) - self.targets
        parts = [d.ravel() / root]
        columns = [[kin.sensitivity(k, of="point", body=body, local=self.local).ravel()
                    / root] for k in names]
        if self.angles is not None:
            column = kin.coordinate_names.index(f"{body.name}.angle")
            parts.append(self.length * (kin.q[:, column] - self.angles) / root)
            for entry, k in zip(columns, names):
                entry.append(self.length * kin.sensitivity(k)[:, column] / root)
        r = np.concatenate(parts)
        jac = np.array([np.concatenate(c) for c in columns]).T.reshape(len(r), len(names))
        if self.free_timing and names:
            jac = np.hstack([jac, self._timing_jacobian(mech, kin, body, root)])
        return r, jac

    def _timing_jacobian(self, mech, kin, body, root) -> np.ndarray:
        """∂r/∂(advance j) = Σ_{i ≥ j} ∂r/∂values[i], ∂r_i/∂values[i] being the point's
        velocity over the driver's rate at sample i (and the body's angular velocity over
        it for the angle errors)."""
        driver = mech.driver(self.driver)
        rates = np.array([driver.law.jet("t", float(t))[1] for t in kin.t])
        count = len(self.values)
        along = kin.point_velocity(body, self.local) / rates[:, None] / root
        per_value = np.zeros((2 * count, count))
        for i in range(count):
            per_value[2 * i:2 * i + 2, i] = along[i]
        if self.angles is not None:
            turning = self.length * kin.angular_velocity(body) / rates / root
            per_value = np.vstack([per_value, np.diag(turning)])
        return np.cumsum(per_value[:, ::-1], axis=1)[:, ::-1][:, 1:]


def _squares(residuals):
    """(r·r, 2 Jᵀ r) of an objective's (r, J)."""
    r, jac = residuals
    return float(r @ r), 2.0 * (jac.T @ r)


class FunctionPoints:
    """Function generation: the angle of `body_b` relative to `body_a` (bodies or names;
    the ground's angle is 0) should have turned by `targets[i]` [rad] from its value at the
    first point when `driver` has moved its joint by `values[i]` (targets[0] is 0). Its
    value is the mean squared error of those turns [rad²], its gradient exact (the
    angles' kinematic sensitivities)."""

    def __init__(self, body_a, body_b, targets, driver, values):
        self.body_a, self.body_b, self.driver = body_a, body_b, driver
        self.targets = np.asarray(targets, float).ravel()
        self.values = np.asarray(values, float).ravel()
        if self.targets.shape != self.values.shape or self.values.size < 2:
            raise ValueError(f"FunctionPoints: `targets` must be one turn per value (at "
                             f"least two), got {self.targets.size} for {self.values.size}")

    def _angle(self, kin, body, of):
        """Body's angle (or its sensitivity `of`) over the samples; 0 for the ground."""
        name = getattr(body, "name", body)
        key = f"{name}.angle"
        if key not in kin.coordinate_names:
            return np.zeros(len(kin.t))
        column = kin.coordinate_names.index(key)
        return (kin.q if of is None else kin.sensitivity(of))[:, column]

    def __call__(self, mech, names):
        return _squares(self.residuals(mech, names))

    def residuals(self, mech, names):
        """(r, J): the turns' errors over √N (r·r is the value) and their exact Jacobian
        over `names` (`PathPoints.residuals`)."""
        kin = mech.kinematics(over=(self.driver, self.values),
                              sensitivities=list(names) or None)
        if not kin.success or len(kin.t) != len(self.values):
            raise DesignError(f"the function's points could not be reached: {kin.message}")

        def turn(of=None):
            psi = self._angle(kin, self.body_b, of) - self._angle(kin, self.body_a, of)
            return psi - psi[0]
        root = np.sqrt(len(self.values))
        r = (turn() - self.targets) / root
        jac = np.array([turn(k) / root for k in names]).T.reshape(len(r), len(names))
        return r, jac


class _OnAnalysis:
    """An objective or constraint taken over a kinematic analysis: `over` (a driver's
    range), or `t_end` and `output_step`."""

    def _analysis(self, mech, names):
        """The analysis at the mechanism's present design, with the sensitivities to
        `names`; DesignError where it fails."""
        kin = mech.kinematics(self.t_end, self.output_step, over=self.over,
                              sensitivities=list(names) or None)
        if not kin.success:
            raise DesignError(f"the analysis failed: {kin.message}")
        return kin


class _PNorm(_OnAnalysis):
    """The p-norm mean (mean abs(x)^p)^(1/p) of a quantity x over a kinematic analysis
    (`over`, or `t_end` and `output_step`), p ≥ 1: the subclass's `samples(kin)` gives
    (x, what its slopes need), `slopes(kin, k, that)` x's sensitivity to the Parameter k
    (∂/∂k = mean(abs(x/value)^(p−1) sign(x) ∂x/∂k))."""

    def __init__(self, p, t_end, output_step, over):
        if not p >= 1.0:
            raise ValueError(f"{type(self).__name__}: `p` must be at least 1, got {p!r:.40}")
        self.p = float(p)
        self.t_end, self.output_step, self.over = t_end, output_step, over

    def __call__(self, mech, names):
        kin = self._analysis(mech, names)
        x, aux = self.samples(kin)
        value = float(np.mean(np.abs(x) ** self.p) ** (1.0 / self.p))
        if value == 0.0:
            return 0.0, np.zeros(len(names))
        weight = np.abs(x / value) ** (self.p - 1.0) * np.sign(x)
        return value, np.array([float(np.mean(weight * self.slopes(kin, k, aux)))
                                for k in names])


class EffortNorm(_PNorm):
    """The p-norm mean of a driver's effort τ over a kinematic analysis,
    (mean abs(τ)^p)^(1/p) [N·m or N]: p = 2 its RMS; a large p (16) a smooth stand-in for
    its peak, below it by at most the factor N^(−1/p) over N samples. The analysis is
    `kinematics(t_end, output_step)` or over a driver's range (`over`). The gradient is
    exact (the effort's sensitivities): ∂/∂k = mean(abs(τ/value)^(p−1) sign(τ) ∂τ/∂k)."""

    def __init__(self, driver, p: float = 2.0, t_end=None, output_step=None, over=None):
        super().__init__(p, t_end, output_step, over)
        self.driver = driver

    def samples(self, kin):
        return kin.driver_effort(self.driver), None

    def slopes(self, kin, name, _):
        return kin.sensitivity(name, of="driver_effort", driver=self.driver)


class JointForceNorm(_PNorm):
    """The p-norm mean of the magnitude of the force a joint transmits, ‖F‖ [N] of
    `joint_force(joint)`, over a kinematic analysis: (mean ‖F‖^p)^(1/p); p = 2 its RMS, a
    large p (16) a smooth stand-in for the peak pin load (below it by at most N^(−1/p)
    over N samples). The analysis as for `EffortNorm`. The gradient is exact (the joint
    force's sensitivities): ∂‖F‖/∂k = F·∂F/∂k / ‖F‖."""

    def __init__(self, joint, p: float = 2.0, t_end=None, output_step=None, over=None):
        super().__init__(p, t_end, output_step, over)
        self.joint = joint

    def samples(self, kin):
        """(‖F‖, F/‖F‖: the unit vector along which ‖F‖ changes, 0 where F is)."""
        force = kin.joint_force(self.joint)
        size = np.hypot(force[:, 0], force[:, 1])
        return size, np.divide(force, size[:, None], out=np.zeros_like(force),
                               where=size[:, None] > 0.0)

    def slopes(self, kin, name, along):
        return np.sum(along * kin.sensitivity(name, of="joint_force", joint=self.joint),
                      axis=1)


class GrashofCrank:
    """A four-bar's crank kept turning fully: with crank a, coupler b, rocker c and ground
    d, the crank the shortest link and s + l ≤ p + q (Grashof), i.e. the three linear
    conditions b + c − a − d, b + d − a − c, c + d − a − b ≥ `margin` (each link's length
    either the name of a Parameter or a number [m]; `margin` > 0 keeps the design away
    from the change point, where the linkage can fold). Values ≥ 0 where feasible, with
    their exact jacobian (±1 on the links' Parameters)."""

    def __init__(self, crank, coupler, rocker, ground, margin: float = 0.0):
        self.links = (crank, coupler, rocker, ground)
        for role, link in zip(("crank", "coupler", "rocker", "ground"), self.links):
            if isinstance(link, bool) or not isinstance(link, (str, int, float)):
                raise ValueError(f"GrashofCrank: the {role} must be a Parameter's name or a "
                                 f"length, got {link!r:.60}")
        if isinstance(margin, bool) or not isinstance(margin, (int, float)) or margin < 0:
            raise ValueError(f"GrashofCrank: `margin` must be a length ≥ 0, got {margin!r:.40}")
        self.margin = float(margin)

    # Rows: b + c − a − d, b + d − a − c, c + d − a − b over (a, b, c, d).
    SIGNS = np.array([[-1.0, 1.0, 1.0, -1.0], [-1.0, 1.0, -1.0, 1.0],
                      [-1.0, -1.0, 1.0, 1.0]])

    def check(self, mech):
        """ValueError naming a link that names no Parameter of `mech`."""
        known = mech.parameters
        for link in self.links:
            if isinstance(link, str) and link not in known:
                raise ValueError(f"GrashofCrank: {link!r:.60} is no Parameter of mechanism "
                                 f"'{mech.name}'; its parameters: {', '.join(known) or '(none)'}")

    def __call__(self, mech, names):
        values = mech.parameter_values()
        try:
            lengths = np.array([values[x] if isinstance(x, str) else float(x)
                                for x in self.links])
        except KeyError:
            self.check(mech)                   # (says which link names no Parameter)
            raise

        jac = np.zeros((3, len(names)))
        for j, link in enumerate(self.links):
            if isinstance(link, str) and link in names:
                jac[:, names.index(link)] += self.SIGNS[:, j]
        return self.SIGNS @ lengths - self.margin, jac


class TransmissionAngle(_OnAnalysis):
    """The angle μ between the x axes of two bodies (a four-bar's coupler and rocker,
    their frames along the links as `RigidBody.rod` puts them) kept at least `minimum`
    degrees from alignment at every sample of a kinematic analysis (`over`, or `t_end` and
    `output_step`): one value per sample, abs(sin μ) − sin(minimum), feasible where ≥ 0,
    with their exact jacobian (the angles' sensitivities)."""

    def __init__(self, body_a, body_b, minimum: float, t_end=None, output_step=None,
                 over=None):
        if not 0.0 < minimum < 90.0:
            raise ValueError(f"TransmissionAngle: `minimum` must be between 0 and 90 degrees, "
                             f"got {minimum!r:.40}")
        self.body_a, self.body_b = body_a, body_b
        self.floor = float(np.sin(np.radians(minimum)))
        self.t_end, self.output_step, self.over = t_end, output_step, over

    def __call__(self, mech, names):
        kin = self._analysis(mech, names)
        a, b = (kin.coordinate_names.index(f"{getattr(x, 'name', x)}.angle")
                for x in (self.body_a, self.body_b))
        mu = kin.q[:, b] - kin.q[:, a]
        values = np.abs(np.sin(mu)) - self.floor
        slope = np.sign(np.sin(mu)) * np.cos(mu)
        jac = np.column_stack([slope * (kin.sensitivity(k)[:, b] - kin.sensitivity(k)[:, a])
                               for k in names]) if names else np.zeros((len(mu), 0))
        return values, jac
