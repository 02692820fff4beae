"""Exact design sensitivities (`ms.Parameter`, `kinematics(..., sensitivities=...)`):
against the offset slider-crank's closed form and against central finite differences of
rebuilt mechanisms, and the errors that keep a derivative from being dropped silently."""

import math
import pathlib

import numpy as np
import pytest

import mechsim as ms
from mechsim.engineering.driven import KinematicsError
from mechsim.model.parameters import Dual, atan2, hypot

THETA0, SPEED = 0.3, 5.0


def offset_slider_crank(r=0.15, l=0.40, e=0.05, tilt=0.0, theta0=THETA0, m_rod=0.8,
                        speed=SPEED, law="w*t"):
    """Crank r from the origin (driven by `law` in t and w = `speed` from theta0), rod l,
    slider on the line y = e (tilted by `tilt`: its axis (1, tilt)); numbers or
    Parameters."""
    mech = ms.Mechanism("offset slider-crank", gravity=(0.0, -9.81))
    b = np.array([r * np.cos(theta0), r * np.sin(theta0)])
    # The slider's point on its line y = e + tilt·x, found from the rod's length by one
    # quadratic in x (numpy functions carry the Parameters' derivatives).
    u = np.array([1.0, tilt]) / np.hypot(1.0, tilt)
    p0 = np.array([0.0, e])
    w = p0 - b
    half = w @ u
    s = -half + np.sqrt(half * half - (w @ w - l * l))
    c = p0 + s * u
    crank = mech.add(ms.RigidBody.rod("crank", (0.0, 0.0), b, mass=0.4))
    rod = mech.add(ms.RigidBody.rod("rod", b, c, mass=m_rod))
    slider = mech.add(ms.RigidBody("slider", mass=0.3, inertia=1e-4, position=c))
    pin = mech.add(ms.Revolute(mech.ground, crank, at=(0.0, 0.0), name="O"))
    mech.add(ms.Revolute(crank, rod, at=b, name="A"))
    mech.add(ms.Revolute(rod, slider, at=c, name="B"))
    mech.add(ms.Prismatic(mech.ground, slider, axis=(1.0, tilt), at=c, name="guide"))
    mech.add(ms.Driver(pin, law, values={"w": speed}))
    return mech


def four_bar(a=0.10, d=0.40, coupler_mass=2.0):
    """Crank a, ground pivots (0, 0) and (d, 0), coupler to (d, 0.3), driven crank."""
    mech = ms.Mechanism("four-bar", gravity=(0.0, -9.81))
    g = mech.ground
    crank = mech.add(ms.RigidBody.rod("crank", (0.0, 0.0), (a, 0.0), mass=1.0))
    coupler = mech.add(ms.RigidBody.rod("coupler", (a, 0.0), (d, 0.3), mass=coupler_mass))
    rocker = mech.add(ms.RigidBody.rod("rocker", (d, 0.3), (d, 0.0), mass=1.5))
    pin = mech.add(ms.Revolute(g, crank, at=(0.0, 0.0)))
    mech.add(ms.Revolute(crank, coupler, at=(a, 0.0)))
    mech.add(ms.Revolute(coupler, rocker, at=(d, 0.3)))
    mech.add(ms.Revolute(rocker, g, at=(d, 0.0)))
    mech.add(ms.Driver(pin, "6*t"))
    return mech


def central_difference(build, value, quantity, t_end=1.0, step=0.05):
    """(quantity(+h) − quantity(−h)) / 2h of the kinematics of `build(value ± h)`; h from
    the error balance of a central difference on states solved to ~1e-12: ∛(3e-12)·scale."""
    h = (3e-12) ** (1.0 / 3.0) * max(1.0, abs(value))
    plus = build(value + h).kinematics(t_end, step)
    minus = build(value - h).kinematics(t_end, step)
    return (quantity(plus) - quantity(minus)) / (2.0 * h)


def relative(a, b):
    return np.max(np.abs(a - b)) / np.max(np.abs(b))


