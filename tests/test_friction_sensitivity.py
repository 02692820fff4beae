"""Sensitivities of motions whose joints are held or rub: through sliding, sticking,
breaking away and reversing under dry friction, and resting on a stop and leaving it,
against closed forms on an incline, exact invariances, and central differences (h from
the error balance of runs at rtol 1e-12) on a rubbing pendulum, a block riding a sprung
cart, a slider in a swinging arm's slot, a closed four-bar whose coupler pins rub, a
rubbing pendulum bouncing on a stop and a double pendulum resting on a stop."""

import math

import numpy as np
import pytest

import mechsim as ms

G = 9.81
RTOL = 1e-12


def at(res, times):
    """The indices of the samples of `res` at `times` (on the output grid; an event's
    sample falls between)."""
    rows = [int(np.argmin(np.abs(res.t - t))) for t in times]
    np.testing.assert_allclose(res.t[rows], times, atol=1e-12)
    return rows


def coordinates(*columns):
    """The quantity pair (sensitivity, value) of the coordinates `columns`."""
    columns = list(columns)
    return (lambda res, name: res.sensitivity(name)[:, columns], lambda res: res.q[:, columns])


def step(values, name):
    """The central differences' step in the parameter `name`."""
    return (3 * RTOL) ** (1 / 3) * abs(values[name])


def central(build, values, name, times, t_end, quantities):
    """[∂quantity/∂name at `times`], ∂(event times)/∂name by central differences of
    `build(**values)` runs (the events: impacts, then switches)."""
    h = step(values, name)
    runs = [build(**{**values, name: values[name] + s * h}).simulate(
        t_end, rtol=RTOL, atol=1e-14, output_step=0.05) for s in (1.0, -1.0)]
    changes = [(value(runs[0])[at(runs[0], times)] - value(runs[1])[at(runs[1], times)]) /
               (2 * h) for _, value in quantities]
    events = [[e.t for e in r.impacts + r.friction_switches] for r in runs]
    assert len(events[0]) == len(events[1])
    return changes, (np.array(events[0]) - np.array(events[1])) / (2 * h)


def check(build, values, names, times, t_end, *quantities, tol=1e-5):
    """The carried sensitivities of each quantity (a pair: the sensitivity from the
    result and the name, the value from a result) at `times` and of every event's time
    agree with central differences to `tol` relative (of the largest). An event's time
    is as accurate as the run (within 20 RTOL of it: the error ÷ rtol the runs keep), so
    its difference quotient carries up to 2 · 20 RTOL t / (2 h) besides (3.7e-7 for a
    switch at 0.27 s; seen 7e-8: more than 1e-5 of a small sensitivity)."""
    res = build(**values).simulate(t_end, rtol=1e-10, atol=1e-12, output_step=0.05,
                                   sensitivities=names)
    assert res.success, res.message
    for name in names:
        events = np.array([e.time_sensitivity[name]
                           for e in res.impacts + res.friction_switches])
        fds, fd_events = central(build, values, name, times, t_end, quantities)
        for (sensitivity, _), fd in zip(quantities, fds):
            exact = sensitivity(res, name)[at(res, times)]
            scale = max(np.max(np.abs(fd)), 1e-3)
            assert np.max(np.abs(exact - fd)) < tol * scale, (name, exact, fd)
        if events.size:
            scale = max(np.max(np.abs(fd_events)), 1e-3)
            located = 20 * RTOL * max(e.t for e in res.impacts + res.friction_switches) / \
                step(values, name)
            assert np.max(np.abs(events - fd_events)) < tol * scale + located, \
                (name, events, fd_events)
    return res


def incline(angle, mu, mu_static=None, speed=0.0, preload=0.0):
    """A 2 kg block on a guide falling at `angle` below the horizontal (its slide s grows
    downhill), moving downhill at `speed`; friction μ (N + preload) in the guide."""
    mech = ms.Mechanism("incline", gravity=(0.0, -G))
    down = (math.cos(angle), -math.sin(angle))
    block = mech.add(ms.RigidBody("block", mass=2.0, inertia=0.01, angle=-angle,
                                  velocity=(speed * down[0], speed * down[1])))
    guide = mech.add(ms.Prismatic(mech.ground, block, axis=down, at=(0, 0), name="guide"))
    mech.add(ms.Friction(guide, mu=mu, mu_static=mu_static, preload=preload, name="rub"))
    return mech, down


