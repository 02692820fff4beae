"""Kinematic analysis and inverse dynamics of fully driven mechanisms, the cycle figures, and
the engineering keys of scenes and the command line."""

import math
import textwrap

import numpy as np
import pytest

import mechsim as ms
from mechsim.app.cli import main
from mechsim.engineering.driven import KinematicsError
from mechsim.examples import four_bar_angles, general_four_bar, slider_crank_position
from test_driven import crank_rocker
from test_reactions import check_against_newton_euler


def test_a_driven_crank_rocker_is_solved_from_its_constraints():
    mech = crank_rocker()                      # crank driven at 10 rad/s from 0.3 rad
    res = mech.kinematics(0.628, 1e-3)         # a turn (the grid uniform to its end)
    assert res.success and res.stats["method"] == "kinematics", res.message
    th2 = 0.3 + 10.0 * res.t
    th3, th4 = four_bar_angles(th2, 0.2, 0.6, 0.5, 0.7, 1)
    assert np.max(np.abs(np.unwrap(res.coordinate("rocker.angle")) - np.unwrap(th4))) < 1e-12
    assert np.max(np.abs(np.unwrap(res.coordinate("coupler.angle")) - np.unwrap(th3))) < 1e-12
    # Velocities and accelerations: the exact angles' derivatives (central differences of
    # the closed form, error ~1e-9 at this step).
    h = 1e-5
    w4 = (four_bar_angles(th2 + 10 * h, 0.2, 0.6, 0.5, 0.7, 1)[1]
          - four_bar_angles(th2 - 10 * h, 0.2, 0.6, 0.5, 0.7, 1)[1]) / (2 * h)
    assert np.max(np.abs(res.joint_rate("O4") - w4)) < 1e-7 * np.max(np.abs(w4))
    a4 = (four_bar_angles(th2 + 10 * h, 0.2, 0.6, 0.5, 0.7, 1)[1] - 2 * th4
          + four_bar_angles(th2 - 10 * h, 0.2, 0.6, 0.5, 0.7, 1)[1]) / h ** 2
    acc = res.accelerations()[:, mech.coordinate_names.index("rocker.angle")]
    assert np.max(np.abs(acc - a4)) < 1e-4 * np.max(np.abs(a4))
    # The motor torque the motion needs: Newton–Euler on every body.
    check_against_newton_euler(mech, res)


def test_a_driven_change_point_four_bar_keeps_its_branch_and_says_where_it_is_singular():
    mech = general_four_bar(1.0, 2.0, 1.0, 2.0, theta=0.5)
    mech.add(ms.Driver(mech.joint("O2"), "3*t"))
    res = mech.kinematics(2.0, 0.01)
    assert res.success
    # A parallelogram throughout: the rocker turns with the crank.
    th = 0.5 + 3 * res.t
    assert np.max(np.abs(np.exp(1j * res.coordinate("rocker.angle")) - np.exp(1j * th))) < 1e-9
    # All bars aligned at θ = π and 2π: t = 0.881 and 1.928 s.
    assert [abs(p.t_min - t) < 0.011 for p, t in
            zip(res.singular_passages, [(math.pi - 0.5) / 3, (2 * math.pi - 0.5) / 3])] == \
        [True, True]
    assert "do not decide the branch" in res.message


def test_kinematics_over_the_driver_s_range():
    """A crank driven by an accelerating law, analysed at every degree of its first turn:
    the samples fall where the law reaches each angle, and the rocker is where the closed
    form puts it for that crank angle."""
    mech = general_four_bar(0.2, 0.6, 0.5, 0.7, theta=0.3)
    mech.add(ms.Driver(mech.joint("O2"), "4*t + 3*t**2", name="motor"))
    angles = np.radians(np.arange(0.0, 361.0))
    res = mech.kinematics(over=("motor", angles))
    assert res.success and len(res.t) == 361
    np.testing.assert_allclose(4 * res.t + 3 * res.t ** 2, angles, atol=1e-13)
    th4 = four_bar_angles(0.3 + angles, 0.2, 0.6, 0.5, 0.7, 1)[1]
    assert np.max(np.abs(np.unwrap(res.coordinate("rocker.angle")) - np.unwrap(th4))) < 1e-12
    np.testing.assert_allclose(res.joint_rate("O2"), 4 + 6 * res.t, rtol=1e-12)
    # A range that starts beyond the crank's present angle: the samples are still where
    # the law reaches each value (the assembled start is stepped from, not reported).
    later = mech.kinematics(over=("motor", angles[90:181]))
    assert later.success and len(later.t) == 91
    np.testing.assert_allclose(later.joint_coordinate("O2") - 0.3, angles[90:181], atol=1e-12)
    np.testing.assert_allclose(later.q, res.q[90:181], atol=1e-12)
    wave = general_four_bar(0.2, 0.6, 0.5, 0.7, theta=0.3)
    wave.add(ms.Driver(wave.joint("O2"), "sin(t)", name="motor"))
    with pytest.raises(KinematicsError, match="not monotonic"):
        wave.kinematics(over=("motor", [0.0, 1.5]))
    with pytest.raises(KinematicsError, match="not both"):
        wave.kinematics(1.0, 0.01, over=("motor", [0.0, 0.5]))


