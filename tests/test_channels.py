"""Channels: quantities of the user's own, written as expressions, recorded with a result."""

import math

import numpy as np
import pytest

import mechsim as ms

L, M, G = 0.8, 2.0, 9.81


def pendulum():
    """A uniform rod pinned at one end at the origin, drawn horizontal, falling from rest."""
    mech = ms.Mechanism("pendulum", gravity=(0.0, -G))
    rod = mech.add(ms.RigidBody.rod("rod", (0, 0), (L, 0), mass=M))
    mech.add(ms.Revolute(mech.ground, rod, at=(0, 0), name="O"))
    return mech


@pytest.fixture(scope="module")
def swing():
    mech = pendulum()
    mech.add(ms.Channel("energy", f"0.5*{M}*(rod.x.rate**2 + rod.y.rate**2) + "
                                  f"0.5*{M * L**2 / 12}*rod.angle.rate**2 + {M * G}*rod.y",
                        unit="J"))
    mech.add(ms.Channel("tip_speed", f"{L}*abs(rod.angle.rate)", unit="m/s"))
    mech.add(ms.Channel("angular_acceleration", "rod.angle.acceleration", unit="rad/s²"))
    mech.add(ms.Channel("swing", "degrees(O.coordinate)", unit="deg"))
    mech.add(ms.Channel("log_height", "log(rod.y)"))
    return mech.simulate(1.0, rtol=1e-10, atol=1e-12, output_step=0.01)


def test_a_channel_of_the_energy_is_the_results_own_energy(swing):
    """T + V written by hand as a channel equals the result's energy (an independent sum
    from the mass matrix) and stays at its initial value 0 (no dissipation)."""
    np.testing.assert_allclose(swing.channel("energy"), swing.energy.total, rtol=0, atol=1e-12)
    np.testing.assert_allclose(swing.channel("energy"), 0.0, rtol=0, atol=1e-8)


def test_rate_acceleration_and_joint_channels_follow_the_exact_equation(swing):
    """θ̈ = −(3g / 2L) cos θ for the rod pinned at its end; the pin's coordinate is θ − θ₀ =
    θ (drawn at 0); the tip speed is L |θ̇|."""
    theta = swing.coordinate("rod.angle")
    np.testing.assert_allclose(swing.channel("angular_acceleration"),
                               -1.5 * G / L * np.cos(theta), rtol=0, atol=1e-7)
    np.testing.assert_allclose(swing.channel("swing"), np.degrees(theta), rtol=0, atol=1e-9)
    np.testing.assert_allclose(swing.channel("tip_speed"),
                               L * np.abs(swing.v[:, 2]), rtol=1e-14, atol=0)
    assert swing.channel("swing").min() < -60.0          # it really swung


def test_where_a_channel_is_undefined_the_sample_is_nan(swing):
    """log(rod.y): y is 0 at the start (log undefined there) and negative after."""
    values = swing.channel("log_height")
    assert np.isnan(values).all()


def test_channels_are_columns_of_the_table_and_csv(swing, tmp_path):
    table = swing.table()
    assert ["energy [J]", "tip_speed [m/s]", "angular_acceleration [rad/s²]", "swing [deg]",
            "log_height [-]"] == list(table)[-5:]
    np.testing.assert_array_equal(table["swing [deg]"], swing.channel("swing"))
    path = swing.to_csv(tmp_path / "swing.csv")
    header = path.read_text(encoding="utf-8").splitlines()[0]
    assert header.endswith("energy [J],tip_speed [m/s],angular_acceleration [rad/s²],"
                           "swing [deg],log_height [-]")


def test_channels_are_saved_with_the_result_and_answer_after_loading(swing, tmp_path):
    path = swing.save(tmp_path / "swing.npz")
    loaded = ms.load_result(path)
    np.testing.assert_array_equal(loaded.channel("swing"), swing.channel("swing"))
    assert [c.name for c in loaded.mechanism.channels] == [c.name for c in
                                                           swing.mechanism.channels]


def test_a_channel_in_a_scene_binds_its_parameters(tmp_path):
    scene = tmp_path / "pendulum.toml"
    scene.write_text(f"""
name = "pendulum"
[parameters]
L = {L}
[[body]]
name = "rod"
rod = [[0, 0], ["L", 0]]
mass = {M}
[[joint]]
type = "revolute"
name = "O"
bodies = ["ground", "rod"]
at = [0, 0]
[[channel]]
name = "tip_y"
expression = "rod.y + L/2*sin(rod.angle)"
unit = "m"
[simulation]
t_end = 0.5
rtol = 1e-9
""", encoding="utf-8")
    s = ms.load_scene(scene)
    assert s.mechanism.channels[0].expression == f"(rod.y + (({L} / 2) * sin(rod.angle)))"
    res = s.simulate()
    tip = res.point("rod", (L / 2, 0.0))[:, 1]          # the rod's frame is at its centre
    np.testing.assert_allclose(res.channel("tip_y"), tip, rtol=0, atol=1e-12)
    again = tmp_path / "again.toml"
    s.mechanism.save(again)
    loaded = ms.load_mechanism(again).channels[0]
    names = ms.model.channels.channel_names(s.mechanism)
    state = {"rod.y": -0.3, "rod.angle": -1.1}
    assert loaded.parsed(names).value(**state) == pytest.approx(
        s.mechanism.channels[0].parsed(names).value(**state), rel=1e-15)
    assert (loaded.name, loaded.unit) == ("tip_y", "m")


def test_bad_channels_are_refused_naming_them():
    mech = pendulum()
    with pytest.raises(ms.ModelError, match=r"channel 'c'.*unknown name 'rod\.speed'"):
        mech.add(ms.Channel("c", "rod.speed"))
    with pytest.raises(ms.ModelError, match=r"channel 'c'.*unknown name 'crank\.angle'"):
        mech.add(ms.Channel("c", "crank.angle"))
    with pytest.raises(ms.ModelError, match=r"channel 'c'.*unknown name 'rod.angle.__class__'"):
        mech.add(ms.Channel("c", "rod.angle.__class__"))
    with pytest.raises(ms.ModelError, match=r"channel 'c'.*unsupported syntax 't.real'"):
        mech.add(ms.Channel("c", "t.real"))
    with pytest.raises(ms.ModelError, match=r"channel 'c': `unit`"):
        ms.Channel("c", "t", unit="[m]")
    with pytest.raises(ms.ModelError, match=r"channel: `name`"):
        ms.Channel("", "t")
    with pytest.raises(ms.ModelError, match=r"channel 'c': `expression`"):
        ms.Channel("c", lambda r: r.t)
    mech.add(ms.Channel("c", "t"))
    with pytest.raises(ms.ModelError, match=r"a channel named 'c' exists already"):
        mech.add(ms.Channel("c", "2*t"))
    with pytest.raises(KeyError, match=r"no channel 'd'; channels: c"):
        mech.simulate(0.01).channel("d")


def test_a_channel_changes_no_equation():
    """Adding a channel keeps the built problem (nothing is rebuilt for it)."""
    mech = pendulum()
    problem = mech.problem()
    mech.add(ms.Channel("c", "t"))
    assert mech.problem() is problem
    assert math.isclose(mech.simulate(0.1, output_step=0.05).channel("c")[-1], 0.1)
