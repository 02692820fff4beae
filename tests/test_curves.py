"""Points on curves: a pin in a straight or circular slot, a cam follower on its pitch
curve, against closed forms."""

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

import mechsim as ms

W = 2 * math.pi                                   # rad/s, the driven crank or cam


@pytest.mark.parametrize("build", ["assembled", "fused"])
def test_a_scotch_yoke_moves_as_r_cos_theta_and_its_slot_pushes_it(build):
    """A crank pin in the vertical slot of a yoke that slides on a horizontal guide:
    x = r cos θ, and the slot's force on the crank pin is horizontal, m r ω² cos θ."""
    r, m = 0.1, 2.0
    mech = ms.Mechanism("scotch yoke", gravity=(0.0, -9.81))
    crank = mech.add(ms.RigidBody.rod("crank", (0, 0), (r, 0), 0.5))
    yoke = mech.add(ms.RigidBody.point_mass("yoke", (r, 0), m))
    pivot = mech.add(ms.Revolute(mech.ground, crank, at=(0, 0), name="O"))
    mech.add(ms.Prismatic(mech.ground, yoke, axis=(1, 0), at=(r, 0), name="guide"))
    mech.add(ms.PointOnCurve(yoke, crank, at=(r, 0), curve=("line", (0, 1)), name="slot"))
    mech.add(ms.Driver(pivot, f"{W}*t", name="motor"))
    mech.problem(build=build)
    res = mech.kinematics(1.0, 0.01)
    assert res.success, res.message
    theta = W * res.t
    np.testing.assert_allclose(res.coordinate("yoke.x"), r * np.cos(theta), atol=1e-10)
    force = res.joint_force("slot")                       # on the crank (body_b)
    np.testing.assert_allclose(force[:, 0], m * r * W**2 * np.cos(theta), rtol=0, atol=1e-8)
    np.testing.assert_allclose(force[:, 1], 0.0, atol=1e-8)


@pytest.mark.parametrize("build", ["assembled", "fused"])
def test_a_cam_follower_lifts_by_the_cam_profile(build):
    """A cam r(φ) = 0.05 + 0.01 cos φ turning at 2π rad/s under a follower on a vertical
    guide: the roller centre at the cam's polar angle π/2 − θ, so y = r(π/2 − θ), over a
    whole revolution (1e-10)."""
    profile = "0.05 + 0.01*cos(phi)"
    y0 = 0.05 + 0.01 * math.cos(math.pi / 2)
    mech = ms.Mechanism("cam", gravity=(0.0, -9.81))
    cam = mech.add(ms.RigidBody.disc("cam", (0, 0), 0.06, 1.0))
    follower = mech.add(ms.RigidBody.point_mass("follower", (0, y0), 0.3))
    shaft = mech.add(ms.Revolute(mech.ground, cam, at=(0, 0), name="shaft"))
    mech.add(ms.Prismatic(mech.ground, follower, axis=(0, 1), at=(0, y0), name="guide"))
    mech.add(ms.PointOnCurve(cam, follower, at=(0, y0), centre=(0, 0),
                             curve=("polar", profile), name="contact"))
    mech.add(ms.Driver(shaft, f"{W}*t", name="motor"))
    mech.problem(build=build)
    res = mech.kinematics(1.0, 0.005)
    assert res.success, res.message
    lift = 0.05 + 0.01 * np.cos(math.pi / 2 - W * res.t)
    np.testing.assert_allclose(res.coordinate("follower.y"), lift, rtol=0, atol=1e-10)
    # the contact holds the follower up: its force on the follower balances its weight
    # and its acceleration along the guide (ÿ = −0.01 W² sin(W t))
    ydd = -0.01 * W**2 * np.sin(W * res.t)
    force = res.joint_force("contact")
    guide = res.joint_force("guide")
    np.testing.assert_allclose(force[:, 1] + guide[:, 1], 0.3 * (ydd + 9.81), atol=1e-7)