def slide(res, down, which):
    """The slide (or its sensitivity) along the guide."""
    q = res.sensitivity(which) if which else res.q
    return q[:, 0] * down[0] + q[:, 1] * down[1]


def test_a_sliding_block_s_sensitivities_are_the_closed_form_s():
    """m s̈ = m g sin α − μ (m g cos α + P): ∂s/∂μ = −(g cos α + P/m) t²/2, ∂s/∂P = −μ t²/2m."""
    angle, mu, preload = math.radians(30), 0.3, 1.5
    mech, down = incline(angle, ms.Parameter("mu", mu), 0.5,
                         preload=ms.Parameter("preload", preload))
    res = mech.simulate(1.0, rtol=1e-10, atol=1e-12, output_step=0.1,
                        sensitivities=["mu", "preload"])
    assert res.success and not res.friction_switches, res.message
    t = res.t
    np.testing.assert_allclose(slide(res, down, "mu"),
                               -(G * math.cos(angle) + preload / 2.0) * t**2 / 2, atol=1e-9)
    np.testing.assert_allclose(slide(res, down, "preload"), -mu * t**2 / 4.0, atol=1e-9)


def test_a_block_thrown_uphill_stops_where_the_closed_form_says_and_its_rest_moves_so():
    """Thrown up at v0, it stops at t_s = v0/a, a = g (sin α + μ cos α), and sticks (tan α
    < μ_s) at s = −v0²/2a: ∂t_s/∂μ = −v0 g cos α/a², ∂s/∂μ = v0² g cos α/2a² ever after,
    and μ_s moves nothing."""
    angle, mu, v0 = math.radians(20), 0.3, 2.0
    mech, down = incline(angle, ms.Parameter("mu", mu), ms.Parameter("mu_s", 0.5),
                         speed=-v0)
    res = mech.simulate(1.0, rtol=1e-10, atol=1e-12, output_step=0.1,
                        sensitivities=["mu", "mu_s"])
    assert res.success, res.message
    a = G * (math.sin(angle) + mu * math.cos(angle))
    (switch,) = res.friction_switches
    assert switch.after == "stuck" and switch.t == pytest.approx(v0 / a, abs=1e-10)
    assert switch.time_sensitivity["mu"] == pytest.approx(-v0 * G * math.cos(angle) / a**2,
                                                          rel=1e-8)
    assert switch.time_sensitivity["mu_s"] == 0.0
    after = res.t > switch.t
    np.testing.assert_allclose(slide(res, down, "mu")[after],
                               v0**2 * G * math.cos(angle) / (2 * a**2), rtol=1e-8)
    before = res.t < switch.t
    t = res.t[before]
    np.testing.assert_allclose(slide(res, down, "mu")[before],
                               G * math.cos(angle) * t**2 / 2, atol=1e-9)
    assert np.all(slide(res, down, "mu_s") == 0.0)


def rubbing_pendulum(mu=0.3, r=0.3, m=1.0, vt=None):
    """A rod pinned at its end, released level, friction μ r |F| in its pin (μ_s 1.4 μ;
    with `vt` the Stribeck curve)."""
    mech = ms.Mechanism("rubbing pendulum", gravity=(0.0, -G))
    rod = mech.add(ms.RigidBody.rod("rod", (0, 0), (1.0, 0), ms.Parameter("m", m)))
    pin = mech.add(ms.Revolute(mech.ground, rod, at=(0, 0), name="pin"))
    mu = ms.Parameter("mu", mu)
    mech.add(ms.Friction(pin, mu=mu, mu_static=1.4 * mu, radius=ms.Parameter("r", r),
                         transition_velocity=vt, name="bearing"))
    return mech


