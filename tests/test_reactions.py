"""Joint reactions and driver efforts against Newton–Euler solutions written here.

Each body's acceleration comes from the motion itself (the sampled velocities differentiated
by an 8th-order central difference), and the joint forces and motor torques are solved from
m a = Σ F and I α = Σ M of every body with its weight and applied loads: an independent
computation that shares nothing with mechsim's multipliers but the simulated motion. Where
the equations have several solutions (redundant constraints) their least-squares solution of
least norm is compared with mechsim's minimum-norm reactions."""

import math

import numpy as np
import pytest

import mechsim as ms
from mechsim.examples import general_four_bar

G = 9.81
STENCIL = np.array([1 / 280, -4 / 105, 1 / 5, -4 / 5, 0.0, 4 / 5, -1 / 5, 4 / 105, -1 / 280])


def differentiate(t, x):
    """dx/dt at the samples 4 … n−5 of a uniform grid (8th-order central difference)."""
    h = t[1] - t[0]
    n = len(t)
    return sum(c * x[k:n - 8 + k] for k, c in enumerate(STENCIL)) / h


def rotate(angle, p):
    c, s = np.cos(angle), np.sin(angle)
    return np.stack([c * p[0] - s * p[1], s * p[0] + c * p[1]], axis=-1)


def cross(r, f):
    return r[..., 0] * f[..., 1] - r[..., 1] * f[..., 0]


class NewtonEuler:
    """m a = ΣF, I α = ΣM for every moving rigid body of `mech`, at the interior samples of
    `res`, solved for: each revolute's force on its body_b (2 unknowns), each prismatic's
    normal force on its body_b and its couple about the joint's point (2), each driver's
    torque on body_b (1). `applied(t, q, v)` -> {body name: (force (N, 2) at the centre of
    mass, torque (N,))} for loads besides gravity."""

    def __init__(self, mech, res, applied=None):
        self.mech, self.res = mech, res
        self.sl = slice(4, len(res.t) - 4)
        self.t = res.t[self.sl]
        self.q, self.v = res.q[self.sl], res.v[self.sl]
        self.a = differentiate(res.t, res.v)
        self.index = {b.name: 3 * k for k, b in enumerate(mech.bodies)}
        self.applied = applied(self.t, self.q, self.v) if applied else {}
        self.columns = []                    # (item, label) per unknown
        for j in mech.joints:
            self.columns += [(j, 0), (j, 1)]
        for d in mech.drivers:
            self.columns.append((d, 0))
        self.x, self.residual = self._solve()

    def frame(self, body):
        if body is self.mech.ground:
            return np.zeros((len(self.t), 2)), np.zeros(len(self.t))
        k = self.index[body.name]
        return self.q[:, k:k + 2], self.q[:, k + 2]

    def point(self, body, local):
        R, th = self.frame(body)
        return R + rotate(th, np.asarray(local))

    def _solve(self):
        N, nb = len(self.t), len(self.mech.bodies)
        A = np.zeros((N, 3 * nb, len(self.columns)))
        b = np.zeros((N, 3 * nb))
        for body in self.mech.bodies:
            k = self.index[body.name]
            b[:, k:k + 2] = body.mass * self.a[:, k:k + 2] - body.mass * np.array([0.0, -G])
            b[:, k + 2] = body.inertia * self.a[:, k + 2]
            if body.name in self.applied:
                force, torque = self.applied[body.name]
                b[:, k:k + 2] -= force
                b[:, k + 2] -= torque
        for c, (item, label) in enumerate(self.columns):
            for body, sign in self._sides(item):
                k = self.index[body.name]
                R = self.frame(body)[0]
                unit, moment = self._unit_wrench(item, label, body)
                A[:, k:k + 2, c] += sign * unit
                A[:, k + 2, c] += sign * (moment + cross(self._at(item, body) - R, unit))
        x = np.array([np.linalg.lstsq(Ai, bi, rcond=1e-10)[0] for Ai, bi in zip(A, b)])
        residual = np.max(np.abs(np.einsum("nij,nj->ni", A, x) - b))
        return x, residual

    def _sides(self, item):
        joint = item.joint if isinstance(item, ms.Driver) else item
        return [(body, sign) for body, sign in ((joint.body_b, 1.0), (joint.body_a, -1.0))
                if body is not self.mech.ground]

    def _at(self, item, body):
        """Where the unknown force acts on `body`: the joint's point on body_b (for both
        bodies: equal and opposite forces on one line)."""
        joint = item.joint if isinstance(item, ms.Driver) else item
        local_b = joint.body_b.local_point(joint.at) if joint.at is not None else joint.local_b
        return self.point(joint.body_b, local_b)

    def _unit_wrench(self, item, label, body):
        """(force (N, 2), moment about the point of application (N,)) per unit unknown."""
        N = len(self.t)
        zero, one = np.zeros(N), np.ones(N)
        if isinstance(item, ms.Driver):
            return np.zeros((N, 2)), one
        if isinstance(item, ms.Revolute):
            return np.column_stack([one if label == 0 else zero, zero if label == 0 else one]), zero
        # Prismatic: label 0 the normal force along the axis' normal (fixed in body_a),
        # label 1 the couple.
        return (self.normal(item), zero) if label == 0 else (np.zeros((N, 2)), one)

    def normal(self, joint):
        """A prismatic joint's normal in global axes (turning with its body_a)."""
        _, th_a = self.frame(joint.body_a)
        return rotate(th_a, joint.body_a.local_direction((-joint.axis[1], joint.axis[0])))

    def joint_force(self, joint):
        c = self.columns.index((joint, 0))
        if isinstance(joint, ms.Prismatic):
            return self.x[:, c, None] * self.normal(joint)
        return self.x[:, c:c + 2]

    def joint_moment(self, joint):
        if isinstance(joint, ms.Prismatic):
            return self.x[:, self.columns.index((joint, 1))]
        return np.zeros(len(self.t))

    def effort(self, driver):
        return self.x[:, self.columns.index((driver, 0))]