def spline_cam(points, build=None):
    """The cam follower of the test above, its pitch curve through `points` (φ, r)."""
    from mechsim.model.splines import PeriodicSpline
    y0 = PeriodicSpline(points, "cam").value(math.pi / 2)
    mech = ms.Mechanism("spline cam", gravity=(0.0, -9.81))
    cam = mech.add(ms.RigidBody.disc("cam", (0, 0), 0.06, 1.0))
    follower = mech.add(ms.RigidBody.point_mass("follower", (0, y0), 0.3))
    shaft = mech.add(ms.Revolute(mech.ground, cam, at=(0, 0), name="shaft"))
    mech.add(ms.Prismatic(mech.ground, follower, axis=(0, 1), at=(0, y0), name="guide"))
    contact = mech.add(ms.PointOnCurve(cam, follower, at=(0, y0), centre=(0, 0),
                                       curve=("polar", points), name="contact"))
    mech.add(ms.Driver(shaft, f"{W}*t", name="motor"))
    if build:
        mech.problem(build=build)
    return mech, contact.shape


def test_a_cam_given_by_points_lifts_its_follower_along_their_periodic_spline(build="fused"):
    """36 points of r = 0.05 + 0.01 cos φ + 0.004 sin 3φ: the follower's lift is scipy's
    periodic cubic spline through them at π/2 − θ (1e-10), within its interpolation error
    of the profile itself, and the contact force balances weight and inertia (ÿ = W² r'')."""
    phi = np.linspace(-math.pi, math.pi, 36, endpoint=False)
    profile = lambda f: 0.05 + 0.01 * np.cos(f) + 0.004 * np.sin(3 * f)    # noqa: E731
    points = np.column_stack([phi, profile(phi)])
    mech, shape = spline_cam(points, build)
    res = mech.kinematics(1.0, 0.005)
    assert res.success, res.message
    from scipy.interpolate import CubicSpline
    spline = CubicSpline(np.append(phi, math.pi), np.append(profile(phi), profile(phi[0])),
                         bc_type="periodic")
    at = np.mod(math.pi / 2 - W * res.t + math.pi, 2 * math.pi) - math.pi
    np.testing.assert_allclose(res.coordinate("follower.y"), spline(at), rtol=0, atol=1e-10)
    assert np.max(np.abs(spline(at) - profile(at))) < 2e-5
    ydd = W**2 * spline(at, 2)
    force = res.joint_force("contact")[:, 1] + res.joint_force("guide")[:, 1]
    np.testing.assert_allclose(force, 0.3 * (ydd + 9.81), atol=1e-7)
    moving = mech.simulate(0.5, rtol=1e-10, atol=1e-12, output_step=0.05)
    at = np.mod(math.pi / 2 - W * moving.t + math.pi, 2 * math.pi) - math.pi
    np.testing.assert_allclose(moving.coordinate("follower.y"), spline(at), atol=1e-9)


def test_a_cam_with_other_points_but_as_many_needs_no_new_build(tmp_path):
    phi = np.linspace(0.0, 2 * math.pi, 8, endpoint=False)
    a, _ = spline_cam(np.column_stack([phi, 0.05 + 0.01 * np.cos(phi)]))
    b, _ = spline_cam(np.column_stack([phi, 0.05 + 0.012 * np.sin(phi)]))
    c, _ = spline_cam(np.column_stack([phi[:-1], 0.05 + 0.01 * np.cos(phi[:-1])]))
    assert a.structure() == b.structure() != c.structure()
    back = ms.load_mechanism(b.save(tmp_path / "cam.toml"))
    np.testing.assert_array_equal(back.joints[2].shape.points, b.joints[2].shape.points)
    first, again = (m.kinematics(0.5, 0.05) for m in (b, back))
    np.testing.assert_array_equal(first.q, again.q)
    for bad, message in [([[0, 0.05], [1, 0.05], [2, 0.05]], "at least 4 rows"),
                         ([[0, 0.05], [2, 0.05], [1, 0.05], [3, 0.05]], "must increase"),
                         ([[0, 0.05], [2, 0.05], [4, 0.05], [6.5, 0.05]], "within one turn"),
                         ([[0, 0.05], [1, -0.05], [2, 0.05], [3, 0.05]], "positive")]:
        with pytest.raises(ms.ModelError, match=message):
            ms.PointOnCurve(ms.Mechanism().ground, ms.RigidBody("f", 1.0, 1e-3,
                                                                 position=(0.05, 0)),
                            at=(0.05, 0), centre=(0, 0), curve=("polar", bad))


