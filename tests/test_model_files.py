"""A mechanism built in Python saved as a scene (TOML or JSON) and built again."""

import math

import numpy as np
import pytest

import mechsim as ms


def every_element():
    """A model with every element a scene holds: rigid bodies, a flexible beam, revolute
    joints at a point and by local points, a prismatic joint, a driver, a spring with its
    rest length and damping, a rotational spring, a constant force and torque, and a joint
    speed; names with quotes, backslashes, accents and a newline."""
    mech = ms.Mechanism('rig "test" \\ é\nline', gravity=(0.5, -9.81))
    crank = mech.add(ms.RigidBody.rod("crank", (0, 0), (0.2, 0.1), 1.2))
    beam = mech.add(ms.FlexibleBeam("beam", length=0.8, youngs_modulus=70e9, density=2700.0,
                                    area=2e-4, second_moment=1e-9, n_elements=6, n_modes=2,
                                    start=(0.2, 0.1), angle=-0.1, damping_ratio=0.01))
    block = mech.add(ms.RigidBody.rectangle("block", (1.0, -0.3), 0.1, 0.05, 0.5))
    arm = mech.add(ms.RigidBody.polygon("arm", [(1.0, -0.3), (1.3, -0.3), (1.1, 0.0)], 0.7))
    pivot = mech.add(ms.Revolute(mech.ground, crank, at=(0, 0), name="O"))
    mech.add(ms.Revolute(crank, beam, at=(0.2, 0.1), name="A"))
    mech.add(ms.Prismatic(mech.ground, block, axis=(1.0, 0.2), at=(1.0, -0.3), name="rail"))
    mech.add(ms.Revolute(block, arm, local_a=(0.0, 0.0),
                         local_b=np.array([1.0, -0.3]) - arm.position, name='pin "p"'))
    mech.add(ms.Spring(crank, block, at_a=(0.2, 0.1), at_b=(1.0, -0.3), stiffness=300.0,
                       rest_length=0.7, damping=2.0, name="link spring"))
    mech.add(ms.RotationalSpring(mech.ground, arm, stiffness=5.0, damping=0.1,
                                 rest_angle=0.05, name="arm spring"))
    mech.add(ms.Force(arm, (1.0, -2.0), at=(1.2, -0.2), name="push"))
    mech.add(ms.Torque(beam, 0.3, name="twist"))
    mech.set_speed(pivot, 2.0)
    return mech


@pytest.mark.parametrize("suffix", ["toml", "json"])
@pytest.mark.parametrize("make", [every_element, ms.examples.four_bar,
                                  lambda: ms.examples.slider_crank(driven=True,
                                                                   crank_speed=100.0)],
                         ids=["every element", "four-bar", "driven slider-crank"])
def test_a_saved_mechanism_builds_again_exactly(make, suffix, tmp_path):
    """The same structure, masses and initial state, and the same motion to the last bit."""
    mech = make()
    back = ms.load_mechanism(mech.save(tmp_path / f"model.{suffix}"))
    assert back.name == mech.name and back.structure() == mech.structure()
    np.testing.assert_array_equal(back.problem().mass_diagonal, mech.problem().mass_diagonal)
    assert back.speeds == mech.speeds
    a = mech.simulate(0.05, rtol=1e-9, output_step=0.01)
    b = back.simulate(0.05, rtol=1e-9, output_step=0.01)
    assert a.status == b.status == "success", (a.message, b.message)
    np.testing.assert_array_equal(a.q, b.q)
    np.testing.assert_array_equal(a.v, b.v)


def test_what_a_scene_cannot_hold_is_refused_naming_it(tmp_path):
    mech = ms.examples.pendulum()
    mech.add(ms.Torque(mech.body("rod"), lambda t: math.sin(t), name="motor"))
    with pytest.raises(ms.ModelError, match="torque 'motor' is a Python function"):
        mech.save(tmp_path / "m.toml")
    assert not (tmp_path / "m.toml").exists()
    bent = ms.Mechanism("bent")
    bent.add(ms.FlexibleBeam("b", length=1.0, youngs_modulus=1e9, density=1e3, area=1e-4,
                             second_moment=1e-8, eta=[1e-3, 0.0]))
    with pytest.raises(ms.ModelError, match="beam 'b' starts deformed"):
        bent.save(tmp_path / "b.json")
