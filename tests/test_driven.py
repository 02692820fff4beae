"""Fully driven mechanisms (0 degrees of freedom) follow their exact kinematics on the branch
they are assembled on, with every method, to an error that follows rtol.

A partitioned method has no independent coordinate to integrate here: it took one step for
the whole run and found every output sample by Newton from t = 0, landing on the mirror
branch (the crank-rocker's rocker at −490°, the driven slider-crank's slider 0.6 m off)
with status "success". Such runs are now followed by the projection method (a switch at
the start says so)."""

import math

import numpy as np
import pytest

import mechsim as ms
from mechsim.examples import four_bar_angles, slider_crank_position
from mechsim.formulations import METHODS

RTOLS = (1e-6, 1e-8, 1e-10, 1e-12)
# Baumgarte's and the fixed-step method's accuracy is not set by rtol.
METHOD_NAMES = sorted(m for m in METHODS if m != "ss-newmark")


def crank_rocker(a=0.2, b=0.6, c=0.5, d=0.7, th0=0.3, omega=10.0, branch=1):
    """A Grashof crank-rocker (s + l = 0.9 < p + q = 1.1) whose crank is driven at omega."""
    mech = ms.Mechanism("crank-rocker")
    _, th4 = four_bar_angles(np.array(th0), a, b, c, d, branch)
    tip = (a * math.cos(th0), a * math.sin(th0))
    joint = (d + c * math.cos(th4), c * math.sin(th4))
    crank = mech.add(ms.RigidBody.rod("crank", (0, 0), tip, 1.0))
    coupler = mech.add(ms.RigidBody.rod("coupler", tip, joint, 1.0))
    rocker = mech.add(ms.RigidBody.rod("rocker", (d, 0), joint, 1.0))
    pin = mech.add(ms.Revolute(mech.ground, crank, at=(0, 0), name="O2"))
    mech.add(ms.Revolute(crank, coupler, at=tip, name="A"))
    mech.add(ms.Revolute(coupler, rocker, at=joint, name="B"))
    mech.add(ms.Revolute(mech.ground, rocker, at=(d, 0), name="O4"))
    mech.add(ms.Driver(pin, f"{omega!r}*t"))
    return mech


def _errors(method, run, exact):
    errors = []
    for rtol in RTOLS:
        res = run(method, rtol)
        assert res.status == "success", res.message
        errors.append(exact(res))
    return errors


def _follows_rtol(errors, factor=20.0):
    """Each error within `factor` rtol, and falling as rtol falls (by 3× for each 100×
    at least, down to round-off: the local tolerance falls 10× for each 100× of rtol
    between 1e-6 and 1e-9, `Tolerances.local`). Round-off: the driven slider-crank's
    slider, 0.1 s at 150 rad/s, errs 1.05e-11 at rtol 1e-8 with the Haswell BLAS kernel
    (its error at 1e-6 happens to be 1e-15)."""
    for rtol, err in zip(RTOLS, errors):
        assert err < factor * rtol + 1e-12, (rtol, err)
    for coarse, fine in zip(errors, errors[1:]):
        assert fine < max(coarse / 3, 3e-11), errors


@pytest.mark.parametrize("method", METHOD_NAMES)
def test_a_driven_crank_rocker_follows_its_exact_kinematics(method):
    a, b, c, d, th0, w = 0.2, 0.6, 0.5, 0.7, 0.3, 10.0
    mech = crank_rocker()

    def run(method, rtol):
        return mech.simulate(2.0, method=method, rtol=rtol, atol=1e-2 * rtol, output_step=0.01)

    def exact(res):
        th3, th4 = four_bar_angles(th0 + w * res.t, a, b, c, d, 1)
        rocker = np.unwrap(res.coordinate("rocker.angle"))
        assert 95.0 < np.degrees(rocker.min()) and np.degrees(rocker.max()) < 150.0
        return max(np.max(np.abs(rocker - np.unwrap(th4))),
                   np.max(np.abs(np.unwrap(res.coordinate("coupler.angle")) - np.unwrap(th3))))

    _follows_rtol(_errors(method, run, exact))