def test_a_range_reached_by_no_configuration_fails_with_no_samples():
    """A rocker driven over angles it cannot reach from where it starts: the analysis
    fails naming the step, with no samples (none of the range was reached)."""
    mech = general_four_bar(0.2, 0.6, 0.5, 0.7, theta=0.3)
    mech.add(ms.Driver(mech.joint("O4"), "t", name="rocker motor"))
    res = mech.kinematics(over=("rocker motor", [3.0, 3.5]))
    assert res.status == "failed" and len(res.t) == 0 and res.q.shape == (0, 9)
    assert res.message.startswith("no configuration followed from t = 0 to 3")


def test_kinematic_analysis_needs_a_fully_driven_mechanism():
    with pytest.raises(KinematicsError, match="1 degree"):
        general_four_bar(0.2, 0.6, 0.5, 0.7, theta=0.3).kinematics(1.0, 0.01)


def test_a_driven_slider_crank_slides_as_its_closed_form_and_its_motor_torque_balances():
    mech = ms.examples.slider_crank(driven=True, crank_speed=100.0)
    res = mech.kinematics(0.0628, 1e-4)
    x = slider_crank_position(100.0 * res.t)
    assert np.max(np.abs(res.coordinate("slider.x") - x)) < 1e-12
    check_against_newton_euler(mech, res)
    # The same against a simulation of the same mechanism.
    sim = mech.simulate(res.t[-1], rtol=1e-11, atol=1e-13, output_step=1e-4)
    effort = res.driver_effort(mech.drivers[0])
    assert np.max(np.abs(sim.driver_effort(mech.drivers[0]) - effort)) < \
        1e-7 * np.max(np.abs(effort))


def test_cycle_figures_and_the_transmission_angle():
    mech = crank_rocker()
    res = mech.kinematics(2 * math.pi / 10, 1e-4)
    figures = res.cycle_figures()
    # The crank-rocker a, b, c, d = 0.2, 0.6, 0.5, 0.7: cos μ = (b² + c² − a² − d² +
    # 2ad cos θ)/(2bc), from 90° (cos θ = −… ) to its least, 53.13°, at θ = 0.
    th = np.linspace(0, 2 * math.pi, 200001)
    mu = np.degrees(np.arccos((0.36 + 0.25 - 0.04 - 0.49 + 0.28 * np.cos(th)) / 0.6))
    mu = np.minimum(mu, 180 - mu)
    assert set(figures.transmission) == {"B"}
    assert figures.transmission["B"]["min"] == pytest.approx(mu.min(), abs=1e-3)
    # (μ passes 90° steeply: the samples 1e-3 rad of crank apart come within 0.02°.)
    assert figures.transmission["B"]["max"] == pytest.approx(mu.max(), abs=0.02)
    effort = res.driver_effort(mech.drivers[0])
    d = figures.drivers[mech.drivers[0].name]
    assert abs(d["peak_effort"]) == pytest.approx(np.max(np.abs(effort)))
    assert d["rms_effort"] == pytest.approx(np.sqrt(np.mean(effort[:-1] ** 2)), rel=1e-4)
    # Over a whole turn at constant speed gravity's work is zero: the mean power too.
    assert abs(d["mean_power"]) < 1e-6 * abs(d["peak_power"])
    force = np.linalg.norm(res.joint_force("A"), axis=1)
    assert figures.joints["A"]["peak_force"] == pytest.approx(force.max())
    assert "transmission angle at 'B'" in str(figures)


SCENE = """
name = "engine"
[parameters]
r = 0.05
l = 0.2
w = "2*pi*25"
[[body]]
name = "crank"
rod = [[0, 0], ["r", 0]]
mass = 0.8
[[body]]
name = "rod"
rod = [["r", 0], ["r + l", 0]]
mass = 0.6
[[body]]
name = "piston"
mass = 0.5
inertia = 1e-4
position = ["r + l", 0]
[[joint]]
type = "revolute"
name = "main"
bodies = ["ground", "crank"]
at = [0, 0]
[[joint]]
type = "revolute"
name = "pin"
bodies = ["crank", "rod"]
at = ["r", 0]
[[joint]]
type = "revolute"
name = "wrist"
bodies = ["rod", "piston"]
at = ["r + l", 0]
[[joint]]
type = "prismatic"
name = "cylinder"
bodies = ["ground", "piston"]
axis = [1, 0]
at = ["r + l", 0]
[[driver]]
name = "motor"
joint = "main"
expression = "w*t"
[[rotational_spring]]
bodies = ["crank", "rod"]
stiffness = 0.0
damping = 0.01
[simulation]
t_end = 0.04
rtol = 1e-9
atol = 1e-11
output_step = 0.0004
[output]
plots = ["reactions", "efforts"]
reactions = ["pin"]
efforts = true
save = true
"""