def test_a_rubbing_pendulum_s_swings_and_rest_agree_with_central_differences():
    """Through its reversals to where it sticks: the angle, its acceleration and the pin's
    force at samples between them and every reversal's instant, to μ and the pin's radius;
    its mass moves nothing (every force scales with it)."""
    res = check(rubbing_pendulum, dict(mu=0.3, r=0.3), ["mu", "r"],
                [0.4, 0.95, 1.5, 2.2, 2.65], 2.7, coordinates(2),
                (lambda res, name: res.sensitivity(name, of="joint_force", joint="pin"),
                 lambda res: res.joint_force("pin")),
                (lambda res, name: res.sensitivity(name, of="a")[:, 2],
                 lambda res: res.accelerations()[:, 2]))
    assert [s.after for s in res.friction_switches][-1] == "stuck"
    assert len(res.friction_switches) >= 3
    plain = rubbing_pendulum().simulate(2.7, rtol=1e-10, atol=1e-12, output_step=0.05,
                                        sensitivities=["m"])
    assert np.max(np.abs(plain.sensitivity("m"))) < 1e-12
    assert all(abs(s.time_sensitivity["m"]) < 1e-12 for s in plain.friction_switches)


def test_a_pin_s_stribeck_curve_agrees_with_central_differences():
    """The pendulum's pin with μ(ω) = μ + (μ_s − μ) exp(−(ω/0.5)²) through its first
    reversal: the curve's slope in the pin's rate enters."""
    check(rubbing_pendulum, dict(mu=0.3, r=0.3, vt=0.5), ["mu"], [0.3, 0.6, 0.9, 1.1], 1.1,
          coordinates(2))


def sprung_cart(mu=0.2, mu_s=0.3, k=50.0, mb=0.5, vt=None):
    """A 2 kg cart on a smooth rail, a spring k to the ground stretched 0.2 m, carrying a
    block mb on a guide with friction μ (μ_s at rest; with `vt` the Stribeck curve): the
    block rides, breaks away where the cart's acceleration needs more than μ_s g, slides,
    and sticks again."""
    mech = ms.Mechanism("sprung cart", gravity=(0.0, -G))
    cart = mech.add(ms.RigidBody("cart", mass=2.0, inertia=0.1, position=(0.2, 0.0)))
    block = mech.add(ms.RigidBody("block", mass=ms.Parameter("mb", mb), inertia=0.01,
                                  position=(0.2, 0.1)))
    mech.add(ms.Prismatic(mech.ground, cart, axis=(1, 0), at=(0.2, 0), name="rail"))
    top = mech.add(ms.Prismatic(cart, block, axis=(1, 0), at=(0.2, 0.1), name="top"))
    mech.add(ms.Spring(mech.ground, cart, (-1.0, 0.0), (0.2, 0.0),
                       stiffness=ms.Parameter("k", k), rest_length=1.0))
    mech.add(ms.Friction(top, mu=ms.Parameter("mu", mu),
                         mu_static=ms.Parameter("mu_s", mu_s), name="rub",
                         transition_velocity=None if vt is None else ms.Parameter("vt", vt)))
    return mech


def test_a_block_breaking_away_on_a_sprung_cart_agrees_with_central_differences():
    """Sticking and breaking away in turn (the break-away's time from μ_s L − |f| = 0,
    linearised with the reactions): the block's position and every switch's instant, to
    μ_s and the spring rate."""
    res = check(sprung_cart, dict(mu=0.2, mu_s=0.3, k=50.0, mb=0.5), ["mu_s", "k"],
                [0.3, 0.6, 1.0, 1.3], 1.35, coordinates(3))
    kinds = [(s.before, s.after) for s in res.friction_switches]
    assert ("stuck", "slipping backwards") in kinds and \
        ("slipping backwards", "stuck") in kinds and ("slipping forwards", "stuck") in kinds