def relative(a, b):
    """max |a − b| over the peak of |b|."""
    return float(np.max(np.abs(a - b)) / max(np.max(np.abs(b)), 1e-300))


def check_against_newton_euler(mech, res, applied=None, tol=1e-6):
    ne = NewtonEuler(mech, res, applied)
    sl = ne.sl
    scale = max(np.max(np.abs(ne.x)), 1.0)
    assert ne.residual < 1e-6 * scale, ne.residual          # the motion obeys m a = ΣF
    for joint in mech.joints:
        assert relative(res.joint_force(joint)[sl], ne.joint_force(joint)) < tol, joint.name
        assert np.max(np.abs(res.joint_moment(joint)[sl] - ne.joint_moment(joint))) < \
            tol * scale, joint.name
    for driver in mech.drivers:
        assert relative(res.driver_effort(driver)[sl], ne.effort(driver)) < tol, driver.name
    return ne


def test_a_pendulum_pin_force_is_the_centripetal_and_tangential_closed_form():
    m, L = 1.3, 0.9
    mech = ms.examples.pendulum(length=L, mass=m, angle=0.4)
    res = mech.simulate(3.0, rtol=1e-10, atol=1e-12, output_step=0.01)
    assert res.success, res.message
    th = res.joint_coordinate("pivot")
    w = res.joint_rate("pivot")
    np.testing.assert_allclose(th, res.coordinate("rod.angle"), rtol=0, atol=1e-14)
    alpha = -1.5 * G / L * np.cos(th)                  # I_O α = −m g (L/2) cos θ
    e_r = np.column_stack([np.cos(th), np.sin(th)])
    e_t = np.column_stack([-np.sin(th), np.cos(th)])
    a = L / 2 * (alpha[:, None] * e_t - (w ** 2)[:, None] * e_r)
    force = m * a - m * np.array([0.0, -G])            # pin force = m a − m g
    assert relative(res.joint_force("pivot"), force) < 1e-8
    assert np.max(np.abs(res.joint_moment("pivot"))) == 0.0
    # In the rod's axes: along the rod the centripetal part with gravity's share.
    along = res.joint_force("pivot", frame="body")[:, 0]
    np.testing.assert_allclose(along, np.sum(force * e_r, axis=1), rtol=0,
                               atol=1e-8 * np.max(np.abs(force)))


