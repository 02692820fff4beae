"""Joint friction loaded by the joint's own reaction: sliding and sticking on an incline, a
driven crank's extra motor torque, the friction oscillator of the shooting paper built as a
mechanism, a slider-crank with friction in every joint, against closed forms, the
oscillator module and independent integrations."""

import math
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import solve_ivp

import mechsim as ms
from mechsim.shooting.oscillators import CoulombOscillator

ROOT = Path(__file__).resolve().parents[1]

G = 9.81


def incline(angle, mu, mu_static=None, speed=0.0, method_kw=None, **friction):
    """A 2 kg block on a guide falling at `angle` below the horizontal (its slide s grows
    downhill), moving downhill at `speed`."""
    mech = ms.Mechanism("incline", gravity=(0.0, -G))
    down = (math.cos(angle), -math.sin(angle))
    block = mech.add(ms.RigidBody("block", mass=2.0, inertia=0.01, angle=-angle,
                                  velocity=(speed * down[0], speed * down[1])))
    guide = mech.add(ms.Prismatic(mech.ground, block, axis=down, at=(0, 0), name="guide"))
    mech.add(ms.Friction(guide, mu=mu, mu_static=mu_static, length=0.1, name="rub",
                         **friction))
    return mech, guide


@pytest.mark.parametrize("method", ["hybrid", "lu", "projection"])
def test_a_block_slides_down_an_incline_steeper_than_its_friction(method):
    angle, mu = math.radians(30), 0.3                      # tan 30° = 0.577 > μ_s = 0.5
    mech, guide = incline(angle, mu, 0.5)
    res = mech.simulate(1.0, method=method, rtol=1e-10, atol=1e-12, output_step=0.05)
    assert res.success, res.message
    a = G * (math.sin(angle) - mu * math.cos(angle))
    assert np.max(np.abs(res.joint_coordinate(guide) - 0.5 * a * res.t**2)) < 1e-8
    # friction μ N opposes the slide, N = m g cos θ is the guide's normal force
    normal = np.hypot(*res.joint_force(guide).T)
    assert np.allclose(normal, 2.0 * G * math.cos(angle), rtol=1e-10)
    assert np.allclose(res.friction_force("rub"), -mu * normal, rtol=1e-10)
    assert not res.friction_switches
    assert np.max(np.abs(res.energy_drift)) < 1e-8          # friction's work in the balance


def test_a_block_sticks_on_an_incline_flatter_than_its_static_friction():
    angle = math.radians(20)                                # tan 20° = 0.364 < μ_s = 0.4
    mech, guide = incline(angle, 0.3, 0.4)
    res = mech.simulate(1.0, rtol=1e-10, atol=1e-12, output_step=0.1)
    assert res.success, res.message
    assert np.max(np.abs(res.joint_coordinate(guide))) < 1e-12
    # what holds it is gravity's pull along the guide, within μ_s N
    assert np.allclose(res.friction_force("rub"), -2.0 * G * math.sin(angle), rtol=1e-9)


def test_a_sliding_block_stops_where_its_friction_brings_it_to_rest_and_sticks():
    angle, mu, speed = math.radians(10), 0.3, 1.0
    mech, guide = incline(angle, mu, 0.4, speed=speed)
    res = mech.simulate(1.5, rtol=1e-10, atol=1e-12, output_step=0.05)
    assert res.success, res.message
    a = G * (math.sin(angle) - mu * math.cos(angle))        # < 0: it slows down
    t_stop = -speed / a
    (switch,) = res.friction_switches
    assert (switch.before, switch.after) == ("slipping forwards", "stuck")
    assert switch.t == pytest.approx(t_stop, abs=1e-10)
    assert switch.force == pytest.approx(-2.0 * G * math.sin(angle), rel=1e-9)
    assert switch.limit == pytest.approx(0.4 * 2.0 * G * math.cos(angle), rel=1e-9)
    s = res.joint_coordinate(guide)
    exact = np.where(res.t < t_stop, speed * res.t + 0.5 * a * res.t**2, -speed**2 / (2 * a))
    assert np.max(np.abs(s - exact)) < 1e-9
    assert np.max(np.abs(res.joint_rate(guide)[res.t > t_stop])) < 1e-12
    # the kinetic energy went into the friction's work
    work = res.energy.work_by[:, res.energy.channels.index("friction 'rub'")]
    assert work[-1] == pytest.approx(-(0.5 * 2.0 * speed**2 + 2.0 * G * math.sin(angle) *
                                       speed**2 / (2 * -a)), rel=1e-9)


