"""Exact sensitivities of a free motion (`simulate(..., sensitivities=...)`): integrated with
the motion and carried over singular passages by the bridge. Checked against the exact
variational equation of the double four-bar's parallelogram branch (through its passages),
against central finite differences of rebuilt mechanisms, and for what cannot be
differentiated yet being refused before any work."""

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

import mechsim as ms

G = 9.81


def chain(length=1.0, crank_mass=1.0, mass=1.0, speed=-1.0):
    """The double four-bar (IFToMM A02): three vertical cranks of `length`, the first of
    `crank_mass`, two couplers, all uniform rods (the others of `mass`); cranks turning
    at `speed`. Numbers or Parameters."""
    mech = ms.Mechanism("double four-bar", gravity=(0.0, -G))
    cranks = []
    for i in range(3):
        x = i * length
        m = crank_mass if i == 0 else mass
        crank = mech.add(ms.RigidBody.rod(f"crank{i + 1}", (x, 0.0), (x, length), m,
                                          velocity=(-speed * length / 2, 0.0),
                                          angular_velocity=speed))
        mech.add(ms.Revolute(mech.ground, crank, at=(x, 0.0), name=f"A{i + 1}"))
        cranks.append(crank)
    for i in range(2):
        x = i * length
        coupler = mech.add(ms.RigidBody.rod(f"coupler{i + 1}", (x, length),
                                            (x + length, length), mass,
                                            velocity=(-speed * length, 0.0)))
        mech.add(ms.Revolute(cranks[i], coupler, at=(x, length), name=f"B{i + 1}"))
        mech.add(ms.Revolute(coupler, cranks[i + 1], at=(x + length, length),
                             name=f"C{i + 1}"))
    return mech


def branch_rate(length, crank_mass, mass=1.0):
    """K/M_eff of the parallelogram branch M_eff θ̈ = −K cos θ (every crank at θ)."""
    m_eff = (crank_mass + 2 * mass) * length**2 / 3 + 2 * mass * length**2
    k = G * ((crank_mass + 2 * mass) * length / 2 + 2 * mass * length)
    return k / m_eff


def exact_sensitivity(t, dc, c):
    """θ(t) and ∂θ/∂k on the branch θ̈ = −c cos θ from θ = π/2, θ̇ = −1, where c depends on
    k at the rate dc: the variational equation integrated by scipy at 1e-13."""
    def f(_, y):
        th, w, s, sw = y
        return [w, -c * math.cos(th), sw, c * math.sin(th) * s - dc * math.cos(th)]
    sol = solve_ivp(f, (0.0, t[-1]), [math.pi / 2, -1.0, 0.0, 0.0], method="DOP853",
                    rtol=1e-13, atol=1e-14, t_eval=t)
    return sol.y[0], sol.y[2]


def exact_passages(t_end, dc, c):
    """(t*, ∂t*/∂k) of the branch's singular instants (sin θ = 0: the cranks horizontal)
    up to t_end: ∂t*/∂k = −θ_k/θ̇ there, the variational equation integrated by scipy at
    1e-13 with its events."""
    def f(_, y):
        th, w, s, sw = y
        return [w, -c * math.cos(th), sw, c * math.sin(th) * s - dc * math.cos(th)]
    sol = solve_ivp(f, (0.0, t_end), [math.pi / 2, -1.0, 0.0, 0.0], method="DOP853",
                    rtol=1e-13, atol=1e-14, events=lambda _, y: math.sin(y[0]))
    at = sol.y_events[0]
    return sol.t_events[0], -at[:, 2] / at[:, 1]