def test_the_offset_slider_crank_matches_its_closed_form():
    """x = r cos θ + √(l² − (r sin θ − e)²): ∂x/∂e = (r sin θ − e)/√(…) and
    ∂x/∂r = cos θ − sin θ (r sin θ − e)/√(…), and their rates in time, at every sample."""
    r, l, e = ms.Parameter("r", 0.15), ms.Parameter("l", 0.40), ms.Parameter("e", 0.05)
    kin = offset_slider_crank(r, l, e).kinematics(1.2, 0.01, sensitivities=["e", "r", "l"])
    assert kin.success
    th = THETA0 + SPEED * kin.t
    r, l, e = 0.15, 0.40, 0.05
    root = np.sqrt(l**2 - (r * np.sin(th) - e) ** 2)
    k = kin.coordinate_names.index("slider.x")
    exact = {"e": (r * np.sin(th) - e) / root,
             "r": np.cos(th) - np.sin(th) * (r * np.sin(th) - e) / root,
             "l": l / root}
    for name, d in exact.items():
        assert relative(kin.sensitivity(name)[:, k], d) < 1e-10, name
    # d/dt (∂x/∂e) = ∂ẋ/∂e, by the closed form differentiated in θ
    s = r * np.sin(th) - e
    rate = SPEED * (r * np.cos(th) / root + s * s * r * np.cos(th) / root**3)
    assert relative(kin.sensitivity("e", of="v")[:, k], rate) < 1e-9


@pytest.mark.parametrize("which", ["r", "e", "tilt", "theta0"])
def test_slider_crank_sensitivities_agree_with_finite_differences(which):
    """Each geometric parameter, the crank's starting angle too (it enters the driver's
    offset: the drive holds the crank at theta0 + SPEED t)."""
    values = {"r": 0.15, "e": 0.05, "tilt": 0.1, "theta0": THETA0}
    p = ms.Parameter(which, values[which])
    kin = offset_slider_crank(**{**values, which: p}).kinematics(
        1.0, 0.05, sensitivities=[which])

    def build(x):
        return offset_slider_crank(**{**values, which: x})

    assert relative(kin.sensitivity(which), central_difference(build, values[which],
                                                               lambda res: res.q)) < 1e-6
    assert relative(kin.sensitivity(which, of="v"),
                    central_difference(build, values[which], lambda res: res.v)) < 1e-6
    assert relative(kin.sensitivity(which, of="a"),
                    central_difference(build, values[which],
                                       lambda res: res.accelerations())) < 1e-6


@pytest.mark.parametrize("which", ["e", "m_rod"])
def test_a_driven_analysis_s_energies_and_joint_coordinates_sensitivities(which):
    """of="kinetic_energy", "potential_energy" and "joint_coordinate" of a kinematic
    analysis (the guide's slide measured from its point, which the offset moves; the
    rod's mass moves the energies alone) against central differences."""
    values = {"e": 0.05, "m_rod": 0.8}

    def build(x):
        return offset_slider_crank(**{which: x})
    kin = build(ms.Parameter(which, values[which])).kinematics(1.0, 0.05,
                                                               sensitivities=[which])
    quantities = {"kinetic_energy": lambda r: r.energy.kinetic,
                  "potential_energy": lambda r: r.energy.potential}
    for of, quantity in quantities.items():
        reference = central_difference(build, values[which], quantity)
        assert relative(kin.sensitivity(which, of=of), reference) < 1e-6, of
    for joint in ("A", "guide"):
        reference = central_difference(build, values[which],
                                       lambda r: r.joint_coordinate(joint))
        got = kin.sensitivity(which, of="joint_coordinate", joint=joint)
        assert np.max(np.abs(got - reference)) <= 1e-6 * max(np.max(np.abs(reference)),
                                                             1e-6), joint


def test_four_bar_sensitivities_of_states_and_a_coupler_point():
    """Crank length and ground pivot of a driven four-bar: ∂q, ∂v, ∂q̈ and the coupler
    point's ∂r against central differences."""
    a, d = ms.Parameter("a", 0.10), ms.Parameter("d", 0.40)
    mech = four_bar(a, d)
    assert mech.parameters == ["a", "d"]
    kin = mech.kinematics(1.0, 0.05, sensitivities=["a", "d"])
    coupler = mech.bodies[1]
    point = (0.05, 0.02)
    for name, build, value in (("a", lambda x: four_bar(x, 0.40), 0.10),
                               ("d", lambda x: four_bar(0.10, x), 0.40)):
        for of, quantity in (("q", lambda r: r.q), ("v", lambda r: r.v),
                             ("a", lambda r: r.accelerations())):
            assert relative(kin.sensitivity(name, of=of),
                            central_difference(build, value, quantity)) < 1e-6, (name, of)
        fd = central_difference(build, value,
                                lambda r: r.point(r.mechanism.bodies[1], point))
        got = kin.sensitivity(name, of="point", body=coupler, local=point)
        assert got.shape == (len(kin.t), 2)
        assert relative(got, fd) < 1e-6


