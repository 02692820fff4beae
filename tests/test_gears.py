"""Gear pairs: spur (external and internal), rack and pinion, and a plain ratio coupling,
against the closed forms of a driven gear train."""

import numpy as np
import pytest

import mechsim as ms

TAU = 0.5                                  # motor torque on gear a [N·m]
MA, MB = 1.0, 3.0                          # disc masses [kg]


def train(kind="spur", internal=False, build=None):
    """Gear a (a disc) on a pin at the origin, driven by TAU, meshing with gear b on a pin
    at (0.3, 0.1) (external: radii d/3, 2d/3 with d the centre distance; internal: a ring
    of radius 2d around a pinion of radius d), no gravity, from rest."""
    mech = ms.Mechanism("train", gravity=(0.0, 0.0))
    d = float(np.hypot(0.3, 0.1))
    ra, rb = (d / 3, 2 * d / 3) if not internal else (d, 2 * d)
    a = mech.add(ms.RigidBody.disc("a", (0, 0), ra, MA))
    b = mech.add(ms.RigidBody.disc("b", (0.3, 0.1), rb, MB))
    pa = mech.add(ms.Revolute(mech.ground, a, at=(0, 0), name="pa"))
    pb = mech.add(ms.Revolute(mech.ground, b, at=(0.3, 0.1), name="pb"))
    if kind == "spur":
        mech.add(ms.Gear.spur(pa, pb, ra, rb, internal=internal, name="mesh"))
    else:
        mech.add(ms.Gear(pa, pb, (ra if internal else -ra) / rb, name="mesh"))
    mech.add(ms.Torque(a, TAU, name="motor"))
    if build:
        mech.problem(build=build)
    return mech, ra, rb


def closed_form(ra, rb):
    """(α_a, tooth force): (I_a + I_b (r_a/r_b)²) α_a = τ; gear b needs r_b F = I_b α_b."""
    ia, ib = MA * ra**2 / 2, MB * rb**2 / 2
    alpha = TAU / (ia + ib * (ra / rb) ** 2)
    return alpha, ib * (ra / rb) * alpha / rb


@pytest.mark.parametrize("build", ["assembled", "fused"])
@pytest.mark.parametrize("internal", [False, True])
def test_a_spur_pair_turns_at_its_ratio_and_loads_both_pins_with_the_tooth_force(build,
                                                                                internal):
    mech, ra, rb = train(internal=internal, build=build)
    res = mech.simulate(1.0, rtol=1e-10, atol=1e-12, output_step=0.05)
    assert res.success
    alpha, force = closed_form(ra, rb)
    angle_a = res.coordinate("a.angle")
    np.testing.assert_allclose(angle_a, alpha * res.t**2 / 2, rtol=0, atol=1e-10)
    ratio = ra / rb if internal else -ra / rb
    np.testing.assert_allclose(res.coordinate("b.angle"), ratio * angle_a, rtol=0, atol=1e-12)
    # The tooth force turns b the way it goes (counter-clockwise for an internal pair,
    # clockwise for an external one) and is carried by both pins, perpendicular to the
    # line of centres.
    np.testing.assert_allclose(res.gear_force("mesh"), force if internal else -force,
                               rtol=1e-9)
    line = np.array([0.3, 0.1]) / np.hypot(0.3, 0.1)
    for pin in ("pa", "pb"):
        f = res.joint_force(pin)
        np.testing.assert_allclose(np.hypot(f[:, 0], f[:, 1]), force, rtol=1e-9)
        np.testing.assert_allclose(f @ line, 0.0, atol=1e-9)
    # The motor's work is the kinetic energy (no losses): the balance holds.
    assert np.abs(res.energy.balance).max() < 1e-8 * res.energy.total.max()


def test_a_ratio_coupling_moves_the_same_but_loads_no_pin():
    spur, ra, rb = train("spur")
    plain, _, _ = train("ratio")
    a = spur.simulate(0.5, rtol=1e-10, atol=1e-12, output_step=0.05)
    b = plain.simulate(0.5, rtol=1e-10, atol=1e-12, output_step=0.05)
    np.testing.assert_allclose(b.q, a.q, rtol=0, atol=1e-10)
    np.testing.assert_allclose(b.joint_force("pa"), 0.0, atol=1e-9)
    # its multiplier is the torque on b: r_b times the tooth force
    np.testing.assert_allclose(b.gear_force("mesh"), rb * a.gear_force("mesh"), rtol=1e-8)


@pytest.mark.parametrize("build", ["assembled", "fused"])
def test_a_rack_moves_r_per_radian_and_the_pinion_pin_carries_the_tooth_force(build):
    mech = ms.Mechanism("rack", gravity=(0.0, -9.81))
    r, m_rack, m_pinion = 0.05, 2.0, 0.4
    pinion = mech.add(ms.RigidBody.disc("pinion", (0, r), r, m_pinion))
    rack = mech.add(ms.RigidBody.rectangle("rack", (0, 0), 0.5, 0.02, m_rack))
    pin = mech.add(ms.Revolute(mech.ground, pinion, at=(0, r), name="pin"))
    slide = mech.add(ms.Prismatic(mech.ground, rack, axis=(1, 0), at=(0, 0), name="slide"))
    mech.add(ms.Gear.rack(pin, slide, r, name="mesh"))
    mech.add(ms.Torque(pinion, 0.2, name="motor"))
    mech.problem(build=build)
    res = mech.simulate(0.5, rtol=1e-10, atol=1e-12, output_step=0.05)
    alpha = 0.2 / (m_pinion * r**2 / 2 + m_rack * r**2)
    np.testing.assert_allclose(res.coordinate("pinion.angle"), alpha * res.t**2 / 2, atol=1e-11)
    np.testing.assert_allclose(res.coordinate("rack.x"), r * res.coordinate("pinion.angle"),
                               atol=1e-12)
    force = m_rack * r * alpha                                # pushes the rack along +x
    np.testing.assert_allclose(res.gear_force("mesh"), force, rtol=1e-9)
    f_pin = res.joint_force("pin")
    np.testing.assert_allclose(f_pin[:, 0], force, rtol=1e-9)
    np.testing.assert_allclose(f_pin[:, 1], m_pinion * 9.81, rtol=1e-9)   # and its weight