def test_a_crank_rocker_under_gravity():
    mech = general_four_bar(0.2, 0.6, 0.5, 0.7, theta=0.3, speed=8.0, masses=(1.0, 2.0, 1.5))
    res = mech.simulate(1.5, rtol=1e-10, atol=1e-12, output_step=2e-3)
    assert res.success and not res.singular_passages, res.message
    check_against_newton_euler(mech, res)
    assert not res.reactions.flagged.any() and res.reactions.note() == ""


def offset_slider_crank(r=0.15, l=0.30, theta=0.4, speed=30.0, pin=(0.03, 0.02)):
    """A slider-crank whose rod is pinned to the slider `pin` off its centre of mass: the
    guide must hold a couple as well as a normal force."""
    mech = ms.Mechanism("offset slider-crank")
    b = np.array([r * math.cos(theta), r * math.sin(theta)])
    y = 0.0
    c = np.array([b[0] + math.sqrt(l * l - (b[1] - y - pin[1]) ** 2), y + pin[1]])
    crank = mech.add(ms.RigidBody.rod("crank", (0, 0), b, 0.4))
    rod = mech.add(ms.RigidBody.rod("rod", b, c, 0.6))
    slider = mech.add(ms.RigidBody("slider", mass=0.8, inertia=1e-3,
                                   position=(c[0] - pin[0], y)))
    pivot = mech.add(ms.Revolute(mech.ground, crank, at=(0, 0), name="O"))
    mech.add(ms.Revolute(crank, rod, at=b, name="A"))
    mech.add(ms.Revolute(rod, slider, at=c, name="B"))
    mech.add(ms.Prismatic(mech.ground, slider, axis=(1.0, 0.0), at=(c[0] - pin[0], y),
                          name="guide"))
    mech.set_speed(pivot, speed)
    return mech, crank, pivot


def test_a_slider_crank_with_a_crank_torque_normal_force_and_couple():
    mech, crank, _ = offset_slider_crank()
    mech.add(ms.Torque(crank, lambda t: 0.3 * math.sin(7.0 * t), name="motor"))
    res = mech.simulate(0.6, rtol=1e-10, atol=1e-12, output_step=2.5e-4)
    assert res.success, res.message

    def applied(t, q, v):
        return {"crank": (np.zeros((len(t), 2)), 0.3 * np.sin(7.0 * t))}
    ne = check_against_newton_euler(mech, res, applied)
    couple = res.joint_moment("guide")
    assert np.max(np.abs(couple)) > 0.1                    # the offset pin needs one
    # The guide's force is along its normal, the slider's slide along its axis.
    assert np.max(np.abs(res.joint_force("guide")[:, 0])) < 1e-9 * np.max(np.abs(ne.x))
    np.testing.assert_allclose(res.joint_coordinate("guide"),
                               res.coordinate("slider.x") - res.coordinate("slider.x")[0],
                               rtol=0, atol=1e-12)