def test_a_mass_moves_no_driven_kinematics():
    """A Parameter in a mass: a driven mechanism's motion does not depend on it (exact
    zeros), and it is one of the mechanism's parameters."""
    m = ms.Parameter("m", 2.0)
    mech = four_bar(coupler_mass=m)
    assert mech.parameters == ["m"]
    kin = mech.kinematics(0.5, 0.05, sensitivities=["m"])
    assert np.all(kin.sensitivity("m") == 0.0) and np.all(kin.sensitivity("m", of="a") == 0.0)


def test_a_model_with_parameters_runs_as_one_with_their_values():
    e = ms.Parameter("e", 0.05)
    with_parameter = offset_slider_crank(e=e).kinematics(0.5, 0.05)
    plain = offset_slider_crank(e=0.05).kinematics(0.5, 0.05)
    np.testing.assert_allclose(with_parameter.q, plain.q, rtol=0, atol=1e-14)


def test_dual_arithmetic_carries_exact_derivatives():
    x, y = ms.Parameter("x", 0.7), ms.Parameter("y", -1.3)
    f = x * x * y - 3.0 / x + y ** 3 + np.sin(x * y) + np.sqrt(x) * np.exp(y)
    assert f.value == pytest.approx(0.7**2 * -1.3 - 3 / 0.7 + (-1.3) ** 3 + math.sin(-0.91)
                                    + math.sqrt(0.7) * math.exp(-1.3))
    dfx = 2 * 0.7 * -1.3 + 3 / 0.49 + math.cos(-0.91) * -1.3 + 0.5 / math.sqrt(0.7) * math.exp(-1.3)
    dfy = 0.49 + 3 * 1.69 + math.cos(-0.91) * 0.7 + math.sqrt(0.7) * math.exp(-1.3)
    assert f.partials["x"] == pytest.approx(dfx, rel=1e-14)
    assert f.partials["y"] == pytest.approx(dfy, rel=1e-14)
    g = atan2(y, x) + hypot(x, y)
    r2 = 0.49 + 1.69
    assert g.partials["x"] == pytest.approx(1.3 / r2 + 0.7 / math.sqrt(r2), rel=1e-14)
    v = np.array([1.0, 2.0]) * x                          # arrays carry them elementwise
    assert [e.partials["x"] for e in v] == [1.0, 2.0]
    w = 1.0 / (np.array([3.0, 4.0]) - x)                  # reflected operators as well
    assert [e.partials["x"] for e in w] == pytest.approx([1 / 2.3**2, 1 / 3.3**2], rel=1e-14)
    assert (2.0 ** x).partials["x"] == pytest.approx(2.0**0.7 * math.log(2.0), rel=1e-14)
    assert isinstance(np.cos(x), Dual)
    # A number computed again from a new value takes the branch that value asks for.
    from mechsim.model.parameters import refresh
    z = ms.Parameter("z", -2.0)
    w = abs(z) * 3.0
    z.set(1.5)
    refresh([w])
    assert (w.value, w.partials) == (4.5, {"z": 3.0})
    # A pickled Dual (the background build, process pools) is its value and partials.
    import pickle
    copy = pickle.loads(pickle.dumps(f))
    assert (copy.value, copy.partials) == (f.value, f.partials)
    assert repr(pickle.loads(pickle.dumps(x))) == "Parameter('x', 0.7)"


def test_what_would_drop_a_derivative_is_refused():
    k = ms.Parameter("k", 100.0)
    with pytest.raises(TypeError, match="numpy's functions"):
        math.cos(k)
    with pytest.raises(TypeError, match="numpy's functions"):
        float(k)
    mech = four_bar()
    with pytest.raises(ms.ModelError, match=r"spring .*`at_b` cannot depend on a Parameter"):
        ms.Spring(mech.bodies[0], mech.bodies[2], at_a=(0.0, 0.0), at_b=(k / 250.0, 0.0),
                  stiffness=100.0, rest_length=0.3)
    with pytest.raises(ms.ModelError, match="Parameter 'z': `value` must be a finite number"):
        ms.Parameter("z", float("nan"))


