"""Initial speeds users can give: joint rates (Mechanism.set_speed) taken exactly, and a
warning where assembly has to change a velocity the user gave."""


import numpy as np
import pytest

import mechsim as ms
from mechsim.examples import four_bar_angles, general_four_bar


def spinning_rod(omega=20.0, m=1.0, L=1.0):
    mech = ms.Mechanism("spinning rod", gravity=(0.0, 0.0))
    rod = mech.add(ms.RigidBody.rod("rod", (0, 0), (L, 0), m, angular_velocity=omega))
    pin = mech.add(ms.Revolute(mech.ground, rod, at=(0, 0), name="pin"))
    return mech, pin


def test_a_body_velocity_that_does_not_fit_its_joint_is_changed_with_a_warning():
    """Given ω but not its centre's velocity, the rod pinned at its end gets the nearest
    consistent motion in the mass metric, ω I / (I + m (L/2)²) = ω/4, and the user is told."""
    mech, _ = spinning_rod()
    with pytest.warns(UserWarning, match=r"'rod.angle' from 20 to 5: .*set_speed"):
        report = mech.assemble()
    np.testing.assert_allclose(report.v, [0.0, 2.5, 5.0], atol=1e-12)


def test_a_joint_rate_is_taken_exactly(recwarn):
    mech, pin = spinning_rod()
    mech.set_speed(pin, 20.0)
    res = mech.simulate(0.5, rtol=1e-10, atol=1e-12, output_step=0.1)
    assert not [w for w in recwarn if "changed the initial velocity" in str(w.message)]
    np.testing.assert_allclose(res.joint_rate(pin), 20.0, rtol=1e-12)
    np.testing.assert_allclose(res.v[0], [0.0, 10.0, 20.0], atol=1e-12)


def test_a_four_bar_starts_at_its_crank_speed(recwarn):
    a, b, c, d, th, w = 0.2, 0.6, 0.5, 0.7, 0.3, 8.0
    mech = general_four_bar(a, b, c, d, theta=th, speed=w)
    res = mech.simulate(0.01, rtol=1e-10, atol=1e-12, output_step=0.01)
    assert res.joint_rate("O2")[0] == pytest.approx(w, rel=1e-12)
    h = 1e-6                                    # the closed form's derivative in θ
    _, th4p = four_bar_angles(np.array(th + h), a, b, c, d, 1)
    _, th4m = four_bar_angles(np.array(th - h), a, b, c, d, 1)
    assert res.v[0, 8] == pytest.approx(w * (th4p - th4m) / (2 * h), rel=1e-8)
    assert not [w for w in recwarn if "changed the initial velocity" in str(w.message)]


def test_joint_rates_that_cannot_hold_are_refused():
    mech = general_four_bar(0.2, 0.6, 0.5, 0.7, theta=0.3)
    mech.set_speed("O2", 8.0)
    mech.set_speed("O4", 8.0)                   # one degree of freedom: not both
    with pytest.raises(ms.AssemblyError, match="cannot all hold"):
        mech.assemble()


@pytest.mark.parametrize("joint, rate, message", [
    ("nowhere", 1.0, "no joint 'nowhere'"),
    ("O2", float("nan"), "`rate` must be finite"),
    ("O2", "8", "`rate` must be a number"),
])
def test_set_speed_checks_its_arguments(joint, rate, message):
    mech = general_four_bar(0.2, 0.6, 0.5, 0.7, theta=0.3)
    with pytest.raises((ms.ModelError, KeyError), match=message):
        mech.set_speed(joint, rate)


def test_a_driven_joint_takes_its_rate_from_its_driver():
    mech = general_four_bar(0.2, 0.6, 0.5, 0.7, theta=0.3)
    mech.add(ms.Driver(mech.joint("O2"), "10*t"))
    with pytest.raises(ms.ModelError, match="driven"):
        mech.set_speed("O2", 3.0)