def test_a_scene_asks_for_reactions_and_efforts(tmp_path, capsys, monkeypatch):
    path = tmp_path / "engine.toml"
    path.write_text(SCENE)
    monkeypatch.chdir(tmp_path)
    assert main(["run", str(path)]) == 0
    out = capsys.readouterr().out
    scene = ms.load_scene(path)
    res = scene.simulate()
    pin = np.linalg.norm(res.joint_force("pin"), axis=1)
    effort = res.driver_effort("motor")
    assert f"joint 'pin': peak force {pin.max():.4g} N" in out
    assert "joint 'main'" not in out
    assert f"driver 'motor': peak {effort[np.argmax(np.abs(effort))]:.4g}" in out
    for name in ("engine_reactions.png", "engine_efforts.png"):
        assert (tmp_path / "out" / "engine" / name).stat().st_size > 1000
    saved = ms.load_result(tmp_path / "out" / "engine" / "engine.npz")
    np.testing.assert_allclose(saved.driver_effort("motor"), effort, rtol=1e-12)
    # The driver's law took the parameter w = 50π.
    np.testing.assert_allclose(res.joint_rate("main"), 50 * math.pi, rtol=1e-12)


def test_the_command_line_prints_equilibrium_modes_and_kinematics(tmp_path, capsys,
                                                                   monkeypatch):
    monkeypatch.chdir(tmp_path)
    path = tmp_path / "engine.toml"
    path.write_text(SCENE)
    assert main(["run", str(path), "--kinematics", "--no-plots"]) == 0
    out = capsys.readouterr().out
    assert "kinematics 101 configurations solved" in out and "effort     driver 'motor'" in out
    rod = tmp_path / "rod.toml"
    rod.write_text(textwrap.dedent("""
        [[body]]
        name = "rod"
        rod = [[0, 0], [0.8, 0]]
        mass = 2.0
        [[joint]]
        type = "revolute"
        name = "pin"
        bodies = ["ground", "rod"]
        at = [0, 0]
        [[rotational_spring]]
        bodies = ["ground", "rod"]
        stiffness = 15.0
        rest_angle = 0.0
        [simulation]
        t_end = 0.1
    """))
    assert main(["run", str(rod), "--equilibrium", "--modes", "--no-plots"]) == 0
    out = capsys.readouterr().out
    exact = -0.4671434776157626          # 15 θ = −2 g 0.4 cos θ
    assert f"rod.angle = {exact:.6g}" in out
    omega = math.sqrt((15 - 2 * 9.81 * 0.4 * math.sin(exact)) / (2 * 0.64 / 3))
    assert f"ω = {omega:.6g} rad/s" in out


@pytest.mark.parametrize("change, message", [
    ('reactions = ["nowhere"]', "no joint named 'nowhere'"),
    ("reactions = 3", "expected true or an array of joint names"),
    ('plots = ["forces"]', "must be one of 'energy', 'reactions', 'efforts'"),
])
def test_scene_engineering_keys_are_checked(tmp_path, change, message):
    text = SCENE.replace('reactions = ["pin"]', "").replace(
        'plots = ["reactions", "efforts"]', change)
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(ms.scene.SceneError, match=message):
        ms.load_scene(path)


def test_efforts_need_a_driver(tmp_path):
    text = SCENE.replace('[[driver]]\nname = "motor"\njoint = "main"\nexpression = "w*t"\n', "")
    path = tmp_path / "free.toml"
    path.write_text(text)
    with pytest.raises(ms.scene.SceneError, match="no driver"):
        ms.load_scene(path)


@pytest.mark.parametrize("bad, message", [
    (dict(stiffness=-1.0), "`stiffness` must be"),
    (dict(stiffness="2"), "`stiffness` must be a number"),
    (dict(rest_angle=float("nan")), "`rest_angle` must be finite"),
])
def test_rotational_spring_arguments_are_checked(bad, message):
    mech = ms.examples.pendulum()
    rod = mech.body("rod")
    with pytest.raises(ms.ModelError, match=message):
        ms.RotationalSpring(mech.ground, rod, **{"stiffness": 1.0, **bad})


def test_load_functions_are_checked_against_their_inputs():
    mech = ms.examples.pendulum()
    rod = mech.body("rod")
    pivot = mech.joint("pivot")
    with pytest.raises(ms.ModelError, match=r"must take \(t, s, rate\)"):
        ms.Torque(rod, lambda t: 1.0, joint=pivot)
    with pytest.raises(ms.ModelError, match=r"must take \(t, q, v\)"):
        ms.Force(rod, lambda t, s: (0, 0), state=True)
    with pytest.raises(ms.ModelError, match="not both"):
        ms.Torque(rod, lambda t, q, v: 0.0, joint=pivot, state=True)
    other = ms.examples.pendulum()
    with pytest.raises(ms.ModelError, match="add the joint first"):
        mech.add(ms.Torque(rod, lambda t, s, w: 0.0, joint=other.joint("pivot")))