@pytest.mark.parametrize("method", ["hybrid", "projection"])
@pytest.mark.parametrize("which", ["length", "crank_mass"])
def test_the_double_four_bar_through_its_passages_matches_the_exact_variational_solution(
        method, which):
    """Three singular passages in 3 s: the sensitivity of the crank angle to the links'
    length and to one crank's mass against the 1-DOF branch's own variational equation,
    at every sample (the length enters the positions, the velocities and the equations;
    the mass only the equations)."""
    values = {"length": 1.0, "crank_mass": 1.0}
    k = ms.Parameter(which, values[which])
    res = chain(**{**values, which: k}).simulate(3.0, method=method, output_step=0.01,
                                                 rtol=1e-10, sensitivities=[which])
    assert res.success, res.message
    assert len(res.singular_passages) == 3
    assert "sensitivities were carried through the singular passages" in res.message
    h = 1e-6
    plus, minus = ({**values, which: values[which] + d} for d in (h, -h))
    dc = (branch_rate(**plus) - branch_rate(**minus)) / (2 * h)
    theta, exact = exact_sensitivity(res.t, dc, branch_rate(**values))
    col = res.coordinate_names.index("crank1.angle")
    assert np.max(np.abs(res.q[:, col] - theta)) < 1e-7
    got = res.sensitivity(which)[:, col]
    assert np.max(np.abs(got - exact)) < 1e-6 * np.max(np.abs(exact))
    # Every crank turns with the first on the branch, and so do their sensitivities.
    for name in ("crank2.angle", "crank3.angle"):
        other = res.sensitivity(which)[:, res.coordinate_names.index(name)]
        assert np.max(np.abs(other - got)) < 1e-6 * np.max(np.abs(exact))
    # The passages' instants move with the parameter as the branch's do (each instant
    # refined from the bridge's prediction, which is off by up to 1e-5 s).
    instants, shifts = exact_passages(3.0, dc, branch_rate(**values))
    for passage, t_star, shift in zip(res.singular_passages, instants, shifts):
        assert passage.t_min == pytest.approx(t_star, abs=2e-5)
        assert passage.time_sensitivity[which] == pytest.approx(shift, rel=1e-6)


def offset_slider_crank(r=0.12, l=0.30, e=0.03, rod_mass=0.5, speed=20.0):
    """A free slider-crank (crank r from the origin, rod l, slider on y = e) started at
    θ = 0.4 rad turning at `speed`, its velocities given consistent (np functions carry
    the Parameters)."""
    th = 0.4
    mech = ms.Mechanism("offset slider-crank", gravity=(0.0, -G))
    b = np.array([r * np.cos(th), r * np.sin(th)])
    phi = np.arcsin((e - b[1]) / l)
    c = b + l * np.array([np.cos(phi), np.sin(phi)])
    phid = -r * np.cos(th) * speed / (l * np.cos(phi))
    vb = speed * r * np.array([-np.sin(th), np.cos(th)])
    e_rod = np.array([-np.sin(phi), np.cos(phi)])
    crank = mech.add(ms.RigidBody.rod("crank", (0.0, 0.0), b, 0.4, velocity=vb / 2,
                                      angular_velocity=speed))
    rod = mech.add(ms.RigidBody.rod("rod", b, c, rod_mass, velocity=vb + phid * l / 2 * e_rod,
                                    angular_velocity=phid))
    vc = vb + phid * l * e_rod
    slider = mech.add(ms.RigidBody("slider", mass=0.3, inertia=1e-4, position=c,
                                   velocity=(vc[0], 0.0)))
    mech.add(ms.Revolute(mech.ground, crank, at=(0.0, 0.0), name="O"))
    mech.add(ms.Revolute(crank, rod, at=b, name="A"))
    mech.add(ms.Revolute(rod, slider, at=c, name="B"))
    mech.add(ms.Prismatic(mech.ground, slider, axis=(1.0, 0.0), at=c, name="guide"))
    return mech


def central_difference(build, value, quantity, t_end, rtol=1e-12, output_step=0.01):
    """(quantity(+h) − quantity(−h)) / 2h of `build(value ± h)` simulated to t_end; h from
    the error balance of a central difference on runs accurate to ~rtol, relative to the
    parameter's own size (a length of 3 cm)."""
    h = (3 * rtol) ** (1 / 3) * abs(value)
    out = [quantity(build(value + s * h).simulate(t_end, output_step=output_step, rtol=rtol,
                                                  atol=1e-12))
           for s in (1.0, -1.0)]
    return (out[0] - out[1]) / (2 * h)