@pytest.mark.parametrize("method", METHOD_NAMES)
def test_a_driven_slider_crank_follows_its_exact_kinematics(method):
    mech = ms.examples.slider_crank(driven=True)

    def run(method, rtol):
        return mech.simulate(0.1, method=method, rtol=rtol, atol=1e-2 * rtol, output_step=1e-3)

    def exact(res):
        x = res.coordinate("slider.x")
        xdot = res.v[:, res.coordinate_names.index("slider.x")]
        th = 150.0 * res.t
        r, l = 0.15, 0.30
        root = np.sqrt(l * l - (r * np.sin(th)) ** 2)
        xdot_exact = -150.0 * r * np.sin(th) * (1 + r * np.cos(th) / root)
        return max(np.max(np.abs(x - slider_crank_position(th))),
                   np.max(np.abs(xdot - xdot_exact)) / 150.0)

    _follows_rtol(_errors(method, run, exact))


def test_a_driven_slider_crank_has_its_exact_accelerations():
    """Kinematic analysis: the slider's acceleration at every sample (`accelerations()`,
    from the equations of motion at the sample) against d²x/dt² of the exact kinematics,
    −ω² (c + c²/ρ + s² (c² − ρ²)/ρ³), s = r sin θ, c = r cos θ, ρ = √(l² − s²)."""
    res = ms.examples.slider_crank(driven=True).simulate(0.1, rtol=1e-10, atol=1e-12,
                                                          output_step=1e-3)
    th, r, l, w = 150.0 * res.t, 0.15, 0.30, 150.0
    s, c = r * np.sin(th), r * np.cos(th)
    root = np.sqrt(l * l - s * s)
    exact = -w * w * (c + c * c / root + s * s * (c * c - root * root) / root**3)
    xdd = res.accelerations()[:, res.coordinate_names.index("slider.x")]
    assert np.max(np.abs(xdd - exact)) < 1e-8 * np.max(np.abs(exact))


def driven_change_point_four_bar():
    mech = ms.examples.four_bar()
    mech.add(ms.Driver(mech.joint("A"), "-2*t"))
    return mech


def test_baumgarte_stops_at_a_driven_dead_centre_saying_so():
    """Baumgarte's method solves the full constrained system, singular where the driven
    parallelogram's bars align (at t = (10° + kπ) / 2 rad/s): it stops at one of them,
    saying so, with the samples before it. Which one is round-off: with Haswell kernels
    the first (0.087 s), with Sandybridge's it slipped through that and stopped at the
    second (1.658 s)."""
    th0 = math.radians(10.0)
    res = driven_change_point_four_bar().simulate(3.0, method="baumgarte", rtol=1e-8,
                                                  atol=1e-10, output_step=0.01)
    assert res.status == "failed" and "nearly singular" in res.message
    centres = [(th0 + k * math.pi) / 2.0 for k in range(2)]
    assert any(c - 0.011 < res.t[-1] <= c for c in centres), res.t[-1]   # the sample before


@pytest.mark.parametrize("method", [m for m in METHOD_NAMES if m != "baumgarte"])
def test_a_driven_change_point_four_bar_crosses_its_dead_centres(method):
    """The parallelogram of `four_bar()` (a change-point four-bar: all bars align twice a
    turn) with its crank driven at −2 rad/s stays a parallelogram (rocker angle = crank
    angle) through both aligned positions, which are reported as singular passages."""
    mech = driven_change_point_four_bar()
    th0 = math.radians(10.0)
    res = mech.simulate(3.0, method=method, rtol=1e-8, atol=1e-10, output_step=0.01)
    assert res.status == "success", res.message
    assert np.max(np.abs(res.coordinate("rocker.angle") - (th0 - 2.0 * res.t))) < 1e-6
    expected = [(th0 + k * math.pi) / 2.0 for k in range(2)]
    found = sorted(p.t_min for p in res.singular_passages)
    assert len(found) == 2 and np.allclose(found, expected, atol=2e-3), found
    # The passage is a real event for a driven mechanism: the run says what it means.
    assert "drivers carried the mechanism through 2 singular configuration(s)" in res.message
    assert "driver efforts are not unique" in res.message
    # The driver's work balances the kinetic energy it gives and takes (uniform rotation of
    # a parallelogram at -2 rad/s in gravity: the driver does the work against gravity).
    assert np.max(np.abs(res.energy_drift)) < 1e-7