def test_gears_round_trip_through_a_scene(tmp_path):
    mech, _, _ = train(internal=True)
    back = ms.load_mechanism(mech.save(tmp_path / "train.toml"))
    assert back.structure() == mech.structure()
    a = mech.simulate(0.2, rtol=1e-9, output_step=0.05)
    b = back.simulate(0.2, rtol=1e-9, output_step=0.05)
    np.testing.assert_array_equal(a.q, b.q)


def test_bad_gears_are_refused_naming_them():
    mech, ra, rb = train()
    pa, pb = mech.joint("pa"), mech.joint("pb")
    c = mech.add(ms.RigidBody.disc("c", (1, 0), 0.1, 1.0))
    pc = mech.add(ms.Revolute(mech.body("b"), c, at=(1, 0), name="pc"))
    with pytest.raises(ms.ModelError, match=r"gear 'g': joints 'pa' and 'pc' share no body"):
        ms.Gear.spur(pa, pc, 0.1, 0.1, name="g")
    with pytest.raises(ms.ModelError, match=r"gear 'g': `ratio` must not be 0"):
        ms.Gear(pa, pb, 0.0, name="g")
    with pytest.raises(ms.ModelError, match=r"gear 'g'.*`radius_b` must be positive"):
        ms.Gear.spur(pa, pb, 0.1, -0.1, name="g")
    other = ms.Revolute(mech.ground, c, at=(1, 0), name="loose")
    with pytest.raises(ms.ModelError, match=r"gear 'g': joint 'loose' is not in mechanism"):
        mech.add(ms.Gear(pa, other, 2.0, name="g"))
    with pytest.raises(ms.ModelError, match=r"gear: couples joint 'pa' to itself"):
        ms.Gear(pa, pa, 2.0)


@pytest.mark.parametrize("build", ["assembled", "fused"])
def test_a_planetary_stage_obeys_willis(build, tmp_path):
    """Sun and arm driven (ω_s = 10, ω_arm = 2 rad/s): the planet turns at ω_arm −
    (r_s/r_p)(ω_s − ω_arm) and the ring, meshing with the planet inside it, at ω_arm +
    (r_p/R)(ω_p − ω_arm), R = r_s + 2 r_p (Willis); the pairs' line of centres turns
    with the arm, their `carrier`."""
    rs, rp = 0.1, 0.05
    big = rs + 2 * rp
    mech = ms.Mechanism("planetary", gravity=(0.0, 0.0))
    sun = mech.add(ms.RigidBody.disc("sun", (0, 0), rs, 1.0))
    arm = mech.add(ms.RigidBody.rod("arm", (0, 0), (rs + rp, 0), 0.5))
    planet = mech.add(ms.RigidBody.disc("planet", (rs + rp, 0), rp, 0.3))
    ring = mech.add(ms.RigidBody.disc("ring", (0, 0), big, 2.0))
    p_sun = mech.add(ms.Revolute(mech.ground, sun, at=(0, 0), name="sun pin"))
    p_arm = mech.add(ms.Revolute(mech.ground, arm, at=(0, 0), name="arm pin"))
    p_planet = mech.add(ms.Revolute(arm, planet, at=(rs + rp, 0), name="planet pin"))
    p_ring = mech.add(ms.Revolute(mech.ground, ring, at=(0, 0), name="ring pin"))
    mech.add(ms.Gear.spur(p_sun, p_planet, rs, rp, carrier=arm, name="sun-planet"))
    mech.add(ms.Gear.spur(p_planet, p_ring, rp, big, internal=True, carrier=arm,
                          name="planet-ring"))
    mech.add(ms.Driver(p_sun, "10*t"))
    mech.add(ms.Driver(p_arm, "2*t"))
    mech.problem(build=build)
    res = mech.kinematics(0.5, 0.05)
    assert res.success, res.message
    w_planet = 2.0 - rs / rp * (10.0 - 2.0)
    w_ring = 2.0 + rp / big * (w_planet - 2.0)
    np.testing.assert_allclose(res.coordinate("planet.angle"), w_planet * res.t, atol=1e-10)
    np.testing.assert_allclose(res.coordinate("ring.angle"), w_ring * res.t, atol=1e-10)
    back = ms.load_mechanism(mech.save(tmp_path / "planetary.toml"))
    assert back.structure() == mech.structure()
    back.problem(build=build)                       # the same build: the same numbers
    np.testing.assert_allclose(back.kinematics(0.5, 0.05).q, res.q, rtol=0, atol=1e-12)