@pytest.mark.parametrize("method", ["hybrid", "lu", "projection"])
@pytest.mark.parametrize("which", ["r", "e", "rod_mass"])
def test_a_free_slider_crank_agrees_with_finite_differences(method, which):
    """Through two dead centres in 0.4 s: ∂q/∂k and ∂v/∂k of every coordinate against
    central differences of rebuilt mechanisms, for the crank's length (positions and
    velocities as given move with it), the guide's offset and the rod's mass."""
    values = {"r": 0.12, "e": 0.03, "rod_mass": 0.5}

    def build(x):
        return offset_slider_crank(**{**values, which: x})
    res = offset_slider_crank(**{**values, which: ms.Parameter(which, values[which])}) \
        .simulate(0.4, method=method, output_step=0.01, rtol=1e-10, atol=1e-12,
                  sensitivities=[which])
    assert res.success, res.message
    for of, quantity in (("q", lambda r: r.q), ("v", lambda r: r.v)):
        reference = central_difference(build, values[which], quantity, 0.4)
        got = res.sensitivity(which, of=of)
        assert np.max(np.abs(got - reference)) < 1e-5 * np.max(np.abs(reference)), of


@pytest.mark.parametrize("which", ["r", "e"])
def test_joint_coordinates_sensitivities_include_the_joints_own_geometry(which):
    """The guide's slide is measured from its point on the ground, which moves with the
    crank's length and the offset (the guide's `at` is computed from them): ∂s/∂k is
    ∂s/∂q q_k plus that; the rod's pin angle through the states alone."""
    values = {"r": 0.12, "e": 0.03}

    def build(x):
        return offset_slider_crank(**{**values, which: x})
    res = build(ms.Parameter(which, values[which])).simulate(
        0.2, output_step=0.01, rtol=1e-10, atol=1e-12, sensitivities=[which])
    for joint in ("guide", "A"):
        reference = central_difference(build, values[which],
                                       lambda r: r.joint_coordinate(joint), 0.2)
        got = res.sensitivity(which, of="joint_coordinate", joint=joint)
        assert np.max(np.abs(got - reference)) < 1e-6 * np.max(np.abs(reference)), joint
    through_states = res.sensitivity(which)[:, 6] if which == "r" else None
    if through_states is not None:       # the slide's own geometry moves: not x_k alone
        assert np.max(np.abs(res.sensitivity(which, of="joint_coordinate", joint="guide")
                             - through_states)) > 1e-3


def test_accelerations_and_multipliers_of_a_free_motion_agree_with_finite_differences():
    """∂q̈/∂k and ∂λ/∂k at the samples (computed when asked, from the carried q_k and v_k)
    against central differences of the rebuilt runs' accelerations and multipliers."""
    value = 0.12

    def build(x):
        return offset_slider_crank(r=x)
    res = build(ms.Parameter("r", value)).simulate(0.3, output_step=0.01, rtol=1e-10,
                                                   atol=1e-12, sensitivities=["r"])
    assert res.success
    for of, quantity in (("a", lambda r: r.accelerations()),
                         ("lambda", lambda r: r.reactions.multipliers.lam)):
        reference = central_difference(build, value, quantity, 0.3)
        got = res.sensitivity("r", of=of)
        assert np.max(np.abs(got - reference)) < 1e-5 * np.max(np.abs(reference)), of


def test_a_coupler_point_sensitivity_follows_from_the_coordinates():
    """of="point" of a free motion: r's Jacobian applied to ∂q/∂k, against differences."""
    value = 0.03

    def build(x):
        return offset_slider_crank(e=x)
    res = build(ms.Parameter("e", value)).simulate(0.3, output_step=0.01, rtol=1e-10,
                                                   atol=1e-12, sensitivities=["e"])
    middle = (0.0, 0.0)
    reference = central_difference(build, value, lambda r: r.point("rod", middle),
                                   0.3)
    got = res.sensitivity("e", of="point", body="rod", local=middle)
    assert np.max(np.abs(got - reference)) < 1e-5 * np.max(np.abs(reference))


def test_a_state_the_user_set_is_held_and_its_sensitivity_starts_on_the_tangent():
    """After `set_state` the start does not move with the parameter: ∂q0/∂k is the
    smallest change that keeps the joints closed, zero where the geometry holds."""
    mech = offset_slider_crank(rod_mass=ms.Parameter("m", 0.5))
    report = mech.assemble()
    mech.set_state(report.q, report.v)
    res = mech.simulate(0.05, output_step=0.01, sensitivities=["m"])
    assert res.success
    assert np.max(np.abs(res.sensitivity("m")[0])) == 0.0
    assert np.max(np.abs(res.sensitivity("m")[-1])) > 1e-6