# A study: the Stribeck curve's slope is checked on the pin above in the default suite.
@pytest.mark.slow
def test_a_block_on_a_sprung_cart_with_a_stribeck_curve_agrees_with_central_differences():
    """μ(ṡ) = μ + (μ_s − μ) exp(−(ṡ/v_t)²): its slope in the speed and the transition
    velocity's own derivative enter the sliding block's."""
    check(sprung_cart, dict(mu=0.2, mu_s=0.3, k=50.0, mb=0.5, vt=0.05), ["vt"],
          [0.3, 0.45, 0.6, 0.7], 0.7, coordinates(3))


def rubbing_four_bar(mu=0.1, m1=1.0):
    """A crank-rocker falling from a turning start, friction in the coupler's two pins
    (radius 0.02 m): their loads are reactions of the closed loop."""
    mech = ms.examples.general_four_bar(0.3, 1.0, 0.8, 1.0, theta=0.5, speed=3.0,
                                        masses=(ms.Parameter("m1", m1), 1.0, 1.5))
    mu = ms.Parameter("mu", mu)
    for joint in ("A", "B"):
        mech.add(ms.Friction(mech.joint(joint), mu=mu, mu_static=1.5 * mu, radius=0.02))
    return mech


def test_a_four_bar_with_friction_in_its_coupler_pins_agrees_with_central_differences():
    """The crank angle, the rocker's pivot force and the pins' reversals' instants
    (together, and the coupler–rocker pin alone) to μ and the crank's mass."""
    res = check(rubbing_four_bar, dict(mu=0.1, m1=1.0), ["mu", "m1"],
                [0.05, 0.15, 0.25, 0.35], 0.35, coordinates(2),
                (lambda res, name: res.sensitivity(name, of="joint_force", joint="O4"),
                 lambda res: res.joint_force("O4")))
    assert len(res.friction_switches) == 3


def rubbing_slot(k=30.0, mu=0.8, length=None):
    """A slider in a slot 0.1 m off a swinging arm's axis, tied to the pivot by a spring,
    friction μ (μ_s 1.0; 1.25 μ for a slider of `length`, whose centre is off its
    slot) in the slot: its load is the Coriolis and swing's reaction (or the couple on a
    short slider), and the slot's coordinate turns with the arm (the joint's curvature and
    third derivatives enter)."""
    mech = ms.Mechanism("rubbing slot", gravity=(0.0, -G))
    arm = mech.add(ms.RigidBody.rod("arm", (0, 0), (1.0, 0.0), 1.0))
    pivot = mech.add(ms.Revolute(mech.ground, arm, at=(0, 0), name="pivot"))
    # (the short slider's centre off its point: the couple's arm turns with it)
    slider = mech.add(ms.RigidBody("slider", 0.5, 0.01,
                                   (0.3, 0.1) if length is None else (0.33, 0.13)))
    slot = mech.add(ms.Prismatic(arm, slider, axis=(1.0, 0.0), at=(0.3, 0.1), name="slot"))
    mech.add(ms.Spring(arm, slider, at_a=(0.0, 0.0), at_b=(0.3, 0.1),
                       stiffness=ms.Parameter("k", k), rest_length=0.3, name="tie"))
    mu = ms.Parameter("mu", mu)
    if length is None:
        mech.add(ms.Friction(slot, mu=mu, mu_static=1.0, name="rub"))
    else:
        mech.add(ms.Friction(slot, mu=mu, mu_static=1.25 * mu, name="rub",
                             length=ms.Parameter("length", length)))
    mech.set_speed(slot, 0.6)
    mech.set_speed(pivot, 3.5)
    return mech


def test_a_slider_sticking_in_a_swinging_arm_s_slot_agrees_with_central_differences():
    res = check(rubbing_slot, dict(k=30.0, mu=0.8), ["mu"], [0.1, 0.25, 0.4, 0.5],
                0.5, coordinates(2, 3))
    assert [s.after for s in res.friction_switches] == \
        ["slipping backwards", "stuck", "slipping forwards"]