def test_the_stribeck_curve_slows_a_block_as_an_independent_integration_says():
    mu, mu_s, vt, speed = 0.2, 0.5, 0.3, 2.0
    mech, guide = incline(0.0, mu, mu_s, speed=speed, transition_velocity=vt)
    res = mech.simulate(0.5, rtol=1e-10, atol=1e-12, output_step=0.05)
    assert res.success, res.message

    def slowing(t, y):
        return [y[1], -(mu + (mu_s - mu) * math.exp(-(y[1] / vt) ** 2)) * G]
    ref = solve_ivp(slowing, (0, 0.5), [0.0, speed], method="DOP853", rtol=1e-12,
                    atol=1e-14, t_eval=res.t)
    assert np.max(np.abs(res.joint_coordinate(guide) - ref.y[0])) < 1e-8


def test_a_pin_with_friction_adds_mu_r_F_to_the_motor_torque():
    """Friction in a driven crank's pin O: the motor delivers μ r |F_O| more (the pin force
    itself is unchanged: the crank's motion is prescribed), in kinematics and dynamics."""
    mu, r, preload = 0.1, 0.01, 50.0
    plain = ms.examples.slider_crank(driven=True, crank_speed=100.0)
    rubbing = ms.examples.slider_crank(driven=True, crank_speed=100.0)
    pin = rubbing.joints[0]
    rubbing.add(ms.Friction(pin, mu=mu, radius=r, preload=preload, name="bearing"))
    period = 2 * math.pi / 100
    for run in ("kinematics", "simulate"):
        if run == "kinematics":
            a, b = (m.kinematics(period, period / 100) for m in (plain, rubbing))
        else:
            a, b = (m.simulate(period, rtol=1e-10, atol=1e-12, output_step=period / 100)
                    for m in (plain, rubbing))
        force = np.hypot(*b.joint_force(pin).T)
        assert np.allclose(force, np.hypot(*a.joint_force(plain.joints[0]).T), rtol=1e-9)
        extra = b.driver_effort(rubbing.drivers[0]) - a.driver_effort(plain.drivers[0])
        assert np.max(np.abs(extra - mu * r * (force + preload))) < 1e-9 * np.max(force)
        assert np.allclose(b.friction_force("bearing"), -extra, atol=1e-9 * np.max(force))


def test_a_slider_crank_with_friction_in_every_joint_balances_its_motor_energy():
    """Driven at constant speed through a revolution: the motor's work equals the change of
    kinetic and potential energy plus the work the friction took, to 100 rtol; each joint
    whose rate reverses (the rod–slider pin at 90° and 270°, the slide at 180°) switches."""
    mech = ms.examples.slider_crank(driven=True, crank_speed=100.0)
    for j in mech.joints:
        size = {"radius": 0.01} if j.kind == "revolute" else {"length": 0.02}
        mech.add(ms.Friction(j, mu=0.15, **size))
    period, rtol = 2 * math.pi / 100, 1e-8
    res = mech.simulate(period, rtol=rtol, atol=1e-10, output_step=period / 200)
    assert res.success, res.message
    assert np.max(np.abs(res.energy_drift)) < 100 * rtol
    switched = sorted((s.friction, round(s.t / period, 6)) for s in res.friction_switches)
    assert switched == [("friction(B)", 0.25), ("friction(B)", 0.75),
                        ("friction(slide)", 0.5)]
    for fr in mech.frictions:          # every joint's friction resists (but at its reversal,
        power = res.friction_force(fr) * res.joint_rate(fr.joint)   # located to 1e-13 s)
        assert np.all(power <= 1e-9 * np.max(np.abs(power))), (fr.name, power.max())
    friction_work = sum(res.energy.work_by[-1, i] for i, c in enumerate(res.energy.channels)
                        if c.startswith("friction"))
    assert friction_work < -0.01 * res.energy.work_by[-1, -1]     # it took a real share