def test_the_motor_torque_of_a_driven_crank_with_a_hanging_pendulum():
    mech = ms.Mechanism("crank and pendulum")
    crank = mech.add(ms.RigidBody.rod("crank", (0, 0), (0.3, 0), 2.0))
    bob = mech.add(ms.RigidBody.rod("bob", (0.3, 0), (0.3, -0.5), 1.0))
    pivot = mech.add(ms.Revolute(mech.ground, crank, at=(0, 0), name="pivot"))
    mech.add(ms.Revolute(crank, bob, at=(0.3, 0), name="hinge"))
    motor = mech.add(ms.Driver(pivot, "5*t + 0.5*sin(3*t)", name="motor"))
    res = mech.simulate(2.0, rtol=1e-10, atol=1e-12, output_step=2e-3)
    assert res.success, res.message
    check_against_newton_euler(mech, res)
    # The driver's rate is its law's derivative; its power is effort × rate.
    np.testing.assert_allclose(res.joint_rate(pivot), 5 + 1.5 * np.cos(3 * res.t), atol=1e-9)
    np.testing.assert_allclose(res.driver_power(motor),
                               res.driver_effort(motor) * res.joint_rate(pivot), rtol=1e-12)


def test_saved_results_answer_for_reactions():
    mech, crank, pivot = offset_slider_crank()
    res = mech.simulate(0.2, rtol=1e-9, atol=1e-11, output_step=0.01)
    path = res.save(__import__("tempfile").mkdtemp() + "/r.npz", reactions=True)
    back = ms.load_result(path)
    for j in mech.joints:
        np.testing.assert_array_equal(back.joint_force(j), res.joint_force(j))
        np.testing.assert_array_equal(back.joint_force(j, frame="body"),
                                      res.joint_force(j, frame="body"))
        np.testing.assert_array_equal(back.joint_moment(j), res.joint_moment(j))
        np.testing.assert_array_equal(back.joint_rate(j), res.joint_rate(j))
    res.mechanism = None            # a result without its model (as from solver.simulate)
    unsaved = ms.load_result(res.save(path.with_name("plain.npz"), reactions=False))
    with pytest.raises(RuntimeError, match="reactions=True"):
        unsaved.joint_force("A")
    with pytest.raises(KeyError, match="joints: O, A, B, guide"):
        res.joint_force("nowhere")


def fifth_bar_parallelogram(tilt=math.radians(30.0)):
    """The seed's falling parallelogram with a fifth bar parallel to its cranks: one of
    its 12 constraint equations is redundant."""
    mech = ms.examples.four_bar(tilt=tilt)
    c, s = math.cos(tilt), math.sin(tilt)
    fifth = mech.add(ms.RigidBody.rod("fifth", (0.5, 0.0), (0.5 + c, s), 1.0))
    mech.add(ms.Revolute(mech.ground, fifth, at=(0.5, 0.0), name="E"))
    mech.add(ms.Revolute(mech.body("coupler"), fifth, at=(0.5 + c, s), name="F"))
    return mech


@pytest.mark.parametrize("method", ["hybrid", "projection"])
def test_redundant_constraints_give_minimum_norm_reactions_and_say_so(method):
    mech = fifth_bar_parallelogram()
    assert mech.dof().redundant == 1
    res = mech.simulate(1.2, method=method, rtol=1e-9, atol=1e-11, output_step=2e-3)
    assert res.success, res.message
    # The motion: the parallelogram through its singular passages (crank horizontal,
    # 0.308 s and 0.924 s), stepped through (the bridge's one-step crossing is for
    # mechanisms without redundancy), energy kept to the tolerance.
    assert [round(p.t_min, 2) for p in res.singular_passages] == [0.31, 0.92]
    assert not any(p.bridged for p in res.singular_passages)
    assert np.max(np.abs(res.energy_drift)) < 10 * 1e-9
    assert res.reactions.flagged.all()
    note = res.reactions.note()
    assert "not unique" in note and all(f"'{j}'" in note for j in "ABCDEF")
    # Newton–Euler has a line of solutions here: its least-norm one is mechsim's. At the
    # samples closest to the singular configurations (cranks horizontal) a second direction
    # is left out, as the projection method left it out of the motion; within 5° of them
    # both solutions are ill-conditioned (by (σ_max/σ_min)²) and not compared.
    ne = NewtonEuler(mech, res)
    assert ne.residual < 1e-6 * np.max(np.abs(ne.x))
    dropped = res.reactions.multipliers.dropped[ne.sl]
    assert set(np.unique(dropped)) <= {1, 2} and np.sum(dropped == 1) > 0.9 * len(dropped)
    assert np.all(np.min(np.abs(ne.t[dropped == 2, None] - [0.308, 0.924]), axis=1) < 0.01)
    only = np.abs(np.sin(res.coordinate("crank.angle")[ne.sl])) > math.sin(math.radians(5))
    assert only.sum() > 0.5 * len(ne.t)
    for joint in mech.joints:
        ours, theirs = res.joint_force(joint)[ne.sl][only], ne.joint_force(joint)[only]
        assert relative(ours, theirs) < 1e-6, joint.name