def test_a_short_slider_whose_load_is_its_couple_agrees_with_central_differences():
    """A slider 5 cm long in the swinging slot: its load is mostly 2|M|/ℓ (the couple
    about its point, its centre's arm turning with it), through sliding, sticking and
    breaking away, to the slider's length."""
    res = check(rubbing_slot, dict(k=30.0, mu=0.4, length=0.05), ["length"],
                [0.05, 0.25, 0.35, 0.45, 0.55], 0.55, coordinates(2, 3))
    assert [s.after for s in res.friction_switches][-2:] == ["stuck", "slipping forwards"]


def test_a_block_tipped_by_its_pull_slides_as_the_closed_form_says():
    """Pulled by F at a height h over a guide of length ℓ, its load is the couple's
    2 F h/ℓ (> m g) plus the preload P: s = (F − μ (2 F h/ℓ + P)) t²/2m, so ∂s/∂μ,
    ∂s/∂ℓ and ∂s/∂P in closed form."""
    force, h, length, mu, mass, preload = 30.0, 0.2, 0.1, 0.2, 2.0, 1.0
    mech = ms.Mechanism("tipped block", gravity=(0.0, -G))
    block = mech.add(ms.RigidBody("block", mass, 0.01, (0.0, 0.0)))
    guide = mech.add(ms.Prismatic(mech.ground, block, axis=(1, 0), at=(0, 0), name="guide"))
    mech.add(ms.Force(block, [force, 0.0], at=(0.0, h), name="pull"))
    mech.add(ms.Friction(guide, mu=ms.Parameter("mu", mu),
                         length=ms.Parameter("length", length),
                         preload=ms.Parameter("preload", preload), name="rub"))
    res = mech.simulate(0.5, rtol=1e-10, atol=1e-12, output_step=0.1,
                        sensitivities=["mu", "length", "preload"])
    assert res.success, res.message
    couple = 2 * force * h / length
    assert couple > mass * G
    half = res.t**2 / (2 * mass)
    np.testing.assert_allclose(res.q[:, 0], (force - mu * (couple + preload)) * half,
                               atol=1e-9)
    np.testing.assert_allclose(res.sensitivity("mu")[:, 0], -(couple + preload) * half,
                               atol=1e-9)
    np.testing.assert_allclose(res.sensitivity("length")[:, 0], mu * couple / length * half,
                               atol=1e-9)
    np.testing.assert_allclose(res.sensitivity("preload")[:, 0], -mu * half, atol=1e-9)


def bouncing_pendulum(length=1.0, mu=0.1):
    """A rod released level onto a stop at −60° (restitution 0.8), friction in its pin."""
    mech = ms.Mechanism("pendulum on a stop", gravity=(0.0, -G))
    rod = mech.add(ms.RigidBody.rod("rod", (0, 0), (ms.Parameter("length", length), 0.0),
                                    1.0))
    pin = mech.add(ms.Revolute(mech.ground, rod, at=(0, 0), name="pin"))
    mech.add(ms.Stop(pin, lower=-math.pi / 3, restitution=0.8, name="stop"))
    mech.add(ms.Friction(pin, mu=ms.Parameter("mu", mu), mu_static=0.3, radius=0.05,
                         name="bearing"))
    return mech


def test_impacts_and_reversals_of_a_rubbing_pendulum_agree_with_central_differences():
    res = check(bouncing_pendulum, dict(length=1.0, mu=0.1), ["length"],
                [0.3, 0.7, 1.1, 1.45], 1.5, coordinates(2))
    assert len(res.impacts) == 2 and len(res.friction_switches) == 2