PAPER = dict(zeta=0.05, omega_n=100.0, delta_st=0.1, omega=100.0)


def friction_oscillator(x0, v0, mu=0.08):
    """Eq. 10 of the shooting paper as a mechanism: a 1 kg block on a guide, a spring
    k = ω_n², a damper 2ζω_n, the force k δ_st cos ωt, friction μ with the guide's normal
    force m g (g = 9800, the paper's mm/s²)."""
    mech = ms.Mechanism("friction oscillator", gravity=(0.0, -9800.0))
    block = mech.add(ms.RigidBody("block", mass=1.0, inertia=1e-4, position=(x0, 0),
                                  velocity=(v0, 0)))
    guide = mech.add(ms.Prismatic(mech.ground, block, axis=(1, 0), at=(x0, 0)))
    mech.add(ms.Spring(mech.ground, block, at_a=(-1.0, 0), at_b=(x0, 0), stiffness=1e4,
                       damping=10.0, rest_length=1.0))
    mech.add(ms.Force(block, ["1000*cos(100*t)", "0"], at=(x0, 0)))
    mech.add(ms.Friction(guide, mu=mu, name="rub"))
    return mech


def test_the_friction_oscillator_built_as_a_mechanism_has_the_oscillator_modules_orbit():
    osc = CoulombOscillator(**PAPER, mu=0.08)
    sol = ms.shooting.solve(osc, (-0.014, 2.7), method="newton", tol=1e-12)
    assert sol.converged
    period = 2 * math.pi / 100
    res = friction_oscillator(*sol.x0).simulate(period, rtol=1e-10, atol=1e-12,
                                                output_step=period / 20)
    assert res.success, res.message
    # the stick and slip instants of the closed-form flow
    expected = [t for t, kind in sol.trajectory.events if kind in ("stick", "slip")]
    switches = [s.t for s in res.friction_switches]
    assert np.max(np.abs(np.array(switches) - expected)) < 1e-9
    # the motion at the grid's samples, against the module's exact flow to that time
    grid = np.flatnonzero(np.isclose(np.round(res.t / (period / 20)) * period / 20, res.t,
                                     rtol=0, atol=1e-15))
    for t, x, v in zip(res.t[grid[1::3]], res.q[grid[1::3], 0], res.v[grid[1::3], 0]):
        exact = osc.flow_with_monodromy(sol.x0, (0.0, t))[0].x[-1]
        assert abs(x - exact[0]) < 1e-9 and abs(v - exact[1]) < 1e-7, t
    # shooting on the mechanism itself finds the same orbit
    found = friction_oscillator(-0.014, 2.7).steady_state(period, tol=1e-10)
    assert found.converged
    assert np.allclose(found.x0, sol.x0, atol=1e-8)


@pytest.mark.parametrize("bad, message", [
    (dict(mu=-0.1), "`mu` must be non-negative"),
    (dict(mu=0.3, mu_static=0.2), "must not be below `mu`"),
    (dict(mu=0.3, transition_velocity=0.0), "`transition_velocity` must be positive"),
    (dict(mu=0.3, preload=-1.0), "`preload` must be non-negative"),
    (dict(mu=0.3), "needs the pin's `radius`"),
    (dict(mu=0.3, radius=0.01, length=0.1), "takes `radius`"),
])
def test_bad_friction_is_refused_naming_it(bad, message):
    mech = ms.examples.pendulum()
    with pytest.raises(ms.ModelError, match=message):
        ms.Friction(mech.joints[0], **bad)


def test_friction_needs_a_joint_of_the_mechanism_with_a_coordinate_once():
    mech = ms.examples.pendulum()
    pin = mech.joints[0]
    mech.add(ms.Friction(pin, mu=0.1, radius=0.01))
    with pytest.raises(ms.ModelError, match="has friction already"):
        mech.add(ms.Friction(pin, mu=0.2, radius=0.01))
    other = ms.examples.pendulum()
    with pytest.raises(ms.ModelError, match="is not in"):
        other.add(ms.Friction(pin, mu=0.1, radius=0.01))
    mech2, guide = incline(0.1, 0.1)
    with pytest.raises(ms.ModelError, match="takes `length`"):
        ms.Friction(guide, mu=0.1, radius=0.01)