def test_a_fully_driven_mechanism_with_a_redundant_bar_runs_and_balances_its_energy():
    """With its crank driven, the fifth-bar parallelogram has no instantaneous motion left
    (Φ_q of rank n with one redundant row): its driver moves it, it is not locked (it was
    refused as a chain held straight). The crank follows the law and the driver's work,
    from its least-norm λ (the energy balance), keeps the energy to the tolerance through
    the aligned position (the crank, from 30°, horizontal at 5π/12 s). A sample's
    velocities are checked against their constraints: one 1 ms after the start of a long
    step had been projected by a Cholesky factor of the singular complement and missed
    them by 0.4 (its energy by 2 %). Inside the passage the velocities the drivers give
    depend on the positions by 1/σ_min (a sample 3 µs from the aligned position errs 1e-5
    in energy); the run reports the passage."""
    mech = fifth_bar_parallelogram()
    mech.add(ms.Driver(mech.joint("A"), "2*t"))
    res = mech.simulate(2.0, rtol=1e-8, atol=1e-10, output_step=1e-3)
    assert res.success, res.message
    assert [round(p.t_min, 4) for p in res.singular_passages] == [round(5 * math.pi / 12, 4)]
    angle = res.coordinate("crank.angle")
    np.testing.assert_allclose(angle - angle[0], 2 * res.t, rtol=0, atol=1e-8)
    passage = res.singular_passages[0]
    outside = (res.t < passage.t_start) | (res.t > passage.t_end)
    assert np.max(np.abs(res.energy_drift[outside])) < 100 * 1e-8
    assert np.max(np.abs(res.energy.work)) > 0.1 * res.energy_scale


# A study: a stiff beam's convergence to the rigid limit.
@pytest.mark.slow
def test_a_flexible_coupler_approaches_the_rigid_limit():
    """The flexible four-bar with a coupler 1000 times stiffer than copper (lowest bending
    mode 3300 rad/s, 5 % modal damping) against the same four-bar with a rigid coupler of
    the same mass. Released at rest, the beam rings at first with forces of the order of
    the load it takes up; once that has died away (e^{-ζωt} < 1e-6 after 0.1 s) its pins
    carry the rigid forces up to its quasi-static deflection's share, (ω_rigid/ω_beam)²."""
    stiff = ms.examples.flexible_four_bar(youngs_modulus=117e9 * 1000, damping_ratio=0.05)
    rigid = ms.examples.flexible_four_bar(rigid=True)
    a = stiff.simulate(0.3, rtol=1e-9, atol=1e-12, output_step=5e-3)
    b = rigid.simulate(0.3, rtol=1e-9, atol=1e-12, output_step=5e-3)
    assert a.success and b.success, (a.message, b.message)
    late = a.t >= 0.1
    for joint in "ABCD":
        assert relative(a.joint_force(joint)[late], b.joint_force(joint)[late]) < 1e-4, joint
        np.testing.assert_allclose(a.joint_coordinate(joint), b.joint_coordinate(joint),
                                   atol=1e-5)
