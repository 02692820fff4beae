"""Sensitivities carried across impacts on stops (`mechsim.engineering.impact_sensitivity`):
against central differences of rebuilt mechanisms on the samples of the output grid, and
each impact's time sensitivity against the difference of the rebuilt runs' impact times;
where a joint comes to rest the sensitivities end, and the result says so."""

import math
import warnings

import numpy as np
import pytest

import mechsim as ms
from mechsim.problem.geometry import joint_gradient

G = 9.81


def pendulum(length=1.0, restitution=0.8):
    """A uniform rod pinned at its end, released horizontal onto a stop at −60°."""
    mech = ms.Mechanism("pendulum on a stop", gravity=(0.0, -G))
    rod = mech.add(ms.RigidBody.rod("rod", (0, 0), (length, 0.0), 1.0))
    pin = mech.add(ms.Revolute(mech.ground, rod, at=(0, 0), name="pin"))
    mech.add(ms.Stop(pin, lower=-math.pi / 3, restitution=restitution, name="stop"))
    return mech


def thrown_slider(k=30.0, slider_mass=0.5, arm_mass=1.0, w=2.0, driven=True):
    """A slider on a turning arm, tied to the pivot by a spring, thrown against the two
    ends of its slot (a prismatic stop whose coordinate turns with the arm; the slot 0.1 m
    off the pivot, so that its impulses turn the arm too); the arm
    driven by w t + 0.5 sin 3t (w = 2 rad/s), or free from 3.5 rad/s."""
    mech = ms.Mechanism("thrown slider", gravity=(0.0, -G))
    arm = mech.add(ms.RigidBody.rod("arm", (0, 0), (1.0, 0.0), arm_mass))
    pivot = mech.add(ms.Revolute(mech.ground, arm, at=(0, 0), name="pivot"))
    slider = mech.add(ms.RigidBody("slider", slider_mass, 0.01, (0.3, 0.1)))
    slot = mech.add(ms.Prismatic(arm, slider, axis=(1.0, 0.0), at=(0.3, 0.1), name="slot"))
    mech.add(ms.Stop(slot, lower=-0.2, upper=0.25, restitution=0.7, name="ends"))
    mech.add(ms.Spring(arm, slider, at_a=(0.0, 0.0), at_b=(0.3, 0.1), stiffness=k,
                       rest_length=0.3, name="tie"))
    mech.set_speed(slot, 0.6)
    if driven:
        mech.add(ms.Driver(pivot, "w*t + 0.5*sin(3*t)", values={"w": w}, name="motor"))
    else:
        mech.set_speed(pivot, 3.5)
    return mech


def on_grid(res, values, grid):
    """`values` (one row per sample of `res`) at the output grid's times (a run also
    samples each impact, at times that differ between the rebuilt mechanisms)."""
    rows = np.searchsorted(res.t, grid - 1e-12)
    np.testing.assert_allclose(res.t[rows], grid, atol=1e-12)
    return values[rows]