def test_a_pendulum_with_pin_friction_swings_as_its_implicit_equation_says_then_sticks():
    """A rod pinned at its end, released level: I θ̈ = −m g L/2 cos θ − sign(θ̇) μ r |F|,
    F the pin force m a_G − m g, itself depending on θ̈ (solved by scipy's brentq at every
    evaluation of scipy's own integration). Its swings die out and it sticks where gravity's
    moment is within μ_s r |F| of the bottom."""
    from scipy.optimize import brentq
    length, mass, mu, mu_s, r = 1.0, 1.0, 0.3, 0.4, 0.15
    inertia = mass * length**2 / 3
    mech = ms.Mechanism("rubbing pendulum", gravity=(0.0, -G))
    rod = mech.add(ms.RigidBody.rod("rod", (0, 0), (length, 0), mass))
    pin = mech.add(ms.Revolute(mech.ground, rod, at=(0, 0), name="pin"))
    mech.add(ms.Friction(pin, mu=mu, mu_static=mu_s, radius=r, name="bearing"))
    res = mech.simulate(0.9, rtol=1e-10, atol=1e-12, output_step=0.05)   # first swing
    assert res.success, res.message

    def acceleration(th, w):
        radial = np.array([math.cos(th), math.sin(th)])
        tangent = np.array([-math.sin(th), math.cos(th)])

        def balance(a):
            pin_force = mass * length / 2 * (a * tangent - w * w * radial) + \
                mass * np.array([0.0, G])
            return inertia * a + mass * G * length / 2 * math.cos(th) + \
                np.sign(w) * mu * r * np.hypot(*pin_force)
        return brentq(balance, -100.0, 100.0, xtol=1e-15)
    ref = solve_ivp(lambda t, y: [y[1], acceleration(*y)], (0, 0.9), [0.0, 0.0],
                    method="DOP853", rtol=1e-12, atol=1e-14, t_eval=res.t)
    assert np.max(np.abs(res.coordinate("rod.angle") - ref.y[0])) < 1e-8
    rest = mech.simulate(6.0, rtol=1e-8, atol=1e-10, output_step=0.1)
    assert rest.success, rest.message
    last = rest.friction_switches[-1]
    assert last.after == "stuck" and abs(last.force) <= last.limit
    th = rest.coordinate("rod.angle")[-1]
    assert abs(mass * G * length / 2 * math.cos(th)) <= mu_s * r * mass * G * 1.001
    assert np.max(np.abs(rest.v[rest.t > last.t + 1e-9])) < 1e-9
    assert np.max(np.abs(rest.energy_drift)) < 100 * 1e-8


def test_friction_in_a_scene_and_round_tripping_through_one(tmp_path):
    scene = tmp_path / "incline.toml"
    scene.write_text("""
name = "block on a guide"
gravity = [0.0, -9.81]
[[body]]
name = "block"
mass = 2.0
inertia = 0.01
velocity = [1.0, 0.0]
[[joint]]
type = "prismatic"
name = "guide"
bodies = ["ground", "block"]
axis = [1.0, 0.0]
at = [0.0, 0.0]
[[friction]]
joint = "guide"
name = "rub"
mu = 0.25
mu_static = 0.3
length = 0.05
""")
    mech = ms.load_mechanism(scene)
    (fr,) = mech.frictions
    assert (fr.name, fr.joint.name, fr.mu, fr.mu_static, fr.length) == \
        ("rub", "guide", 0.25, 0.3, 0.05)
    res = mech.simulate(0.6, rtol=1e-10, atol=1e-12, output_step=0.05)
    (switch,) = res.friction_switches                         # stops at v/(μ g) and sticks
    assert switch.t == pytest.approx(1.0 / (0.25 * G), abs=1e-10)
    back = ms.load_mechanism(mech.save(tmp_path / "saved.toml"))
    (again,) = back.frictions
    assert vars(again).keys() == vars(fr).keys()
    assert all(getattr(again, k) == getattr(fr, k) for k in
               ("name", "mu", "mu_static", "radius", "length", "transition_velocity", "preload"))
    other = back.simulate(0.6, rtol=1e-10, atol=1e-12, output_step=0.05)
    assert np.array_equal(other.q, res.q)
    bad = scene.read_text().replace("mu = 0.25", "mu = -0.25")
    scene.write_text(bad)
    with pytest.raises(ms.ModelError, match="`mu` must be non-negative"):
        ms.load_mechanism(scene)