def resting_double_pendulum(l1=1.0, l2=0.8, m2=1.0):
    """Two rods hanging from a pin with a plastic stop (e = 0) at −45°: the upper comes to
    rest on it, is lifted off at once by the lower's swing, rests again, is held while
    the lower swings, and let go where the stop would pull."""
    mech = ms.Mechanism("double pendulum on a stop", gravity=(0.0, -G))
    l1 = ms.Parameter("l1", l1)
    upper = mech.add(ms.RigidBody.rod("upper", (0, 0), (l1, 0.0), 1.0))
    pin = mech.add(ms.Revolute(mech.ground, upper, at=(0, 0), name="pin"))
    lower = mech.add(ms.RigidBody.rod("lower", (l1, 0.0), (l1 + ms.Parameter("l2", l2), 0.0),
                                      ms.Parameter("m2", m2)))
    mech.add(ms.Revolute(upper, lower, at=(l1, 0.0), name="knee"))
    mech.add(ms.Stop(pin, lower=-math.pi / 4, restitution=0.0, name="stop"))
    return mech


def test_a_double_pendulum_resting_on_its_stop_and_let_go_agrees_with_central_differences():
    """Through the resting impacts (plastic), the holds (the stop's force holding the pin
    still, linearised as a stuck joint's) and the releases (where the push reaches zero;
    or at once, moving with its impact): both angles and the impacts' instants."""
    res = check(resting_double_pendulum, dict(l1=1.0, l2=0.8, m2=1.0), ["l2"],
                [0.3, 0.45, 0.8, 1.5, 1.9], 1.95, coordinates(2, 5))
    assert [i.resting for i in res.impacts] == [True] * 3
    upper = res.coordinate("upper.angle")
    # (an impact's own sample holds the state before it)
    events = np.isin(res.t, [i.t for i in res.impacts])
    held = (np.abs(upper + math.pi / 4) < 1e-12) & ~events
    assert np.any(held[res.t < 1.3]) and np.any(held[res.t > 1.75])
    assert np.max(np.abs(res.sensitivity("l2")[held, 2])) < 1e-9


def test_what_friction_cannot_carry_is_refused_or_ended_and_said():
    upside_down = ms.Mechanism("guide on its block", gravity=(0.0, -G))
    block = upside_down.add(ms.RigidBody("block", 1.0, 0.01, (0.0, 0.0)))
    guide = upside_down.add(ms.Prismatic(block, upside_down.ground, axis=(1, 0), at=(0, 0)))
    upside_down.add(ms.Friction(guide, mu=ms.Parameter("mu", 0.2), length=0.1, name="rub"))
    with pytest.raises(ValueError, match="friction 'rub' with a `length` on a guide whose "
                                         "body_b is the ground"):
        upside_down.simulate(0.5, sensitivities=["mu"])
    tilted = ms.Mechanism("tilted guide", gravity=(0.0, -G))
    block = tilted.add(ms.RigidBody("block", 1.0, 0.01, (0.0, 0.0)))
    guide = tilted.add(ms.Prismatic(tilted.ground, block,
                                    axis=(1.0, ms.Parameter("tilt", -0.3)), at=(0.0, 0.0),
                                    name="guide"))
    tilted.add(ms.Friction(guide, mu=0.1, name="rub"))
    with pytest.raises(ValueError, match="joint 'guide', where friction 'rub' rubs, moves "
                                         "with Parameter 'tilt'"):
        tilted.simulate(0.5, sensitivities=["tilt"])
    # A block held on a level guide until a force growing in time breaks it away: the
    # break-away's instant depends on time explicitly, which is not differentiated.
    pushed = ms.Mechanism("pushed block", gravity=(0.0, -G))
    block = pushed.add(ms.RigidBody("block", ms.Parameter("m", 1.0), 0.01, (0.0, 0.0)))
    guide = pushed.add(ms.Prismatic(pushed.ground, block, axis=(1, 0), at=(0, 0)))
    pushed.add(ms.Force(block, ["10*t", "0"], at=(0.0, 0.0)))
    pushed.add(ms.Friction(guide, mu=0.2, mu_static=0.3, name="rub"))
    res = pushed.simulate(0.5, rtol=1e-10, atol=1e-12, output_step=0.05,
                          sensitivities=["m"])
    assert res.success and "the sensitivities end at t = 0.2943" in res.message
    later = res.t > 0.2943 + 1e-9
    assert np.all(np.isnan(res.sensitivity("m")[later]))
    assert np.all(np.isfinite(res.sensitivity("m")[~later]))