def test_sensitivities_to_an_unknown_name_are_refused_before_any_work():
    mech = four_bar(ms.Parameter("a", 0.1))
    with pytest.raises(KinematicsError, match=r"names 'b', which is no Parameter of "
                                              r"mechanism 'four-bar'; its parameters: a"):
        mech.kinematics(0.5, 0.05, sensitivities=["b"])
    res = mech.kinematics(0.5, 0.05)
    with pytest.raises(ValueError, match="no sensitivities to 'a'"):
        res.sensitivity("a")


def test_new_values_need_no_new_build_and_equal_a_fresh_model():
    """`set_parameters` computes the model's numbers again from the Parameters: the
    analysis and its sensitivities equal those of a model built with the new values, and
    values that make it invalid (an offset beyond the rod) are refused, the old ones
    kept."""
    e, r = ms.Parameter("e", 0.05), ms.Parameter("r", 0.15)
    mech = offset_slider_crank(r=r, e=e)
    mech.kinematics(0.5, 0.05, sensitivities=["e"])
    mech.set_parameters(e=0.07, r=0.12)
    again = mech.kinematics(0.5, 0.05, sensitivities=["e", "r"])
    fresh = offset_slider_crank(r=ms.Parameter("r", 0.12), e=ms.Parameter("e", 0.07))
    built = fresh.kinematics(0.5, 0.05, sensitivities=["e", "r"])
    np.testing.assert_array_equal(again.q, built.q)
    np.testing.assert_array_equal(again.sensitivity("r", of="a"), built.sensitivity("r", of="a"))
    plain = offset_slider_crank(r=0.12, e=0.07).kinematics(0.5, 0.05)
    np.testing.assert_allclose(again.q, plain.q, rtol=0, atol=1e-13)
    with pytest.raises(ms.ModelError, match=r"make it invalid .*old values are kept"):
        mech.set_parameters(e=0.6)                  # the slider's line beyond the rod
    assert (e.value, r.value) == (0.07, 0.12)
    np.testing.assert_array_equal(mech.kinematics(0.5, 0.05).q, again.q)
    with pytest.raises(ms.ModelError, match="names 'z', which is no Parameter"):
        mech.set_parameters(z=1.0)
    with pytest.raises(ms.ModelError, match="`value` must be a finite number"):
        mech.set_parameters(e=float("inf"))


def test_a_constraint_that_drops_derivatives_refuses_sensitivities():
    """A pin in a slot (`PointOnCurve`) whose bodies move with a Parameter does not carry
    its derivatives: sensitivities through it are refused, naming it (a plain run is
    not)."""
    r = ms.Parameter("r", 0.1)
    mech = ms.Mechanism("scotch yoke")
    crank = mech.add(ms.RigidBody.rod("crank", (0, 0), (r, 0.0), 0.5))
    yoke = mech.add(ms.RigidBody.point_mass("yoke", (r, 0.0), 2.0))
    pivot = mech.add(ms.Revolute(mech.ground, crank, at=(0, 0), name="O"))
    mech.add(ms.Prismatic(mech.ground, yoke, axis=(1, 0), at=(r, 0.0), name="guide"))
    mech.add(ms.PointOnCurve(yoke, crank, at=(0.1, 0.0), curve=("line", (0, 1)), name="slot"))
    mech.add(ms.Driver(pivot, "t"))
    assert mech.parameter_blind() == ["slot"]
    with pytest.raises(KinematicsError, match="'slot' depends on Parameters but does not carry"):
        mech.kinematics(0.5, 0.1, sensitivities=["r"])
    assert mech.kinematics(0.5, 0.1).success