def test_a_saved_result_keeps_its_stick_and_slip(tmp_path):
    """Reloaded, a result computes the friction and reactions of each sample with the mode
    it ran in (a stuck block's rate is round-off, whose sign says nothing)."""
    mech, guide = incline(math.radians(10), 0.3, 0.4, speed=1.0)
    res = mech.simulate(1.5, rtol=1e-10, atol=1e-12, output_step=0.05)
    path = res.save(tmp_path / "stuck.npz")
    back = ms.load_result(path)
    assert back.friction_switches == res.friction_switches
    assert np.array_equal(back.friction_force("rub"), res.friction_force("rub"))
    stuck = res.t > res.friction_switches[0].t
    assert np.allclose(back.friction_force("rub")[stuck], -2.0 * G * math.sin(math.radians(10)),
                       rtol=1e-9)
    assert np.array_equal(back.joint_force(guide), res.joint_force(guide))


def test_a_rubbing_pendulum_bouncing_on_a_stop_keeps_its_energy_balance():
    """Pin friction and a stop together: the friction's work and the impacts' losses are
    both channels of the balance, which holds to the solver's accuracy through 13 impacts,
    the rest on the stop and the friction's reversals at every rebound."""
    mech = ms.Mechanism("rubbing pendulum on a stop", gravity=(0.0, -G))
    rod = mech.add(ms.RigidBody.rod("rod", (0, 0), (1.0, 0), 1.0))
    pin = mech.add(ms.Revolute(mech.ground, rod, at=(0, 0), name="pin"))
    mech.add(ms.Stop(pin, lower=-math.pi / 3, restitution=0.5))
    mech.add(ms.Friction(pin, mu=0.2, radius=0.02, name="bearing"))
    rtol = 1e-9
    res = mech.simulate(3.0, rtol=rtol, atol=1e-11, output_step=0.01)
    assert res.success, res.message
    assert res.impacts[-1].resting
    # each rebound but the last (it rests) rises to a top, where its friction reverses
    assert len(res.friction_switches) == len(res.impacts) - 1
    assert res.energy.channels == ("friction 'bearing'", "impacts")
    assert np.max(np.abs(res.energy.balance)) < 10 * rtol * np.ptp(res.energy.total)


def test_the_stick_slip_scene_runs_from_the_command_line(tmp_path, capsys, monkeypatch):
    """mechanisms/stick_slip.toml, the oscillator in SI units on its orbit: `mechsim run`
    lists its switches where the oscillator module's flow sticks and slips (scaled from mm
    to m), and its table's friction column is ±μ m g while slipping, the holding force
    (within it) while stuck."""
    from pathlib import Path
    from mechsim.app.cli import main
    scene = Path(__file__).resolve().parents[1] / "mechanisms" / "stick_slip.toml"
    monkeypatch.chdir(tmp_path)
    text = scene.read_text().replace("t_end = 0.3141592653589793    # five periods",
                                     "t_end = 0.0628318530717959")
    (tmp_path / "stick_slip.toml").write_text(text)
    assert main(["run", "stick_slip.toml"]) == 0
    out = capsys.readouterr().out
    osc = CoulombOscillator(**PAPER, mu=0.08)
    sol = ms.shooting.solve(osc, (-0.014, 2.7), method="newton", tol=1e-12)
    switches = [t for t, kind in sol.trajectory.events if kind in ("stick", "slip")]
    assert len(switches) == 4                                 # stick, slip, twice a period
    for t in switches:
        assert f"t = {t:.6f} s: 'rubbing'" in out, (t, out)
    import csv
    with open(tmp_path / "out" / "stick_slip" / "motion.csv", newline="",
              encoding="utf-8") as f:
        rows = list(csv.DictReader(f))
    force = np.array([float(r["rubbing friction force [N]"]) for r in rows])
    rate = np.array([float(r["guide rate [m/s]"]) for r in rows])
    sliding = np.abs(rate) > 1e-9
    np.testing.assert_allclose(force[sliding], -0.08 * 9.8 * np.sign(rate[sliding]),
                               rtol=1e-12)
    assert np.all(np.abs(force[~sliding]) <= 0.08 * 9.8 + 1e-12) and np.any(~sliding)