def test_what_cannot_be_differentiated_is_refused_before_any_work():
    mech = offset_slider_crank(r=ms.Parameter("r", 0.12))
    with pytest.raises(ValueError, match="simulate: `sensitivities` names 'R'.*parameters: r"):
        mech.simulate(0.1, sensitivities=["R"])
    with pytest.raises(ValueError, match="list of Parameter names"):
        mech.simulate(0.1, sensitivities=3)
    flexible = ms.examples.slider_crank(flexible=True, crank_mass=ms.Parameter("m", 0.36))
    flexible.add(ms.Spring(flexible.ground, flexible.body("rod"), at_a=(0.2, 0.1),
                           at_b=(0.15, 0.0), stiffness=10.0, name="tie"))
    with pytest.raises(ValueError, match="the spring 'tie' on a flexible body"):
        flexible.simulate(0.1, sensitivities=["m"])


def loaded_slider_crank(rod_mass=0.5):
    """The free offset slider-crank with a spring–damper from the ground to the slider, a
    torsion spring–damper at the crank's pivot, a force of fixed direction on the rod and
    a torque on the crank that varies in time."""
    mech = offset_slider_crank(rod_mass=rod_mass)
    slider, crank, rod = (mech.body(x) for x in ("slider", "crank", "rod"))
    mech.add(ms.Spring(mech.ground, slider, at_a=(0.6, 0.03), at_b=slider.position,
                       stiffness=400.0, rest_length=0.3, damping=2.0, name="return"))
    mech.add(ms.RotationalSpring(mech.ground, crank, stiffness=3.0, damping=0.05,
                                 rest_angle=0.2, name="coil"))
    mech.add(ms.Force(rod, (5.0, -20.0), at=rod.position + np.array([0.05, 0.0]),
                      name="push"))
    mech.add(ms.Torque(crank, lambda t: 2.0 * np.sin(30.0 * t), name="drive"))
    return mech


def test_springs_dampers_forces_and_torques_are_differentiated_in_the_motion():
    """Q_q q_k + Q_v v_k of a spring–damper, a torsion spring–damper, a force whose arm
    turns with its body and a torque of time, exact: the states' sensitivities to the rod's
    mass against central differences, and the multipliers'."""
    value = 0.5
    res = loaded_slider_crank(ms.Parameter("m", value)).simulate(
        0.3, output_step=0.01, rtol=1e-10, atol=1e-12, sensitivities=["m"])
    assert res.success, res.message
    for of, quantity in (("q", lambda r: r.q), ("v", lambda r: r.v),
                         ("lambda", lambda r: r.reactions.multipliers.lam)):
        reference = central_difference(loaded_slider_crank, value, quantity, 0.3)
        got = res.sensitivity("m", of=of)
        assert np.max(np.abs(got - reference)) < 1e-5 * np.max(np.abs(reference)), of


def test_a_load_on_a_body_moved_by_a_parameter_is_refused_naming_it():
    """A spring's body-fixed point computed from a frame that moves with a Parameter (the
    slider's, with the offset) does not carry the derivatives: refused, not wrong."""
    mech = offset_slider_crank(e=ms.Parameter("e", 0.03))
    slider = mech.body("slider")
    mech.add(ms.Spring(mech.ground, slider, at_a=(0.6, 0.03), at_b=(0.35, 0.03),
                       stiffness=400.0, name="return"))
    with pytest.raises(ValueError, match="'return' depends on Parameters"):
        mech.simulate(0.1, sensitivities=["e"])
    with pytest.raises(ValueError, match="function reads the motion"):
        mech = offset_slider_crank(rod_mass=ms.Parameter("m", 0.5))
        mech.add(ms.Torque(mech.body("crank"), lambda t, q, v: -0.1 * v[2], state=True,
                           name="brake"))
        mech.simulate(0.1, sensitivities=["m"])


def test_joint_force_sensitivity_of_a_free_motion():
    """of="joint_force" of a simulation: the crank pin's force to the rod's mass against
    central differences."""
    value = 0.5

    def build(x):
        return offset_slider_crank(rod_mass=x)
    res = build(ms.Parameter("m", value)).simulate(0.3, output_step=0.01, rtol=1e-10,
                                                   atol=1e-12, sensitivities=["m"])
    reference = central_difference(build, value, lambda r: r.joint_force("A"), 0.3)
    got = res.sensitivity("m", of="joint_force", joint="A")
    assert np.max(np.abs(got - reference)) < 1e-5 * np.max(np.abs(reference))