def check_against_differences(build, which, value, t_end, method="hybrid"):
    """q_k and v_k on the grid and every impact's dt/dk against central differences (step
    from the error balance of runs at rtol 1e-12); returns the run."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = build(ms.Parameter(which, value)).simulate(
            t_end, method=method, rtol=1e-10, atol=1e-12, output_step=0.01,
            sensitivities=[which])
        h = (3e-12) ** (1 / 3) * abs(value)
        plus, minus = (build(value + s * h).simulate(t_end, method=method, rtol=1e-12,
                                                     atol=1e-12, output_step=0.01)
                       for s in (1.0, -1.0))
    assert res.success, res.message
    assert len(res.impacts) >= 2 and len(plus.impacts) == len(res.impacts)
    grid = np.round(np.arange(0.0, t_end + 1e-9, 0.01), 10)
    for of, quantity in (("q", lambda r: r.q), ("v", lambda r: r.v)):
        reference = (on_grid(plus, quantity(plus), grid)
                     - on_grid(minus, quantity(minus), grid)) / (2 * h)
        got = on_grid(res, res.sensitivity(which, of=of), grid)
        assert np.max(np.abs(got - reference)) < 1e-5 * np.max(np.abs(reference)), of
    for impact, a, b in zip(res.impacts, plus.impacts, minus.impacts):
        assert impact.time_sensitivity[which] == pytest.approx((a.t - b.t) / (2 * h),
                                                               rel=1e-5, abs=1e-9)
    return res


@pytest.mark.parametrize("method", ["hybrid", "projection"])
def test_a_pendulum_bouncing_on_its_stop_agrees_with_finite_differences(method):
    """Three impacts in 2 s: the rod's length moves every impact's time (≈ 0.19, 0.53,
    0.82 s per metre) and the motion after it."""
    res = check_against_differences(lambda x: pendulum(length=x), "length", 1.0, 2.0,
                                    method)
    assert len(res.impacts) == 3
    assert res.impacts[0].time_sensitivity["length"] == pytest.approx(0.1922, abs=1e-3)


@pytest.mark.parametrize("which, driven", [("k", True), ("slider_mass", True),
                                           ("w", True), ("arm_mass", False)])
def test_a_slider_thrown_against_the_ends_of_a_turning_slot(which, driven):
    """A prismatic stop whose coordinate turns with the arm (its second derivatives enter
    the impact), a spring, and a driver (the constraint's time derivative enters the
    impact's time shift): the spring's stiffness, the slider's and the arm's mass, the
    driver's speed."""
    values = {"k": 30.0, "slider_mass": 0.5, "arm_mass": 1.0, "w": 2.0}
    check_against_differences(
        lambda x: thrown_slider(**{**values, which: x}, driven=driven), which,
        values[which], 2.0)


def test_a_pendulum_coming_to_rest_on_its_stop_keeps_its_sensitivities_there():
    """With e = 0.5 the pendulum rests on its stop after a few bounces: the resting impact
    is differentiated as a plastic one and the stop holds the pin still, so from then on
    the angle's sensitivity is zero (it rests at the limit whatever the length) and its
    centre's is (cos, sin)(−60°)/2; every impact's time has its sensitivity."""
    res = pendulum(length=ms.Parameter("length", 1.0), restitution=0.5).simulate(
        3.0, rtol=1e-9, atol=1e-11, output_step=0.01, sensitivities=["length"])
    assert res.success and "sensitivities end" not in res.message, res.message
    resting = next(i for i in res.impacts if i.resting)
    s = res.sensitivity("length")
    exact = [math.cos(-math.pi / 3) / 2, math.sin(-math.pi / 3) / 2, 0.0]
    assert np.max(np.abs(s[res.t > resting.t] - exact)) < 1e-9
    assert np.max(np.abs(s[res.t < resting.t, 2])) > 0.1
    assert all("length" in i.time_sensitivity for i in res.impacts)


def test_the_sensitivities_end_where_a_joint_is_pressed_onto_its_stop_at_rest():
    """Released at rest on its stop: no impact's time to differentiate; they end there,
    NaN after it, and the message says so."""
    mech = ms.Mechanism("pendulum at its stop", gravity=(0.0, -G))
    rod = mech.add(ms.RigidBody.rod("rod", (0, 0), (0.5, -0.5 * math.sqrt(3.0)),
                                    ms.Parameter("m", 1.0)))
    pin = mech.add(ms.Revolute(mech.ground, rod, at=(0, 0), name="pin"))
    mech.add(ms.Stop(pin, lower=-math.pi / 3, name="stop"))
    res = mech.simulate(0.2, rtol=1e-9, atol=1e-11, output_step=0.01, sensitivities=["m"])
    assert res.success, res.message
    assert "the sensitivities end at t = 0, where joint 'pin' was pressed onto stop " \
        "'stop' at rest" in res.message
    assert np.all(np.isnan(res.sensitivity("m")[1:]))


def test_an_extended_run_with_impacts_carries_its_sensitivities_on():
    """Extending a bouncing run (past its second impact) continues from its last
    sensitivities: equal to one run."""
    mech = pendulum(length=ms.Parameter("length", 1.0))
    kw = dict(rtol=1e-10, atol=1e-12, output_step=0.01, sensitivities=["length"])
    whole = mech.simulate(1.5, **kw)
    part = mech.simulate(0.7, **kw).extend(1.5)
    assert len(part.impacts) == len(whole.impacts) == 2
    np.testing.assert_allclose(part.sensitivity("length")[-1],
                               whole.sensitivity("length")[-1], rtol=1e-6, atol=1e-8)


def test_what_cannot_be_carried_across_impacts_is_refused_naming_it():
    tilted = ms.Mechanism("tilted slot", gravity=(0.0, -G))
    block = tilted.add(ms.RigidBody("block", 1.0, 0.01, (0.0, 0.0)))
    guide = tilted.add(ms.Prismatic(tilted.ground, block,
                                    axis=(1.0, ms.Parameter("tilt", -0.3)), at=(0.0, 0.0),
                                    name="guide"))
    tilted.add(ms.Stop(guide, lower=-0.5, name="end"))
    with pytest.raises(ValueError, match="joint 'guide', which stop 'end' limits, moves "
                                         "with Parameter 'tilt'"):
        tilted.simulate(1.0, sensitivities=["tilt"])


def test_the_initial_sensitivities_hold_the_rates_set_on_joints():
    """The start linearises the assembly itself: the slot's rate, given by `set_speed`,
    does not move with the driver's speed w, while the arm's rate w + 1.5 moves by 1."""
    mech = thrown_slider(w=ms.Parameter("w", 2.0))
    mech.stops.clear()
    res = mech.simulate(0.05, rtol=1e-10, atol=1e-12, output_step=0.01,
                        sensitivities=["w"])
    Sv = res.sensitivity("w", of="v")[0]
    q, problem = res.q[0], res.problem
    slot = joint_gradient(problem.joints["slot"], q) @ Sv
    pivot = joint_gradient(problem.joints["pivot"], q) @ Sv
    assert abs(slot) < 1e-12 and pivot == pytest.approx(1.0, abs=1e-12)