def test_a_point_on_a_circular_slot_swings_as_a_simple_pendulum():
    """A small disc whose centre runs in a circular slot of radius R about the origin,
    released from the horizontal: its angle on the slot follows θ̈ = −(g/R) cos θ (the
    disc does not turn: nothing turns it)."""
    R = 0.4
    mech = ms.Mechanism("bead", gravity=(0.0, -9.81))
    bead = mech.add(ms.RigidBody.disc("bead", (R, 0), 0.01, 0.2))
    mech.add(ms.PointOnCurve(mech.ground, bead, at=(R, 0), centre=(0, 0),
                             curve=("circle", R), name="slot"))
    res = mech.simulate(1.0, rtol=1e-10, atol=1e-12, output_step=0.05)
    ref = solve_ivp(lambda t, y: [y[1], -9.81 / R * math.cos(y[0])], (0, 1), [0, 0],
                    t_eval=res.t, method="DOP853", rtol=1e-12, atol=1e-14)
    angle = np.arctan2(res.coordinate("bead.y"), res.coordinate("bead.x"))
    np.testing.assert_allclose(angle, ref.y[0], atol=1e-7)
    np.testing.assert_allclose(res.coordinate("bead.angle"), 0.0, atol=1e-10)


def test_a_point_off_its_curve_or_a_bad_curve_is_refused():
    mech = ms.Mechanism("m")
    a = mech.add(ms.RigidBody.disc("a", (0, 0), 0.1, 1.0))
    with pytest.raises(ms.ModelError, match=r"joint 's': its point \(0.2, 0\) is 0.1 off "
                                            r"its circle"):
        ms.PointOnCurve(mech.ground, a, at=(0.2, 0), centre=(0, 0), curve=("circle", 0.1),
                        name="s")
    with pytest.raises(ms.ModelError, match=r"`curve` must be"):
        ms.PointOnCurve(mech.ground, a, at=(0, 0), curve=("spline", 1.0), name="s")
    with pytest.raises(ms.ModelError, match=r"joint 's' `curve`: unknown name 'theta'"):
        ms.PointOnCurve(mech.ground, a, at=(0, 0), curve=("polar", "1 + theta"), name="s")
    with pytest.raises(ms.ModelError, match=r"joint 's': the polar curve must repeat every "
                                            r"2π"):
        ms.PointOnCurve(mech.ground, a, at=(0.1, 0), centre=(0, 0),
                        curve=("polar", "0.1 + 0.01*phi"), name="s")


def test_curve_joints_round_trip_through_a_scene(tmp_path):
    mech = ms.Mechanism("slots", gravity=(0.0, -9.81))
    a = mech.add(ms.RigidBody.disc("a", (0, 0), 0.1, 1.0))
    b = mech.add(ms.RigidBody.disc("b", (0.4, 0), 0.01, 0.2))
    c = mech.add(ms.RigidBody.disc("c", (0, 0.06), 0.01, 0.2))
    mech.add(ms.Revolute(mech.ground, a, at=(0, 0), name="shaft"))
    mech.add(ms.PointOnCurve(mech.ground, b, at=(0.4, 0), centre=(0, 0), curve=("circle", 0.4),
                             name="ring"))
    mech.add(ms.PointOnCurve(a, c, at=(0, 0.06), centre=(0, 0),
                             curve=("polar", "0.05 + 0.01*sin(phi)"), name="cam"))
    mech.add(ms.PointOnCurve(mech.ground, c, at=(0, 0.06), curve=("line", (0, 1)),
                             name="guide"))
    back = ms.load_mechanism(mech.save(tmp_path / "slots.toml"))
    assert back.structure() == mech.structure()
    a_res = mech.simulate(0.3, rtol=1e-9, output_step=0.05)
    b_res = back.simulate(0.3, rtol=1e-9, output_step=0.05)
    np.testing.assert_allclose(b_res.q, a_res.q, rtol=0, atol=1e-12)