def sprung_slider_crank(k=400.0, c=2.0, rest=0.3, kt=3.0, rest_angle=0.2, rod_mass=0.5):
    """The free offset slider-crank with a spring–damper on the slider (stiffness k,
    damping c, rest length `rest`) and a torsion spring at the crank's pivot (kt,
    `rest_angle`): numbers or Parameters."""
    mech = offset_slider_crank(rod_mass=rod_mass)
    slider, crank = mech.body("slider"), mech.body("crank")
    mech.add(ms.Spring(mech.ground, slider, at_a=(0.6, 0.03), at_b=slider.position,
                       stiffness=k, rest_length=rest, damping=c, name="return"))
    mech.add(ms.RotationalSpring(mech.ground, crank, stiffness=kt, damping=0.05,
                                 rest_angle=rest_angle, name="coil"))
    return mech


@pytest.mark.parametrize("which", ["k", "c", "rest", "kt", "rest_angle"])
def test_spring_constants_as_parameters(which):
    """A spring's stiffness, damping and rest length and a torsion spring's stiffness and
    rest angle as Parameters: the motion's sensitivities against central differences, and
    a new value set without a new build runs as a mechanism built with it."""
    values = {"k": 400.0, "c": 2.0, "rest": 0.3, "kt": 3.0, "rest_angle": 0.2}
    check_parameter(sprung_slider_crank, which, values[which])


@pytest.mark.parametrize("which", ["k", "rest", "kt", "rest_angle", "m"])
def test_energies_sensitivities_agree_with_finite_differences(which):
    """of="kinetic_energy" and "potential_energy" (gravity, the spring and the torsion
    spring, their constants and the rod's mass moving them) against central differences
    of the energy log."""
    values = {"k": 400.0, "rest": 0.3, "kt": 3.0, "rest_angle": 0.2, "m": 0.5}

    def build(x):
        return sprung_slider_crank(**{"rod_mass" if which == "m" else which: x})
    res = build(ms.Parameter(which, values[which])).simulate(
        0.2, output_step=0.01, rtol=1e-10, atol=1e-12, sensitivities=[which])
    for of in ("kinetic_energy", "potential_energy"):
        field = of.split("_")[0]
        reference = central_difference(build, values[which],
                                       lambda r: getattr(r.energy, field), 0.2)
        got = res.sensitivity(which, of=of)
        assert np.max(np.abs(got - reference)) < 1e-6 * np.max(np.abs(reference)), of


def check_parameter(build, which, value):
    """`build(**{which: x})` with x a Parameter: its simulation's sensitivity against
    central differences of rebuilt mechanisms (< 1e-5), and a new value set without a new
    build running as a mechanism built with it (to 1e-12)."""
    mech = build(**{which: ms.Parameter(which, value)})
    assert mech.parameters == [which]
    res = mech.simulate(0.3, output_step=0.01, rtol=1e-10, atol=1e-12,
                        sensitivities=[which])
    assert res.success, res.message
    reference = central_difference(lambda x: build(**{which: x}), value, lambda r: r.q, 0.3)
    got = res.sensitivity(which)
    assert np.max(np.abs(got - reference)) < 1e-5 * np.max(np.abs(reference))
    mech.set_parameters(**{which: 1.2 * value})
    again = mech.simulate(0.3, output_step=0.01, rtol=1e-10, atol=1e-12)
    fresh = build(**{which: 1.2 * value}).simulate(0.3, output_step=0.01, rtol=1e-10,
                                                   atol=1e-12)
    assert np.max(np.abs(again.q - fresh.q)) < 1e-12