def geared(ratio=-2.0, ra=0.05, rb=0.1, arm=0.1, rack=0.02, spur=True):
    """A driven crank (arm) geared to a second pin by a plain ratio, a spur pair from that
    pin's gear to a third (with `spur`; else a plain coupling of the same ratio), and a
    rack on a slide driven by the third's pinion against a spring (numbers or
    Parameters)."""
    mech = ms.Mechanism("gear train", gravity=(0.0, -9.81))
    g = mech.ground
    one = mech.add(ms.RigidBody.rod("one", (0.0, 0.0), (arm, 0.0), 0.5))
    two = mech.add(ms.RigidBody("two", mass=1.0, inertia=0.002, position=(0.3, 0.0)))
    three = mech.add(ms.RigidBody("three", mass=1.0, inertia=0.004, position=(0.45, 0.0)))
    bar = mech.add(ms.RigidBody("bar", mass=0.4, inertia=0.001, position=(0.45, -0.12)))
    p1 = mech.add(ms.Revolute(g, one, at=(0.0, 0.0), name="p1"))
    p2 = mech.add(ms.Revolute(g, two, at=(0.3, 0.0), name="p2"))
    p3 = mech.add(ms.Revolute(g, three, at=(0.45, 0.0), name="p3"))
    slide = mech.add(ms.Prismatic(g, bar, axis=(1.0, 0.0), at=(0.45, -0.12), name="slide"))
    mech.add(ms.Gear(p1, p2, ratio=ratio, name="coupling"))
    mech.add(ms.Gear.spur(p2, p3, ra, rb, name="mesh") if spur else
             ms.Gear(p2, p3, -ra / rb, name="mesh"))
    mech.add(ms.Gear.rack(p3, slide, rack, name="rack"))
    mech.add(ms.Spring(g, bar, at_a=(0.7, -0.12), at_b=(0.45, -0.12), stiffness=200.0,
                       rest_length=0.2, name="return"))
    mech.add(ms.Driver(p1, "3*t", name="motor"))
    return mech


@pytest.mark.parametrize("which, spur", [
    ("ratio", False), ("rack", False), ("ra", False),
    pytest.param("rb", True, marks=pytest.mark.slow)])      # the spur's derivatives: 12 s
def test_gear_ratios_and_radii_have_exact_sensitivities(which, spur):
    """A plain coupling's ratio (also one computed from Parameters), a spur pair's radius
    and a rack's radius as Parameters: the rack's travel is exactly linear in each along
    the train (∂x/∂k against its closed form), the motor torque against central
    differences; a new value needs no build."""
    values = {"ratio": -2.0, "ra": 0.05, "rb": 0.1, "rack": 0.02}
    mech = geared(**{**values, which: ms.Parameter(which, values[which])}, spur=spur)
    kin = mech.kinematics(1.0, 0.05, sensitivities=[which])
    assert kin.success, kin.message
    turn = 3.0 * kin.t * values["ratio"] * (-values["ra"] / values["rb"])   # the third gear's
    travel = {"ratio": turn / values["ratio"] * values["rack"],
              "ra": turn / values["ra"] * values["rack"],
              "rb": -turn / values["rb"] * values["rack"], "rack": turn}[which]
    col = kin.coordinate_names.index("bar.x")
    np.testing.assert_allclose(kin.sensitivity(which)[:, col], travel, atol=1e-10)

    def build(x):
        return geared(**{**values, which: x}, spur=spur)

    def central(h):
        up, down = (build(values[which] + s * h).kinematics(1.0, 0.05) for s in (1, -1))
        return (up.driver_effort(up.mechanism.drivers[0])
                - down.driver_effort(down.mechanism.drivers[0])) / (2 * h)
    h = 1e-3 * abs(values[which])                  # Richardson-extrapolated: error O(h⁴)
    effort = (4 * central(h / 2) - central(h)) / 3
    motor = mech.drivers[0]
    assert relative(kin.sensitivity(which, of="driver_effort", driver=motor), effort) < 1e-6
    mech.set_parameters(**{which: 1.2 * values[which]})
    np.testing.assert_allclose(mech.kinematics(1.0, 0.05).q,
                               build(1.2 * values[which]).kinematics(1.0, 0.05).q, atol=1e-12)


def test_motor_torque_and_multiplier_sensitivities_agree_with_finite_differences():
    """The driver's torque and every multiplier of the offset slider-crank under gravity,
    to a mass, a length and the offset (mass matrix, geometry and both at once), against
    central differences (Richardson-extrapolated: error O(h⁴))."""
    def build(r=0.15, e=0.05, m=0.8):
        return offset_slider_crank(r=r, e=e, m_rod=m)      # m: the rod's mass and inertia

    values = {"r": 0.15, "e": 0.05, "m": 0.8}
    params = {k: ms.Parameter(k, v) for k, v in values.items()}
    mech = build(**params)
    kin = mech.kinematics(0.6, 0.05, sensitivities=list(values))
    motor = mech.drivers[0]

    def central(name, h):
        up = build(**{**values, name: values[name] + h}).kinematics(0.6, 0.05)
        down = build(**{**values, name: values[name] - h}).kinematics(0.6, 0.05)
        return ((up.reactions.multipliers.lam - down.reactions.multipliers.lam) / (2 * h),
                (up.driver_effort(up.mechanism.drivers[0])
                 - down.driver_effort(down.mechanism.drivers[0])) / (2 * h))

    for name, value in values.items():
        h = 1e-3 * max(1.0, abs(value))
        (l1, e1), (l2, e2) = central(name, h), central(name, h / 2)
        lam_fd, effort_fd = (4 * l2 - l1) / 3, (4 * e2 - e1) / 3
        assert relative(kin.sensitivity(name, of="lambda"), lam_fd) < 1e-6, name
        assert relative(kin.sensitivity(name, of="driver_effort", driver=motor),
                        effort_fd) < 1e-6, name


