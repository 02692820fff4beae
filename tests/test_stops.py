"""End stops: impacts located in time, Newton's restitution, resting contact without
chatter, and letting go, against closed forms and an independent integration."""

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

import mechsim as ms

L, M, G = 1.0, 1.0, 9.81
LIMIT = -math.pi / 3
I_O = M * L**2 / 3


def pendulum(restitution, angle=0.0, method_torque=None):
    """A uniform rod pinned at its end, drawn at `angle`, with a stop at −60°."""
    mech = ms.Mechanism("pendulum on a stop", gravity=(0.0, -G))
    tip = (L * math.cos(angle), L * math.sin(angle))
    rod = mech.add(ms.RigidBody.rod("rod", (0, 0), tip, M))
    pin = mech.add(ms.Revolute(mech.ground, rod, at=(0, 0), name="pin"))
    mech.add(ms.Stop(pin, lower=LIMIT, restitution=restitution, name="stop"))
    if method_torque is not None:
        mech.add(ms.Torque(rod, method_torque, name="lift"))
    return mech


def first_impact_time():
    """θ̈ = −(3g/2L) cos θ from rest at 0 to θ = −60°, by scipy alone."""
    def reach(t, y):
        return y[0] - LIMIT
    reach.terminal = True
    sol = solve_ivp(lambda t, y: [y[1], -1.5 * G / L * math.cos(y[0])], (0, 2), [0, 0],
                    method="DOP853", rtol=1e-13, atol=1e-14, events=reach)
    return float(sol.t_events[0][0])


@pytest.mark.parametrize("method", ["hybrid", "lu", "projection"])
def test_a_pendulum_bounces_on_its_stop_and_comes_to_rest(method):
    e = 0.5
    res = pendulum(e).simulate(3.0, method=method, rtol=1e-10, atol=1e-12,
                               output_step=0.01)
    assert res.success, res.message
    first = res.impacts[0]
    speed = math.sqrt(3 * G * math.sin(math.pi / 3) / L)       # energy: ½ I ω² = m g L/2 sin 60°
    assert first.t == pytest.approx(first_impact_time(), abs=1e-8)
    assert first.rate_before == pytest.approx(-speed, rel=1e-8)
    assert first.rate_after == pytest.approx(e * speed, rel=1e-8)
    assert first.energy_lost == pytest.approx((1 - e**2) * I_O * speed**2 / 2, rel=1e-8)
    # the stop's angular impulse is I_O (1 + e) ω; the pin's makes up the rod's momentum
    # change m (L/2) Δω, across the rod at −60° (the weight is no impulse)
    assert first.impulse == pytest.approx(I_O * (1 + e) * speed, rel=1e-8)
    across = np.array([-math.sin(LIMIT), math.cos(LIMIT)])
    np.testing.assert_allclose(first.joint_impulses["pin"],
                               M * L / 2 * (1 + e) * speed * across,
                               rtol=1e-8, atol=1e-10)
    for a, b in zip(res.impacts, res.impacts[1:]):
        assert b.rate_before == pytest.approx(-a.rate_after, rel=1e-6)   # the rod returns
    # Every rebound halves the speed until it is below rest_speed: then it rests, no
    # chatter: 5.05 · 0.5^k < 2e-3 → 13 impacts.
    assert len(res.impacts) == 13 and res.impacts[-1].resting
    assert res.coordinate("rod.angle")[-1] == pytest.approx(LIMIT, abs=1e-9)
    assert np.abs(res.v[-1]).max() < 1e-9
    assert np.min(res.coordinate("rod.angle")) > LIMIT - 1e-9              # never through
    # the energy the impacts took is a work channel: the balance holds
    assert res.energy.channels[-1] == "impacts"
    assert np.abs(res.energy.balance).max() < 1e-7


def test_a_resting_joint_is_let_go_when_the_stop_would_pull():
    """At rest on the stop, lifted by a torque 10 t: gravity's moment m g (L/2) cos 60° =
    2.4525 N·m holds it until t = 0.24525 s."""
    mech = pendulum(0.5, angle=LIMIT, method_torque="10*t")
    res = mech.simulate(0.5, rtol=1e-10, atol=1e-12, output_step=0.01)
    assert res.success and len(res.impacts) == 1 and res.impacts[0].resting
    angle = res.coordinate("rod.angle")
    leaves = res.t[np.flatnonzero(angle > LIMIT + 1e-10)[0] - 1]
    assert leaves == pytest.approx(M * G * L / 2 * math.cos(LIMIT) / 10.0, abs=1e-9)
    assert angle[-1] > LIMIT + 0.01                                  # it rose