def test_a_cam_without_a_shape_is_drawn_as_its_pitch_curve():
    """A cam body given by mass and inertia only is drawn as r(φ) about its centre."""
    mech = ms.Mechanism("cam")
    cam = mech.add(ms.RigidBody("cam", 1.0, 1e-3, position=(0.01, 0), angle=0.3))
    follower = mech.add(ms.RigidBody.point_mass("follower", (0, 0.05), 0.3))
    mech.add(ms.Revolute(mech.ground, cam, at=(0, 0), name="shaft"))
    mech.add(ms.Prismatic(mech.ground, follower, axis=(0, 1), at=(0, 0.05), name="guide"))
    mech.add(ms.PointOnCurve(cam, follower, at=(0, 0.05), centre=(0, 0),
                             curve=("polar", "0.05 + 0.01*sin(2*phi)")))
    (name, start, local, _), _ = mech.problem().drawing
    assert name == "cam"
    # back in global axes as built: the points lie at r(φ) from the centre at angle φ
    c, s = np.cos(0.3), np.sin(0.3)
    world = np.column_stack([c * local[:, 0] - s * local[:, 1] + 0.01,
                             s * local[:, 0] + c * local[:, 1]])
    phi = np.arctan2(world[:, 1], world[:, 0])
    np.testing.assert_allclose(np.hypot(*world.T), 0.05 + 0.01 * np.sin(2 * phi), atol=1e-12)


def test_the_cam_scene_lifts_its_follower_through_its_gears(tmp_path):
    """mechanisms/cam_follower.toml: the pinion at 3 rev/s turns the cam at −1.5 rev/s
    (r 20/40 mm), the follower's lift channel is 8 mm cos(π/2 − θ_cam), and its table
    holds the contact force (no coordinate columns for a curve joint)."""
    from pathlib import Path
    scene = ms.load_scene(Path(__file__).resolve().parents[1] / "mechanisms" /
                          "cam_follower.toml")
    res = scene.simulate(t_end=0.2, output_step=0.01)
    assert res.success, res.message
    cam = -0.5 * 2 * math.pi * 3 * res.t
    np.testing.assert_allclose(res.coordinate("cam.angle"), cam, atol=1e-9)
    np.testing.assert_allclose(res.channel("lift"), 0.008 * np.cos(math.pi / 2 - cam),
                               atol=1e-9)
    table = res.table(joints=["contact"], drivers=True)
    assert "contact force x [N]" in table and "contact coordinate [rad]" not in table
    assert np.abs(table["contact force y [N]"]).min() > 5.0      # the spring holds it on


def test_a_point_on_curve_takes_its_arguments_in_either_order():
    """(body_a, body_b, at, curve) and the public API's (body_a, curve, body_b, point) make
    the same joint."""
    mech = ms.Mechanism("slot")
    yoke = mech.add(ms.RigidBody.point_mass("yoke", (0.1, 0), 1.0))
    pin = mech.add(ms.RigidBody.disc("pin", (0.1, 0.05), 0.01, 0.1))
    a = ms.PointOnCurve(yoke, pin, (0.1, 0.05), ("line", (0, 1)), name="a")
    b = ms.PointOnCurve(yoke, ("line", (0, 1)), pin, (0.1, 0.05), name="b")
    c = ms.PointOnCurve(yoke, curve=("line", (0, 1)), body_b=pin, point=(0.1, 0.05), name="c")
    for other in (b, c):
        assert other.body_b is pin and other.parameter_values() == a.parameter_values()
    with pytest.raises(ms.ModelError, match="needs body_b's point"):
        ms.PointOnCurve(yoke, pin, curve=("line", (0, 1)))