def test_multiplier_sensitivities_under_a_load_moved_by_a_parameter_are_refused():
    """A spring on the slider, whose frame moves with the offset: the motion's
    sensitivities stand (loads do not move a driven mechanism), the multipliers' are
    refused naming the spring (its body-fixed point does not carry the derivatives)."""
    e = ms.Parameter("e", 0.05)
    mech = offset_slider_crank(e=e)
    slider = mech.body("slider")
    mech.add(ms.Spring(mech.ground, slider, at_a=(0.0, 0.0), at_b=tuple(slider.position),
                       stiffness=100.0, rest_length=0.3, name="return spring"))
    kin = mech.kinematics(0.3, 0.05, sensitivities=["e"])
    assert np.any(kin.sensitivity("e") != 0.0)
    with pytest.raises(ValueError, match="the load 'return spring' depends on Parameters"):
        kin.sensitivity("e", of="driver_effort", driver=mech.drivers[0])


def test_multiplier_sensitivities_under_springs_and_forces_agree_with_finite_differences():
    """Q_q q_k of a spring–damper from the ground to the rod and of a force on the slider
    enter the multipliers' sensitivities: the motor torque to the crank's length against
    Richardson-extrapolated central differences. The rod and slider frames are given as
    plain numbers (the nominal design's), so the loads' body-fixed points stand; the rod's
    crank-end point follows the crank's tip."""
    theta, l, e = THETA0, 0.40, 0.05
    b0 = 0.15 * np.array([np.cos(theta), np.sin(theta)])
    c0 = np.array([b0[0] + np.sqrt(l * l - (b0[1] - e) ** 2), e])

    def build(r):
        mech = ms.Mechanism("sprung slider-crank", gravity=(0.0, -9.81))
        b = np.array([r * np.cos(theta), r * np.sin(theta)])
        crank = mech.add(ms.RigidBody.rod("crank", (0.0, 0.0), b, mass=0.4))
        rod = mech.add(ms.RigidBody("rod", mass=0.8, inertia=0.8 * l * l / 12,
                                    position=(b0 + c0) / 2,
                                    angle=float(np.arctan2(*(c0 - b0)[::-1]))))
        slider = mech.add(ms.RigidBody("slider", mass=0.3, inertia=1e-4, position=c0))
        pin = mech.add(ms.Revolute(mech.ground, crank, at=(0.0, 0.0), name="O"))
        mech.add(ms.Revolute(crank, rod, at=b, name="A"))
        mech.add(ms.Revolute(rod, slider, at=c0, name="B"))
        mech.add(ms.Prismatic(mech.ground, slider, axis=(1.0, 0.0), at=c0, name="guide"))
        mech.add(ms.Driver(pin, f"{SPEED}*t"))
        mech.add(ms.Spring(mech.ground, rod, at_a=(0.0, 0.3), at_b=(0.2, 0.1),
                           stiffness=300.0, damping=3.0, name="lift"))
        mech.add(ms.Force(slider, (-40.0, 0.0), name="load"))
        return mech

    mech = build(ms.Parameter("r", 0.15))
    kin = mech.kinematics(0.6, 0.05, sensitivities=["r"])
    motor = mech.drivers[0]

    def central(h):
        up, down = (build(0.15 + s).kinematics(0.6, 0.05) for s in (h, -h))
        return (up.driver_effort(up.mechanism.drivers[0])
                - down.driver_effort(down.mechanism.drivers[0])) / (2 * h)

    reference = (4 * central(5e-4) - central(1e-3)) / 3
    assert relative(kin.sensitivity("r", of="driver_effort", driver=motor), reference) < 1e-6