def test_a_run_with_friction_and_stops_extends_as_if_uninterrupted():
    """Extended from its end, a rubbing pendulum on a stop goes on in the modes it ended
    in (here resting on its stop): the joined run equals one run to the same time."""
    mech = ms.Mechanism("rubbing pendulum on a stop", gravity=(0.0, -G))
    rod = mech.add(ms.RigidBody.rod("rod", (0, 0), (1.0, 0), 1.0))
    pin = mech.add(ms.Revolute(mech.ground, rod, at=(0, 0), name="pin"))
    mech.add(ms.Stop(pin, lower=-math.pi / 3, restitution=0.5))
    mech.add(ms.Friction(pin, mu=0.2, radius=0.02, name="bearing"))
    whole = mech.simulate(1.6, rtol=1e-10, atol=1e-12, output_step=0.05)
    first = mech.simulate(1.0, rtol=1e-10, atol=1e-12, output_step=0.05)
    joined = first.extend(1.6)
    assert joined.success, joined.message
    np.testing.assert_allclose(joined.t, whole.t, rtol=0, atol=1e-8)     # events too
    np.testing.assert_allclose(joined.q, whole.q, rtol=0, atol=1e-8)
    assert [i.t for i in joined.impacts] == pytest.approx([i.t for i in whole.impacts],
                                                         abs=1e-8)
    assert joined.impacts[-1].resting
    np.testing.assert_allclose(joined.stop_force("stop(pin)"), whole.stop_force("stop(pin)"),
                               atol=1e-8)
    np.testing.assert_allclose(joined.energy.balance, whole.energy.balance, atol=1e-8)


def test_a_slider_crank_locks_where_its_guide_friction_feeds_its_own_load():
    """Driven through steep rod angles, a slider's guide friction μ N adds μ tan φ of
    itself to N: past μ tan φ = 1 no friction force balances (self-locking). The run ends
    there with its partial result, saying so, instead of an answer."""
    mech = ms.examples.slider_crank(crank_length=0.28, rod_length=0.3, driven=True,
                                    crank_speed=10.0)
    slide = mech.joint("slide")
    mech.add(ms.Friction(slide, mu=0.6, length=0.02, name="guide friction"))
    res = mech.simulate(0.63, rtol=1e-8, output_step=0.01)
    assert res.status == "failed" and "friction lock" in res.message, res.message
    assert "'guide friction'" in res.message
    # μ tan φ = 1 as the rod angle φ falls past −atan(1/μ) after the dead centre at θ = π,
    # sin φ = (r/l) sin θ: at θ = π + asin((l/r) sin atan(1/μ))
    t_lock = (math.pi + math.asin(0.3 / 0.28 * math.sin(math.atan(1 / 0.6)))) / 10.0
    assert res.t[-1] < t_lock < res.t[-1] + 0.03, (res.t[-1], t_lock)