def test_the_switch_says_why_a_partitioned_method_did_not_partition():
    res = crank_rocker().simulate(0.1, method="lu")
    (switch,) = res.switches
    assert (switch.from_method, switch.to_method) == ("lu", "projection")
    assert "0 degrees of freedom" in switch.reason


def driven_pendulum(law):
    mech = ms.Mechanism("pendulum")
    rod = mech.add(ms.RigidBody.rod("rod", (0, 0), (1, 0), 1.0))
    mech.add(ms.Driver(mech.add(ms.Revolute(mech.ground, rod, at=(0, 0), name="O")), law,
                       name="motor"))
    return mech


RUNAWAY_LAWS = {"1/(t-0.1)": lambda t: 1 / (t - 0.1), "tan(20*t)": lambda t: np.tan(20 * t),
                "exp(1000*t)": lambda t: np.exp(1000 * t)}


@pytest.mark.parametrize("law, limit", [("1/(t-0.1)", 0.1), ("tan(20*t)", math.pi / 40),
                                        ("exp(1000*t)", 0.2)])
def test_a_motion_that_runs_away_ends_the_run_naming_its_driver(law, limit):
    """A driver with a pole (1/(t − 0.1), tan 20t) or one growing as exp(1000 t) demands
    ever faster turns: the steps shrink without end (1/(t − 0.1) once ran for 80 minutes,
    and reached the stall rule after 270 000 steps). The run stops where the trend of its
    steps shows t_end out of reach (1250 steps on every BLAS kernel tried), failed, with its
    samples, naming the driver and the fastest coordinate."""
    res = driven_pendulum(law).simulate(0.2, rtol=1e-6, atol=1e-8)
    assert res.status == "failed" and "the motion runs away" in res.message, res.message
    assert f"driver 'motor' prescribes {law}" in res.message and "fastest: rod." in res.message
    assert res.t[-1] < limit and res.t.size > 100
    exact = RUNAWAY_LAWS[law](res.t)                  # the samples before it, on the law
    np.testing.assert_allclose(res.coordinate("rod.angle"), exact, rtol=1e-5, atol=1e-8)


def test_a_segment_s_steps_are_kept_as_one_by_one():
    """The runaway rule keeps a segment's steps (`note_speeds`, array slices between its
    thinnings) exactly as one `note_speed` a step keeps them: the same rows, count and
    stride, over random chunks, keeps and single steps between them."""
    from mechsim.run.runaway import Runaway
    rng = np.random.default_rng(1)
    for _ in range(100):
        one, sliced = Runaway(), Runaway()
        one.keep = sliced.keep = int(rng.integers(4, 40))
        one.rows, sliced.rows = np.empty((one.keep + 1, 3)), np.empty((one.keep + 1, 3))
        j = 1
        for _ in range(int(rng.integers(1, 30))):
            k = int(rng.integers(0, 60))
            hs, speeds = rng.random(k), rng.random(k)
            for i in range(k):
                one.note_speed(j + i, hs[i], speeds[i])
            sliced.note_speeds(j, hs, speeds)
            j += k
            v, h = rng.random(3), rng.random()
            one.note(j, h, v)
            sliced.note(j, h, v)
            j += 1
        assert (one.count, one.stride) == (sliced.count, sliced.stride)
        assert one.rows[:one.count].tobytes() == sliced.rows[:sliced.count].tobytes()


@pytest.mark.parametrize("law", ["20*t**3", "3*exp(2*t)"])
def test_a_motion_that_speeds_up_within_reach_runs_to_the_end(law):
    """A crank driven ever faster, but with an end in reach (60 t² rad/s up to 540 rad/s;
    6 e^(2t) up to 2400 rad/s over 3 s): the run goes to t_end on the driver's law."""
    res = driven_pendulum(law).simulate(3.0, rtol=1e-8, atol=1e-10, output_step=0.01)
    assert res.status == "success", res.message
    exact = 20 * res.t ** 3 if law == "20*t**3" else 3 * np.exp(2 * res.t)
    np.testing.assert_allclose(res.coordinate("rod.angle"), exact, rtol=1e-10, atol=1e-10)