def test_a_driven_mechanism_s_simulated_sensitivities_are_its_kinematic_ones():
    """A fully driven offset slider-crank simulated with sensitivities (the projection
    method follows the drivers) against the implicit function theorem at every sample
    (`kinematics`): the positions' and the motor torque's, two independent paths."""
    e = ms.Parameter("e", 0.02)
    r, l = 0.15, 0.40
    mech = ms.Mechanism("offset slider-crank", gravity=(0.0, -G))
    b = np.array([r, 0.0])
    c = np.array([r + np.sqrt(l * l - e * e), e])
    crank = mech.add(ms.RigidBody.rod("crank", (0.0, 0.0), b, mass=0.4))
    rod = mech.add(ms.RigidBody.rod("rod", b, c, mass=0.8))
    slider = mech.add(ms.RigidBody("slider", mass=0.3, inertia=1e-4, position=c))
    pin = mech.add(ms.Revolute(mech.ground, crank, at=(0.0, 0.0)))
    mech.add(ms.Revolute(crank, rod, at=b))
    mech.add(ms.Revolute(rod, slider, at=c))
    mech.add(ms.Prismatic(mech.ground, slider, axis=(1.0, 0.0), at=c))
    motor = mech.add(ms.Driver(pin, "5*t"))
    res = mech.simulate(2.0, output_step=0.01, sensitivities=["e"])
    kin = mech.kinematics(2.0, 0.01, sensitivities=["e"])
    assert res.success
    scale = np.max(np.abs(kin.sensitivity("e")))
    assert np.max(np.abs(res.sensitivity("e") - kin.sensitivity("e"))) < 1e-9 * scale
    torque = kin.sensitivity("e", of="driver_effort", driver=motor)
    assert np.max(np.abs(res.sensitivity("e", of="driver_effort", driver=motor) - torque)) \
        < 1e-8 * np.max(np.abs(torque))


def sprung_flexible_four_bar(crank_mass=1.0, k=5.0):
    """The seed's flexible four-bar (copper coupler beam, two modes) with a torsion spring
    of stiffness `k` holding its crank at the release angle: numbers or Parameters."""
    mech = ms.examples.flexible_four_bar(crank_mass=crank_mass)
    mech.add(ms.RotationalSpring(mech.ground, mech.body("crank"), stiffness=k,
                                 rest_angle=math.radians(10.0), name="coil"))
    return mech


@pytest.mark.parametrize("which, method", [("crank_mass", "hybrid"), ("k", "projection")])
def test_the_flexible_four_bar_through_its_passage_agrees_with_finite_differences(
        method, which):
    """The elastic coupler's mass matrix M(q) and its quadratic-velocity and elastic forces
    differentiated through the beam kernel's Jacobians: ∂q/∂k of every coordinate (the
    modal amplitudes included) through the singular passage at 0.17 s, against central
    differences of rebuilt mechanisms, for the crank's mass and a spring's stiffness."""
    values = {"crank_mass": 1.0, "k": 5.0}
    res = sprung_flexible_four_bar(**{**values, which: ms.Parameter(which, values[which])}) \
        .simulate(0.3, method=method, output_step=0.01, rtol=1e-8, atol=1e-10,
                  sensitivities=[which])
    assert res.success, res.message
    assert len(res.singular_passages) == 1
    reference = central_difference(
        lambda x: sprung_flexible_four_bar(**{**values, which: x}), values[which],
        lambda r: r.q, 0.3, rtol=1e-10)
    got = res.sensitivity(which)
    assert np.max(np.abs(got - reference)) < 1e-5 * np.max(np.abs(reference))
    eta = res.coordinate_names.index("coupler.eta1")
    assert np.max(np.abs(got[:, eta] - reference[:, eta])) < \
        1e-4 * np.max(np.abs(reference[:, eta]))


def test_the_flexible_slider_crank_agrees_with_finite_differences():
    """The seed's free flexible slider-crank (steel rod as a beam of two modes, crank at
    150 rad/s) over most of a revolution: the rod turns, so its mass matrix M(q) moves with
    its angle and amplitudes, ∂(M q̈)/∂q enters the sensitivities (dropping it errs by
    ~14 %). ∂q/∂m and ∂v/∂m of the slider's mass against central differences."""
    mass = 0.075552

    def build(m):
        return ms.examples.slider_crank(flexible=True, slider_mass=m)
    res = build(ms.Parameter("m", mass)).simulate(0.03, output_step=0.001, rtol=1e-8,
                                                  atol=1e-10, sensitivities=["m"])
    assert res.success, res.message
    eta = res.coordinate_names.index("rod.eta1")
    both = central_difference(build, mass, lambda r: np.stack([r.q, r.v]), 0.03,
                              rtol=1e-10, output_step=0.001)
    for reference, of in zip(both, ("q", "v")):
        got = res.sensitivity("m", of=of)
        assert np.max(np.abs(got - reference)) < 1e-5 * np.max(np.abs(reference)), of
        assert np.max(np.abs(got[:, eta] - reference[:, eta])) < \
            1e-5 * np.max(np.abs(reference[:, eta])), of