def test_a_driven_pin_starting_from_rest_unaccelerated_rubs_the_way_it_turns():
    """θ = −t³ from rest: at t = 0 the pin neither moves nor accelerates, so which way its
    friction acts shows only once it turns (backwards): the friction always resists, and
    the motor delivers μ r ‖F‖ more than the pin's dynamics need."""
    mech = ms.examples.pendulum()
    pin = mech.joints[0]
    motor = mech.add(ms.Driver(pin, "-t**3", name="motor"))
    mech.add(ms.Friction(pin, mu=0.2, radius=0.02, name="bearing"))
    res = mech.simulate(1.0, rtol=1e-9, output_step=0.05)
    assert res.success, res.message
    rate, friction = res.joint_rate(pin), res.friction_force("bearing")
    moving = np.abs(rate) > 1e-9
    assert np.all(friction[moving] * rate[moving] < 0.0)
    force = np.hypot(*res.joint_force(pin).T)
    np.testing.assert_allclose(friction[moving], 0.2 * 0.02 * force[moving], rtol=1e-9)
    plain = ms.examples.pendulum()
    plain.add(ms.Driver(plain.joints[0], "-t**3", name="motor"))
    free = plain.simulate(1.0, rtol=1e-9, output_step=0.05)
    extra = res.driver_effort(motor) - free.driver_effort(plain.drivers[0])
    np.testing.assert_allclose(extra[moving], -friction[moving], rtol=1e-9, atol=1e-12)


def test_friction_coefficients_take_parameters_set_without_a_build():
    """μ and μ_s as Parameters: the block slides at μ = 0.3 (closed form), and after
    `set_parameters(mu=0.2)` at the new μ, no new build; μ_s raised above tan 30° makes it
    stick. A μ_s below μ is refused naming the friction, the old values kept."""
    angle = math.radians(30)
    mu, mu_s = ms.Parameter("mu", 0.3), ms.Parameter("mu_s", 0.5)
    mech, guide = incline(angle, mu, mu_s)
    assert {"mu", "mu_s"} <= set(mech.parameters)

    def slide(value):
        res = mech.simulate(0.5, rtol=1e-10, atol=1e-12, output_step=0.05)
        assert res.success, res.message
        a = G * (math.sin(angle) - value * math.cos(angle))
        return np.max(np.abs(res.joint_coordinate(guide) - 0.5 * a * res.t**2))

    assert slide(0.3) < 1e-8
    mech.set_parameters(mu=0.2)
    assert mech.frictions[0].mu == 0.2
    assert slide(0.2) < 1e-8
    mech.set_parameters(mu_s=0.7)                 # tan 30° = 0.577 < 0.7: the block rests
    res = mech.simulate(0.5, rtol=1e-10, atol=1e-12, output_step=0.05)
    assert np.max(np.abs(res.joint_coordinate(guide))) < 1e-12
    with pytest.raises(ms.ModelError, match="friction 'rub'.*must not be below"):
        mech.set_parameters(mu_s=0.1)
    assert mech.frictions[0].mu_static == 0.7


def test_friction_at_many_states_at_once_is_friction_at_each_alone():
    """`FrictionModel.solve_many` (each joint's geometry over all states in one pass, as
    the work integral asks for nine states a step) gives at every state what `solve` gives
    there alone: on a slider-crank turning freely with friction in all four joints (a
    Newton of four unknowns), with joints sliding as they move, all forwards, and one held
    still, and with states whose joints move different ways in one call (reversed rows)."""
    from mechsim.problem.friction import FORWARD, STUCK
    mech = ms.examples.slider_crank(crank_speed=100.0)
    for j in mech.joints:
        size = {"radius": 0.01} if j.kind == "revolute" else {"length": 0.02}
        mech.add(ms.Friction(j, mu=0.15, **size))
    res = mech.simulate(0.02, rtol=1e-8, output_step=0.002)      # (before its dead centre)
    p = mech.problem()
    T, Q, V = res.t[1:], res.q[1:], res.v[1:] * np.where(np.arange(len(res.t) - 1) % 2, 1.0,
                                                          -1.0)[:, None]
    F = p.load_model.forces_at(T, Q, V)
    K = len(p.friction.elements)
    for modes in (None, [FORWARD] * K, [FORWARD, FORWARD, STUCK, FORWARD]):   # B held
        together = p.friction.solve_many(p, T, Q, V, F, modes)
        for t, q, v, f, one in zip(T, Q, V, F, together):
            alone = p.friction.solve(p, t, q, v, f, modes)
            for name in ("forces", "loads", "rates", "gradients", "modes"):
                a, b = getattr(one, name), getattr(alone, name)
                np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-12 * np.abs(b).max(),
                                           err_msg=f"{name} at t = {t} (modes {modes})")
            assert np.abs(one.forces).max() > 0.0
        if modes is None:           # joints moving different ways: several groups
            assert len({tuple(s.modes) for s in together}) > 1


