"""Loads that vary in time, written as expressions in t (in Python and in scenes)."""

import numpy as np
import pytest

import mechsim as ms

L, M = 0.6, 1.5
I_O = M * L**2 / 3                     # a uniform rod about its end


def spinner(torque):
    """A rod pinned at one end, no gravity, driven by `torque` about the pin."""
    mech = ms.Mechanism("spinner", gravity=(0.0, 0.0))
    rod = mech.add(ms.RigidBody.rod("rod", (0, 0), (L, 0), M))
    mech.add(ms.Revolute(mech.ground, rod, at=(0, 0), name="pin"))
    mech.add(ms.Torque(rod, torque, name="motor"))
    return mech


def exact_angle(t):
    """I_O θ̈ = 2 sin 3t from rest: θ = (2 / I_O)(t/3 − sin(3t)/9)."""
    return 2.0 / I_O * (t / 3.0 - np.sin(3.0 * t) / 9.0)


def test_a_torque_in_t_turns_the_rod_as_the_closed_form_says():
    res = spinner("2*sin(3*t)").simulate(2.0, rtol=1e-10, atol=1e-12, output_step=0.01)
    assert res.success
    np.testing.assert_allclose(res.coordinate("rod.angle"), exact_angle(res.t), rtol=0,
                               atol=1e-8)
    assert res.coordinate("rod.angle")[-1] > 1.0


def test_a_force_in_t_pushes_a_slider_as_m_x_dd_equals_3t():
    mech = ms.Mechanism("push", gravity=(0.0, -9.81))
    block = mech.add(ms.RigidBody.point_mass("block", (0, 0), 2.0))
    mech.add(ms.Prismatic(mech.ground, block, axis=(1, 0), at=(0, 0), name="rail"))
    mech.add(ms.Force(block, ["3*t", 0.0], name="push"))
    res = mech.simulate(1.0, rtol=1e-10, atol=1e-12, output_step=0.1)
    np.testing.assert_allclose(res.coordinate("block.x"), res.t**3 / 4.0, rtol=0, atol=1e-10)


def test_loads_in_t_in_a_scene_bind_parameters_and_round_trip(tmp_path):
    scene = tmp_path / "spinner.toml"
    scene.write_text(f"""
gravity = [0.0, 0.0]
[parameters]
amplitude = 2.0
[[body]]
name = "rod"
rod = [[0, 0], [{L}, 0]]
mass = {M}
[[joint]]
type = "revolute"
name = "pin"
bodies = ["ground", "rod"]
at = [0, 0]
[[torque]]
name = "motor"
body = "rod"
torque = "amplitude*sin(3*t)"
[[force]]
name = "nothing"
body = "rod"
force = ["0*t", 0]
at = [{L}, 0]
[simulation]
t_end = 1.0
rtol = 1e-10
atol = 1e-12
output_step = 0.05
""", encoding="utf-8")
    s = ms.load_scene(scene)
    res = s.simulate()
    np.testing.assert_allclose(res.coordinate("rod.angle"), exact_angle(res.t), rtol=0,
                               atol=1e-8)
    back = ms.load_mechanism(s.mechanism.save(tmp_path / "again.toml"))
    torque = next(ld for ld in back.loads if ld.name == "motor").torque
    assert torque(0.5) == pytest.approx(2.0 * np.sin(1.5), rel=1e-15)
    again = back.simulate(1.0, rtol=1e-10, atol=1e-12, output_step=0.05)
    np.testing.assert_array_equal(again.q, res.q)


def test_a_load_expression_is_checked_before_any_work():
    with pytest.raises(ms.ModelError, match=r"torque 'motor' `torque`: unknown name 'x'"):
        spinner("2*sin(3*x)")
    with pytest.raises(ms.ModelError, match=r"torque 'motor' `torque`: unknown function '__import__'"):
        spinner("__import__('os')")