def test_an_extended_run_carries_its_sensitivities_on():
    """`extend` goes on from the last sample's sensitivities: the double four-bar's
    ∂θ/∂L over 1.5 s and then to 3 s (three passages in all, one after the join) agrees
    with the branch's exact variational solution as an uninterrupted run does."""
    res = chain(length=ms.Parameter("length", 1.0)).simulate(
        1.5, output_step=0.01, rtol=1e-10, sensitivities=["length"])
    longer = res.extend(3.0)
    assert longer.success, longer.message
    assert len(longer.singular_passages) == 3 and longer.t[-1] == pytest.approx(3.0)
    assert longer.sensitivity("length").shape == longer.q.shape
    h = 1e-6
    dc = (branch_rate(1.0 + h, 1.0) - branch_rate(1.0 - h, 1.0)) / (2 * h)
    _, exact = exact_sensitivity(longer.t, dc, branch_rate(1.0, 1.0))
    got = longer.sensitivity("length")[:, longer.coordinate_names.index("crank1.angle")]
    assert np.max(np.abs(got - exact)) < 1e-6 * np.max(np.abs(exact))
    np.testing.assert_array_equal(longer.sensitivity("length")[:len(res.t)],
                                  res.sensitivity("length"))


def test_a_saved_result_keeps_its_sensitivities(tmp_path):
    """`save` keeps the states' sensitivities (a simulation's ∂q/∂k and ∂v/∂k, a kinematic
    analysis's also ∂q̈/∂k): the loaded result gives them bit for bit, and points' from
    them; what needs the model's Parameters (the multipliers') is refused, saying why."""
    res = chain(length=ms.Parameter("length", 1.0)).simulate(
        0.5, output_step=0.05, sensitivities=["length"])
    back = ms.load_result(res.save(tmp_path / "motion.npz"))
    for of in ("q", "v"):
        np.testing.assert_array_equal(back.sensitivity("length", of=of),
                                      res.sensitivity("length", of=of))
    np.testing.assert_array_equal(
        back.sensitivity("length", of="point", body="coupler1", local=(0.5, 0.0)),
        res.sensitivity("length", of="point", body="coupler1", local=(0.5, 0.0)))
    with pytest.raises(ValueError, match="not kept by a saved result"):
        back.sensitivity("length", of="lambda")
    with pytest.raises(ValueError, match="not saved with this result"):
        back.sensitivity("length", of="a")
    kin = offset_slider_crank(e=ms.Parameter("e", 0.03))
    kin.add(ms.Driver(kin.joint("O"), "20*t", name="motor"))
    analysis = kin.kinematics(0.2, 0.01, sensitivities=["e"])
    again = ms.load_result(analysis.save(tmp_path / "kinematics.npz"))
    np.testing.assert_array_equal(again.sensitivity("e", of="a"),
                                  analysis.sensitivity("e", of="a"))


def test_the_masses_sensitivities_sum_to_zero_as_scaling_all_masses_changes_nothing():
    """Under gravity alone, scaling every mass leaves the motion as it is: the
    sensitivities to the five link masses of the double four-bar (all carried at once,
    through three passages) sum to zero at every sample, each of them far from zero."""
    names = [f"m{i}" for i in range(5)]
    mech = ms.examples.double_four_bar(2, mass=[ms.Parameter(k, 1.0 + 0.1 * i)
                                                for i, k in enumerate(names)])
    res = mech.simulate(3.0, output_step=0.01, rtol=1e-10, sensitivities=names)
    assert res.success and len(res.singular_passages) == 3
    each = np.array([res.sensitivity(k) * (1.0 + 0.1 * i) for i, k in enumerate(names)])
    size = np.max(np.abs(each))
    assert min(np.max(np.abs(e)) for e in each) > 1e-3 * size
    assert np.max(np.abs(each.sum(axis=0))) < 1e-7 * size
    with pytest.raises(ValueError, match="2n \\+ 1 = 5 of them"):
        ms.examples.double_four_bar(2, mass=[1.0] * 4)