@pytest.mark.parametrize("size", [1, 2, 3])
def test_friction_s_newton_solves_small_systems_as_numpy_and_refuses_singular_ones(size, rng):
    """The float solve of friction's Newton (closed forms up to 2 × 2) against numpy's
    solve, and a matrix of rank one less counted singular."""
    from mechsim.problem.friction import _solve_small
    for _ in range(20):
        D, r = rng.normal(size=(size, size)), rng.normal(size=size)
        np.testing.assert_allclose(_solve_small(D.tolist(), r.tolist()),
                                   np.linalg.solve(D, r), rtol=1e-9 * np.linalg.cond(D))
        U, s, Vt = np.linalg.svd(D)
        s[-1] = 1e-12 * s[0]
        assert _solve_small(((U * s) @ Vt).tolist(), r.tolist()) is None


def test_a_pin_s_gradient_kept_once_is_its_coordinate_s_at_every_state(rng):
    """A revolute's coordinate (θ_b − θ_a with the beam nodes' modal rotations) is linear
    in q, so its gradient is evaluated once (`JointGeometry.constant_gradient`): on the
    flexible four-bar, at random states, it equals central differences of the coordinate
    itself (which would show any curvature) for every pin, modal ones included."""
    from mechsim.problem.geometry import joint_coordinates, joint_gradients
    mech = ms.examples.flexible_four_bar()
    problem = mech.problem()
    n = problem.n
    modal = [i for i, c in enumerate(problem.coordinate_names) if ".eta" in c]
    Q = rng.normal(size=(3, n))
    turned_by_nodes = set()
    for name, geometry in problem.joints.items():
        assert geometry.joint.linear_coordinate == (geometry.joint.kind == "revolute")
        G = joint_gradients(geometry, Q)
        h = 1e-6
        for q, g in zip(Q, G):
            steps = np.eye(n) * h
            s = lambda x: joint_coordinates(geometry, x, np.zeros_like(x))[0]  # noqa: E731
            fd = (s(q + steps) - s(q - steps)) / (2 * h)
            np.testing.assert_allclose(g, fd, rtol=0, atol=1e-8, err_msg=name)
        if np.any(np.abs(G[:, modal]) > 0.1):
            turned_by_nodes.add(name)
    assert turned_by_nodes == {"B", "C"}           # the coupler's two end nodes


def test_a_joint_at_one_state_is_the_same_joint_among_many(rng):
    """A joint's gradient and attachment points at one state (`geometry.OneState`: floats,
    the right-hand side's case) equal, to the bit, the same state's among five evaluated
    together, for every joint of the cam, the slider-crank (its guide), the pump and the
    flexible four-bar (modal points)."""
    from mechsim.problem.geometry import _attachment, joint_gradients
    scenes = [ms.load_scene(ROOT / "mechanisms" / f"{name}.toml").mechanism
              for name in ("cam_follower", "pump")]
    kinds = set()
    for mech in scenes + [ms.examples.slider_crank(driven=True),
                          ms.examples.flexible_four_bar()]:
        problem = mech.problem()
        Q = rng.normal(size=(5, problem.n))
        for geometry in problem.joints.values():
            for role in "ab":
                together = _attachment(geometry, Q, role)
                alone = [_attachment(geometry, Q[i:i + 1], role)[0] for i in range(5)]
                assert np.array_equal(together, alone), geometry.joint.name
            if type(geometry.joint).coordinate is not ms.Joint.coordinate:
                kinds.add(geometry.joint.kind)
                together = joint_gradients(geometry, Q)
                alone = [joint_gradients(geometry, Q[i:i + 1])[0] for i in range(5)]
                assert np.array_equal(together, alone), geometry.joint.name
    assert {"revolute", "prismatic"} <= kinds