def test_joint_force_sensitivities_agree_with_finite_differences():
    """of="joint_force": the pin forces of a revolute between two moving bodies, of the
    crank's ground pivot and of the slider's guide (a prismatic joint, whose force turns
    with its axis) to the offset and a mass, against Richardson-extrapolated differences."""
    values = {"e": 0.05, "m": 0.8}

    def build(e=0.05, m=0.8):
        return offset_slider_crank(e=e, m_rod=m, tilt=0.2)

    kin = build(**{k: ms.Parameter(k, v) for k, v in values.items()}).kinematics(
        0.6, 0.05, sensitivities=list(values))
    for name, value in values.items():
        def central(h):
            up = build(**{**values, name: value + h}).kinematics(0.6, 0.05)
            down = build(**{**values, name: value - h}).kinematics(0.6, 0.05)
            return {j: (up.joint_force(j) - down.joint_force(j)) / (2 * h)
                    for j in ("O", "B", "guide")}
        h = 1e-3 * max(1.0, abs(value))
        coarse, fine = central(h), central(h / 2)
        for joint in ("O", "B", "guide"):
            reference = (4 * fine[joint] - coarse[joint]) / 3
            assert relative(kin.sensitivity(name, of="joint_force", joint=joint),
                            reference) < 1e-6, (name, joint)
    with pytest.raises(ValueError, match="needs the `joint`"):
        kin.sensitivity("e", of="joint_force")


def quick_return(r=0.1, d=0.25):
    """A crank (r, from the origin, driven) whose tip pin carries a block sliding along a
    rocker pivoted at (0, −d): the slide is a prismatic joint between two moving bodies,
    its force turning with the rocker."""
    mech = ms.Mechanism("quick return", gravity=(0.0, -9.81))
    b = np.array([r * np.cos(THETA0), r * np.sin(THETA0)])
    g = np.array([0.0, -d])
    u = (b - g) / np.hypot(*(b - g))
    crank = mech.add(ms.RigidBody.rod("crank", (0.0, 0.0), b, mass=0.4))
    rocker = mech.add(ms.RigidBody.rod("rocker", g, g + 0.6 * u, mass=1.2))
    block = mech.add(ms.RigidBody("block", mass=0.3, inertia=1e-3, position=b,
                                  angle=np.arctan2(u[1], u[0])))
    pin = mech.add(ms.Revolute(mech.ground, crank, at=(0.0, 0.0), name="O"))
    mech.add(ms.Revolute(crank, block, at=b, name="tip"))
    mech.add(ms.Prismatic(rocker, block, axis=u, at=b, name="slide"))
    mech.add(ms.Revolute(mech.ground, rocker, at=g, name="G"))
    mech.add(ms.Driver(pin, f"{SPEED}*t"))
    return mech


def test_the_force_of_a_slide_that_turns_has_its_sensitivity():
    """The slide's force (normal to a turning rocker) and the rocker pivot's, to the crank
    length and the pivot's offset, against Richardson-extrapolated differences: the
    joint's Jacobian turning with the motion enters (R3_q q_k)."""
    values = {"r": 0.1, "d": 0.25}
    kin = quick_return(**{k: ms.Parameter(k, v) for k, v in values.items()}).kinematics(
        0.8, 0.05, sensitivities=list(values))
    for name, value in values.items():
        def central(h):
            up = quick_return(**{**values, name: value + h}).kinematics(0.8, 0.05)
            down = quick_return(**{**values, name: value - h}).kinematics(0.8, 0.05)
            return {j: (up.joint_force(j) - down.joint_force(j)) / (2 * h)
                    for j in ("slide", "G")}
        coarse, fine = central(1e-3), central(5e-4)
        for joint in ("slide", "G"):
            reference = (4 * fine[joint] - coarse[joint]) / 3
            assert relative(kin.sensitivity(name, of="joint_force", joint=joint),
                            reference) < 1e-6, (name, joint)


