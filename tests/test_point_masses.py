"""Point masses: bodies without rotational inertia, allowed where the joints keep them from
turning (a slider on its guide), refused naming them where they could turn."""

import numpy as np
import pytest

import mechsim as ms


def slider_crank(point: bool, driven: bool):
    """The seed's slider-crank, its slider a 2 cm block or a point mass of the same mass."""
    mech = ms.examples.slider_crank(driven=driven, crank_speed=100.0 if driven else 150.0)
    slider = mech.body("slider")
    if point:
        # The same body as `RigidBody.point_mass` builds (frame and state unchanged).
        twin = ms.RigidBody.point_mass("slider", slider.position, slider.mass,
                                       velocity=slider.velocity)
        assert twin.inertia == 0.0
        slider.inertia = twin.inertia
    return mech


@pytest.mark.parametrize("method", ["lu", "projection", "baumgarte"])
def test_a_point_slider_moves_as_a_block_does(method):
    """A slider that cannot turn: its inertia multiplies θ̈ = 0, so the free slider-crank
    moves the same with a point mass as with a block (to the integration tolerance), and
    the slider's angle stays at 0."""
    runs = [slider_crank(point, driven=False).simulate(0.1, method=method, rtol=1e-10,
                                                       atol=1e-12, output_step=1e-3)
            for point in (False, True)]
    block, point = runs
    assert block.success and point.success, (block.message, point.message)
    np.testing.assert_allclose(point.q, block.q, rtol=0, atol=1e-8)
    np.testing.assert_allclose(point.coordinate("slider.angle"), 0.0, rtol=0, atol=1e-12)
    assert np.ptp(point.coordinate("slider.x")) > 0.25        # it ran through its strokes
    energy = point.energy
    assert np.abs(energy.balance).max() < 1e-7 * np.abs(energy.total).max() + 1e-9


def test_a_point_slider_gives_the_blocks_reactions_and_effort():
    """Driven at 100 rad/s: the motor torque and the guide's couple equal the block's."""
    runs = [slider_crank(point, driven=True).kinematics(0.06, 1e-3) for point in (False, True)]
    block, point = runs
    np.testing.assert_allclose(point.driver_effort("driver(O)"),
                               block.driver_effort("driver(O)"), rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(point.joint_moment("slide"), block.joint_moment("slide"),
                               rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(point.joint_force("B"), block.joint_force("B"), rtol=1e-9,
                               atol=1e-9)
    assert np.abs(point.driver_effort("driver(O)")).max() > 1.0


def test_a_point_mass_on_a_cross_slide_is_held():
    """A point mass on a prismatic joint to a carriage that slides on the ground: both held."""
    mech = ms.Mechanism("cross slide", gravity=(0.0, -9.81))
    carriage = mech.add(ms.RigidBody.rectangle("carriage", (0, 0), 0.2, 0.05, 2.0))
    tool = mech.add(ms.RigidBody.point_mass("tool", (0, 0), 0.5))
    mech.add(ms.Prismatic(mech.ground, carriage, axis=(1, 0), at=(0, 0), name="x-way"))
    mech.add(ms.Prismatic(carriage, tool, axis=(0, 1), at=(0, 0), name="y-way"))
    res = mech.simulate(0.5, rtol=1e-10, atol=1e-12, output_step=0.1)
    # The tool falls freely along its vertical way: y = −g t²/2.
    np.testing.assert_allclose(res.coordinate("tool.y"), -9.81 * res.t**2 / 2, rtol=0,
                               atol=1e-9)


def test_a_point_mass_that_could_turn_is_refused_naming_it():
    """A point mass pinned at its centre to a pendulum would turn freely with no inertia."""
    mech = ms.Mechanism("bob", gravity=(0.0, -9.81))
    rod = mech.add(ms.RigidBody.rod("rod", (0, 0), (1, 0), 1.0))
    bob = mech.add(ms.RigidBody.point_mass("bob", (1, 0), 0.3))
    mech.add(ms.Revolute(mech.ground, rod, at=(0, 0)))
    mech.add(ms.Revolute(rod, bob, at=(1, 0)))
    with pytest.raises(ms.ModelError, match=r"body 'bob' is a point mass \(inertia 0\) that "
                                            r"its joints do not keep from turning"):
        mech.simulate(0.1)
    with pytest.raises(ms.ModelError, match=r"`inertia` must be non-negative, got -1"):
        ms.RigidBody("b", 1.0, -1.0)