def test_a_slider_bounces_elastically_between_two_stops():
    """No gravity, e = 1: the block shuttles between the stops at its speed, its energy
    kept through every impact."""
    mech = ms.Mechanism("shuttle", gravity=(0.0, 0.0))
    block = mech.add(ms.RigidBody.point_mass("block", (0, 0), 2.0, velocity=(0.5, 0.0)))
    rail = mech.add(ms.Prismatic(mech.ground, block, axis=(1, 0), at=(0, 0), name="rail"))
    mech.add(ms.Stop(rail, lower=-0.1, upper=0.2, restitution=1.0, name="ends"))
    res = mech.simulate(2.0, rtol=1e-10, atol=1e-12, output_step=0.01)
    assert res.success, res.message
    # 0.2 m out at 0.5 m/s, then 0.3 m each way: impacts at 0.4, 1.0, 1.6 s
    np.testing.assert_allclose([i.t for i in res.impacts], [0.4, 1.0, 1.6], atol=1e-10)
    assert all(abs(i.energy_lost) < 1e-12 for i in res.impacts)
    x = res.coordinate("block.x")
    assert x.min() > -0.1 - 1e-10 and x.max() < 0.2 + 1e-10


def test_bad_stops_are_refused_naming_them():
    mech = pendulum(0.5)
    pin = mech.joint("pin")
    with pytest.raises(ms.ModelError, match=r"stop 's': `lower` \(1\) must be below `upper`"):
        ms.Stop(pin, lower=1.0, upper=0.5, name="s")
    with pytest.raises(ms.ModelError, match=r"stop 's': `restitution` must be between 0 and 1"):
        ms.Stop(pin, lower=0.0, restitution=1.5, name="s")
    with pytest.raises(ms.ModelError, match=r"stop 's': give `lower`, `upper` or both"):
        ms.Stop(pin, name="s")
    late = pendulum(0.5, angle=-1.5)
    with pytest.raises(ms.ModelError, match=r"stop 'stop': joint 'pin' starts at -1.5, "
                                            r"below `lower`"):
        late.simulate(0.1)
    driven = pendulum(0.5)
    driven.stops.clear()
    driven.add(ms.Driver(driven.joint("pin"), "t"))
    with pytest.raises(ms.ModelError, match=r"joint 'pin' is driven"):
        driven.add(ms.Stop(driven.joint("pin"), lower=-1.0, name="s"))
    with pytest.raises(ms.ModelError, match=r"a run with stops .* cannot be streamed"):
        pendulum(0.5).simulate(0.1, stream="run")


def test_stops_round_trip_through_a_scene(tmp_path):
    mech = pendulum(0.5)
    back = ms.load_mechanism(mech.save(tmp_path / "stop.toml"))
    (stop,) = back.stops
    assert (stop.name, stop.joint.name, stop.lower, stop.upper, stop.restitution) == \
        ("stop", "pin", LIMIT, None, 0.5)
    a = mech.simulate(1.0, rtol=1e-9, output_step=0.05)
    b = back.simulate(1.0, rtol=1e-9, output_step=0.05)
    assert [i.t for i in a.impacts] == pytest.approx([i.t for i in b.impacts], abs=1e-12)


def test_a_pendulum_resting_on_its_stop_is_held_by_the_stop_and_its_pin():
    """At rest on the stop at −60° the rod's weight hangs on its pin, m g upwards, and the
    stop carries gravity's moment about the pin, m g (L/2) cos 60°, as statics says; while
    the rod swings the stop carries nothing."""
    mech = pendulum(0.0)                                       # e = 0: it rests at once
    res = mech.simulate(1.5, rtol=1e-10, atol=1e-12, output_step=0.01)
    assert res.success, res.message
    (impact,) = res.impacts
    resting = res.t > impact.t
    pin, stop = mech.joints[0], mech.stops[0]
    assert np.allclose(res.joint_force(pin)[resting], [0.0, M * G], atol=1e-9)
    held = res.stop_force(stop)
    assert np.allclose(held[resting], M * G * L / 2 * math.cos(LIMIT), rtol=1e-9)
    assert np.all(held[~resting] == 0.0)