def test_a_spring_s_stiffness_enters_the_motor_torque_exactly():
    """The motor torque of a driven slider-crank is linear in a spring's stiffness, so its
    sensitivity is the difference of two analyses one unit of stiffness apart."""
    def build(k):
        mech = offset_slider_crank()
        slider = mech.body("slider")
        mech.add(ms.Spring(mech.ground, slider, at_a=(0.7, 0.05), at_b=slider.position,
                           stiffness=k, rest_length=0.2, damping=1.5, name="return"))
        return mech

    mech = build(ms.Parameter("k", 300.0))
    kin = mech.kinematics(0.6, 0.05, sensitivities=["k"])
    got = kin.sensitivity("k", of="driver_effort", driver=mech.drivers[0])
    one, two = (build(k).kinematics(0.6, 0.05) for k in (300.0, 301.0))
    reference = two.driver_effort(two.mechanism.drivers[0]) - \
        one.driver_effort(one.mechanism.drivers[0])
    assert relative(got, reference) < 1e-8


def test_a_driver_law_s_parameter_has_exact_sensitivities():
    """The crank speed w in the law w t + 0.2 sin(w t) (`Driver(values=...)`): the crank
    angle's sensitivity is t (1 + 0.2 cos(w t)) exactly; the slider's position, rate and
    acceleration and the motor torque against central differences; a new value needs no
    build and equals a fresh model."""
    law = "w*t + 0.2*sin(w*t)"
    mech = offset_slider_crank(speed=ms.Parameter("w", SPEED), law=law)
    assert mech.parameters == ["w"]
    kin = mech.kinematics(1.0, 0.05, sensitivities=["w"])
    col = kin.coordinate_names.index("crank.angle")
    np.testing.assert_allclose(kin.sensitivity("w")[:, col],
                               kin.t * (1 + 0.2 * np.cos(SPEED * kin.t)), atol=1e-12)

    def build(w):
        return offset_slider_crank(speed=w, law=law)
    for of, quantity in (("q", lambda k: k.q), ("v", lambda k: k.v),
                         ("a", lambda k: k.accelerations())):
        assert relative(kin.sensitivity("w", of=of),
                        central_difference(build, SPEED, quantity)) < 1e-6, of
    motor = mech.drivers[0]
    effort = central_difference(build, SPEED,
                                lambda k: k.driver_effort(k.mechanism.drivers[0]))
    assert relative(kin.sensitivity("w", of="driver_effort", driver=motor), effort) < 1e-6
    mech.set_parameters(w=7.0)
    assert motor.expression == "((7.0 * t) + (0.2 * sin((7.0 * t))))"
    np.testing.assert_allclose(mech.kinematics(1.0, 0.05).q, build(7.0).kinematics(1.0, 0.05).q,
                               atol=1e-12)


def test_bad_driver_values_are_refused_naming_the_driver():
    mech = offset_slider_crank()
    pin = mech.joint("O")
    with pytest.raises(ms.ModelError, match="driver 'd': `values` names 'k', which its "
                                            "expression"):
        ms.Driver(pin, "w*t", name="d", values={"w": 1.0, "k": 2.0})
    with pytest.raises(ms.ModelError, match="`values` key 't' is not a name"):
        ms.Driver(pin, "t", name="d", values={"t": 1.0})
    with pytest.raises(ms.ModelError, match="a table or a function has none"):
        ms.Driver(pin, name="d", table=([0, 1, 2, 3], [0, 1, 2, 3]), values={"w": 1.0})
    with pytest.raises(ms.ModelError, match="values\\['w'\\]"):
        ms.Driver(pin, "w*t", name="d", values={"w": "fast"})
    with pytest.raises(ms.ModelError, match="driver 'd': the Parameter bound to 'n' is a whole-number exponent"):
        ms.Driver(pin, "t**n", name="d", values={"n": ms.Parameter("n", 2.0)})
    with pytest.raises(ms.ModelError, match="unknown name|not allowed|'u'"):
        ms.Driver(pin, "u*t", name="d", values={"w": 1.0})


def test_a_scene_s_parameter_in_its_driver_s_law_is_differentiated():
    """The driven slider-crank scene's crank speed w, given as a Parameter, stays one in
    the driver's law "w*t": the crank angle's sensitivity is t exactly."""
    path = pathlib.Path(__file__).resolve().parents[1] / "mechanisms" / \
        "driven_slider_crank.toml"
    mech = ms.load_scene(path, {"w": ms.Parameter("w", 50 * math.pi)}).mechanism
    assert "w" in mech.parameters
    kin = mech.kinematics(0.02, 0.001, sensitivities=["w"])
    col = kin.coordinate_names.index("crank.angle")
    np.testing.assert_allclose(kin.sensitivity("w")[:, col], kin.t, atol=1e-12)