def pushed_slider_crank(push=40.0, drive=1.5):
    """The free offset slider-crank with a constant force pushing its slider back along
    the guide (`push` [N]) and a constant torque on its crank (`drive` [N·m]): numbers or
    Parameters."""
    mech = offset_slider_crank()
    slider, crank = mech.body("slider"), mech.body("crank")
    mech.add(ms.Force(slider, (-push, 0.0), name="load"))
    mech.add(ms.Torque(crank, drive, name="motor torque"))
    return mech


@pytest.mark.parametrize("which", ["push", "drive"])
def test_constant_forces_and_torques_as_parameters(which):
    """A constant force's component and a constant torque as Parameters: the motion's
    sensitivities against central differences of rebuilt mechanisms, a kinematic
    analysis's motor torque exactly linear in them, and a new value set without a new
    build running as a mechanism built with it."""
    values = {"push": 40.0, "drive": 1.5}
    check_parameter(pushed_slider_crank, which, values[which])

    def driven(x):
        m = pushed_slider_crank(**{which: x})
        m.add(ms.Driver(m.joint("O"), "20*t", name="motor"))
        return m
    kin = driven(ms.Parameter(which, values[which])).kinematics(0.2, 0.01,
                                                                 sensitivities=[which])
    effort = kin.sensitivity(which, of="driver_effort", driver="motor")
    h = 0.1 * values[which]
    exact = (driven(values[which] + h).kinematics(0.2, 0.01).driver_effort("motor") -
             driven(values[which] - h).kinematics(0.2, 0.01).driver_effort("motor")) / (2 * h)
    assert np.max(np.abs(effort - exact)) < 1e-8 * np.max(np.abs(exact))
    assert np.max(np.abs(exact)) > 1e-3


def tilted_parallelogram(tilt, length=1.0, mass=1.0):
    """A parallelogram four-bar whose ground line is tilted by `tilt` (a number or a
    Parameter): cranks of `length` upright from (0, 0) and from the other pivot, released
    turning at −1 rad/s. On its branch every crank turns by θ with M θ̈ = −K cos θ whatever
    the tilt; its links align (a singular passage) where θ = tilt (mod π)."""
    mech = ms.Mechanism("tilted parallelogram", gravity=(0.0, -G))
    pivot = np.array([length * np.cos(tilt), length * np.sin(tilt)])
    top = np.array([0.0, length])
    cranks = []
    for i, base in enumerate((np.zeros(2), pivot)):
        crank = mech.add(ms.RigidBody.rod(f"crank{i + 1}", base, base + top, mass,
                                          velocity=(length / 2, 0.0), angular_velocity=-1.0))
        mech.add(ms.Revolute(mech.ground, crank, at=base))
        cranks.append(crank)
    coupler = mech.add(ms.RigidBody.rod("coupler", top, pivot + top, mass,
                                        velocity=(length, 0.0)))
    mech.add(ms.Revolute(cranks[0], coupler, at=top))
    mech.add(ms.Revolute(coupler, cranks[1], at=pivot + top))
    return mech


@pytest.mark.parametrize("method", ["hybrid", "projection"])
def test_a_passage_whose_configuration_moves_with_the_parameter(method):
    """The tilt moves the singular configuration, not the motion: the branch's θ(t) is the
    same at every tilt, and the passages come where θ = tilt (mod π), so ∂t*/∂tilt =
    1/θ̇(t*) there (the constraints' own dependence on the parameter, alone)."""
    tilt = 0.3
    res = tilted_parallelogram(ms.Parameter("tilt", tilt)).simulate(
        2.0, method=method, output_step=0.01, rtol=1e-10, sensitivities=["tilt"])
    assert res.success, res.message
    c = G * 2.0 / (2.0 / 3.0 + 1.0)          # K / M: two 1 m, 1 kg rods and the coupler
    sol = solve_ivp(lambda _, y: [y[1], -c * math.cos(y[0])], (0.0, 2.0),
                    [math.pi / 2, -1.0], method="DOP853", rtol=1e-13, atol=1e-14,
                    events=lambda _, y: math.sin(y[0] - tilt))
    assert len(res.singular_passages) == len(sol.t_events[0]) >= 2
    for passage, t_star, (_, rate) in zip(res.singular_passages, sol.t_events[0],
                                          sol.y_events[0]):
        assert passage.t_min == pytest.approx(t_star, abs=2e-5)
        assert passage.time_sensitivity["tilt"] == pytest.approx(1.0 / rate, rel=1e-6)
