"""Analytic tier: simulations against exact solutions."""

import math
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.interpolate import CubicSpline
from scipy.special import ellipk

import mechsim as ms
from mechsim.examples import parallelogram_exact, slider_crank_position

ROOT = Path(__file__).resolve().parents[1]


def test_double_four_bar_matches_the_parallelogram_branch():
    """IFToMM A02 up to 0.6 s (its first singular configuration is at 0.714 s): every crank
    follows M_eff θ̈ = −K cos θ with θ(0) = π/2, θ̇(0) = −1."""
    mech = ms.examples.double_four_bar()
    res = mech.simulate(t_end=0.6, rtol=1e-9, atol=1e-12, output_step=0.01)
    assert res.status == "success", res.message
    theta, _ = parallelogram_exact(res.t, math.pi / 2, -1.0, n=2)
    exact_tip = np.column_stack([np.cos(theta), np.sin(theta)])
    for i in range(3):
        tip = res.point(f"crank{i + 1}", (0.5, 0.0)) - (i, 0.0)
        assert np.max(np.linalg.norm(tip - exact_tip, axis=1)) <= 1e-7
    assert np.max(np.abs(res.energy_drift)) <= 1e-7
    assert res.constraint_violation.max() <= 1e-8
    # The cranks really moved: about 50° in 0.6 s.
    assert theta[-1] < math.radians(40)


@pytest.mark.parametrize("amplitude_deg", [10.0, 120.0])
def test_pendulum_period(amplitude_deg):
    """A uniform rod pinned at one end: T = 4 √(I_O / (m g d)) K(sin²(α/2)), I_O = mL²/3,
    d = L/2; after one period the state repeats."""
    L, m, g = 0.8, 1.5, 9.81
    alpha = math.radians(amplitude_deg)
    mech = ms.examples.pendulum(length=L, mass=m, angle=-math.pi / 2 + alpha)
    period = 4.0 * math.sqrt((m * L**2 / 3) / (m * g * L / 2)) * ellipk(math.sin(alpha / 2) ** 2)
    res = mech.simulate(t_end=period, rtol=1e-10, atol=1e-12, output_step=period / 2)
    angle, rate = res.coordinate("rod.angle"), res.v[:, 2]
    assert abs(angle[1] - (-math.pi / 2 - alpha)) < 1e-7     # half a period: the other side
    assert abs(angle[2] - angle[0]) < 1e-7 and abs(rate[2]) < 1e-6


@pytest.mark.parametrize("damping", [0.0, 12.0])
def test_spring_mass_on_a_prismatic_joint(damping):
    m, k, x0 = 2.0, 800.0, 0.05
    mech = ms.examples.spring_mass(mass=m, stiffness=k, stretch=x0, damping=damping)
    res = mech.simulate(t_end=1.0, rtol=1e-10, atol=1e-12, output_step=0.01)
    wn = math.sqrt(k / m)
    zeta = damping / (2 * math.sqrt(k * m))
    wd = wn * math.sqrt(1 - zeta**2)
    t = res.t
    exact = x0 * np.exp(-zeta * wn * t) * (np.cos(wd * t) + zeta * wn / wd * np.sin(wd * t))
    np.testing.assert_allclose(res.coordinate("block.x") - 0.5, exact, atol=1e-8)
    np.testing.assert_allclose(res.coordinate("block.y"), 0.0, atol=1e-12)
    if damping == 0.0:
        # Samples between steps come from DOP853's 7th-order dense output, whose error (here
        # ~1e-8 with steps of ωh ≈ 0.5) exceeds the step error (~1e-10 drift at the steps).
        assert np.max(np.abs(res.energy_drift)) < 5e-8
    else:  # damping dissipates: energy falls monotonically (to sampling noise)
        assert np.all(np.diff(res.energy.total) < 1e-9)


def test_driven_crank_follows_its_driver():
    mech = ms.examples.pendulum(length=0.5, mass=2.0, angle=0.3)
    mech.add(ms.Driver(mech.joint("pivot"), "2*t + 0.5*sin(3*t)"))
    mech.assemble()
    res = mech.simulate(t_end=2.0, rtol=1e-9, atol=1e-11, output_step=0.05)
    t = res.t
    np.testing.assert_allclose(res.coordinate("rod.angle") - 0.3, 2 * t + 0.5 * np.sin(3 * t),
                               atol=1e-9)
    np.testing.assert_allclose(res.v[:, 2], 2 + 1.5 * np.cos(3 * t), atol=1e-9)


def test_driver_with_nonzero_start_is_assembled_there():
    mech = ms.examples.pendulum(length=0.5, mass=2.0, angle=0.0)
    mech.add(ms.Driver(mech.joint("pivot"), "0.4 + t"))
    report = mech.assemble()
    assert abs(report.q[2] - 0.4) < 1e-12 and abs(report.v[2] - 1.0) < 1e-12
    assert report.iterations > 0


def test_prismatic_driver():
    mech = ms.examples.spring_mass()
    mech.add(ms.Driver(mech.joint("slide"), "0.1*sin(5*t)"))
    res = mech.simulate(t_end=1.0, rtol=1e-9, atol=1e-11, output_step=0.05)
    np.testing.assert_allclose(res.coordinate("block.x") - 0.55, 0.1 * np.sin(5 * res.t),
                               atol=1e-9)


def test_slider_crank_runs_through_its_dead_centres():
    r, l = 0.15, 0.30
    mech = ms.examples.slider_crank(crank_length=r, rod_length=l, crank_speed=150.0)
    res = mech.simulate(t_end=0.2, rtol=1e-9, atol=1e-11, output_step=2.5e-4)
    assert res.status == "success", res.message
    theta = res.coordinate("crank.angle")
    assert theta[-1] > 7 * math.pi          # 3.5+ revolutions: 7 or more dead-centre passages
    np.testing.assert_allclose(res.coordinate("slider.x"), slider_crank_position(theta, r, l),
                               atol=1e-9)
    assert np.max(np.abs(res.energy_drift)) < 1e-7
    # The crank speed fluctuates (the effective inertia varies with angle), but at every dead
    # centre the slider stands still and all heights are back to zero, so by conservation of
    # energy the crank speed there is the initial 150 rad/s.
    omega = res.v[:, 2]
    assert omega.min() < 110.0
    dead_centres = np.arange(1, 8) * math.pi
    np.testing.assert_allclose(CubicSpline(theta, omega)(dead_centres), 150.0, rtol=1e-6)


def test_every_scipy_integrator_runs_the_double_four_bar():
    mech = ms.examples.double_four_bar()
    theta, _ = parallelogram_exact([0.3], math.pi / 2, -1.0, n=2)
    for name in ["RK45", "DOP853", "Radau", "BDF", "LSODA"]:
        res = mech.simulate(t_end=0.3, rtol=1e-8, atol=1e-10, integrator=name)
        assert res.status == "success", (name, res.message)
        assert res.stats["integrator"] == name
        assert abs(res.coordinate("crank1.angle")[-1] - theta[0]) < 1e-5, name


def test_failure_mid_run_returns_the_partial_result():
    mech = ms.examples.pendulum()
    rod = mech.body("rod")
    mech.add(ms.Force(rod, lambda t: (0.0, 0.0) if t < 0.5 else (float("nan"), 0.0),
                      name="bad force"))
    res = mech.simulate(t_end=1.0, rtol=1e-8, atol=1e-10, output_step=0.01)
    assert res.status == "failed"
    assert "bad force" in res.message
    assert 0.4 <= res.t[-1] <= 0.5 and len(res.t) == len(res.q) > 40


@pytest.mark.parametrize("method", ["hybrid", "projection"])
def test_redundant_triple_crank_simulates_on_its_exact_branch(method):
    """One 2 m coupler on three parallel cranks has a redundant constraint equation; the
    motion is still the 1-DOF parallelogram with M_eff = 3·mL²/3 + m_c L², K = g(3mL/2 + m_c L)."""
    mech = ms.Mechanism("triple crank")
    coupler = mech.add(ms.RigidBody.rod("coupler", (0, 1), (2, 1), 1.0, velocity=(1.0, 0.0)))
    for i in range(3):
        crank = mech.add(ms.RigidBody.rod(f"crank{i}", (i, 0), (i, 1), 1.0,
                                          velocity=(0.5, 0.0), angular_velocity=-1.0))
        mech.add(ms.Revolute(mech.ground, crank, at=(i, 0), name=f"A{i}"))
        mech.add(ms.Revolute(crank, coupler, at=(i, 1), name=f"B{i}"))
    res = mech.simulate(t_end=0.6, method=method, rtol=1e-9, atol=1e-12, output_step=0.01)
    m_eff, k = 2.0, 9.81 * 2.5
    exact = solve_ivp(lambda t, y: [y[1], -k / m_eff * math.cos(y[0])], (0, 0.6),
                      [math.pi / 2, -1.0], t_eval=res.t, rtol=1e-13, atol=1e-14, method="DOP853")
    for i in range(3):
        assert np.max(np.abs(res.coordinate(f"crank{i}.angle") - exact.y[0])) < 1e-8
    assert np.max(np.abs(res.energy_drift)) < 1e-7


def point_mass(mass, inertia, d=0.5):
    mech = ms.Mechanism("point mass")
    body = mech.add(ms.RigidBody("b", mass, inertia, position=(d, 0.0)))
    mech.add(ms.Revolute(mech.ground, body, at=(0.0, 0.0)))
    return mech


@pytest.mark.parametrize("method, mass, inertia", [
    (method, mass, inertia) for method in ("hybrid", "lu", "projection")
    for mass, inertia in ((1.0, 1e-9), (1.0, 1e-12), (1e20, 1.0))
    if (method, mass) != ("projection", 1e20)])
def test_very_unequal_masses_follow_the_exact_pendulum(method, mass, inertia):
    """A body pinned 0.5 m from its centre of mass swings as a compound pendulum,
    (I + m d²) θ̈ = −m g d cos θ, however unequal its mass and inertia: a 1 kg point mass
    (inertia 1e-9 kg·m²) made Φ_q M⁻¹ Φ_qᵀ ill-conditioned by 1e8 and LU crawled, and the
    projection method's fixed truncation cut dropped one of the pin's equations (0.6 rad
    off after 2 s, reported as success)."""
    d, g = 0.5, 9.81
    mech = point_mass(mass, inertia, d)
    run = dict(t_end=2.0, method=method, rtol=1e-8, atol=1e-10, output_step=0.1,
               max_steps=5000)
    res = mech.simulate(**run)
    exact = solve_ivp(lambda t, y: [y[1], -mass * g * d * math.cos(y[0]) / (inertia + mass * d * d)],
                      (0.0, 2.0), [0.0, 0.0], t_eval=res.t, rtol=1e-13, atol=1e-13)
    assert res.status == "success", res.message
    assert np.max(np.abs(res.coordinate("b.angle") - exact.y[0])) < 1e-6


def test_the_projection_method_refuses_masses_it_cannot_resolve():
    """The projection method cannot resolve a ratio σ_min/σ_max of its mass-scaled
    Jacobian of 2e-10 (1e20 kg with unit inertia on a pin 0.5 m off: it took 200 000 steps
    and 142 s to reach 0.04 s): it says so before the run, naming the coordinates of the
    largest and smallest mass and the methods that can."""
    with pytest.raises(ValueError, match=r"masses are too unequal \(b.x carries 1e\+20, "
                                         r"b.angle 1\).*'hybrid' or 'lu'"):
        point_mass(1e20, 1.0).simulate(t_end=2.0, method="projection", rtol=1e-8, atol=1e-10)


def test_a_very_heavy_rod_runs_as_its_limit():
    """The slider-crank scene with a 1e10, 1e16 and 1e100 kg connecting rod: the motion of
    the rod-dominated limit (within 1e-8 of each other) and an energy balance within 1e-6.
    (The passage search inside each step read a bound on the rate of σ_min/σ_max millions
    of times the rates seen and spent 4000 evaluations a step: 16 s for 0.2 s of motion,
    162 s before; now 0.1 s, `mechsim bench costs`, heavy-rod.) At 1e100 kg σ_min/σ_max of
    the mass-scaled Jacobian is 3e-53, below round-off: the hybrid switched to projection
    at a passage that was noise and failed, blaming the configuration; now no passage is
    watched there, and the message says so."""
    runs = [ms.load_scene(ROOT / "mechanisms" / "slider_crank.toml",
                          parameters={"rod_mass": m}).simulate() for m in (1e10, 1e16, 1e100)]
    for res in runs:
        assert res.status == "success", res.message
        assert np.max(np.abs(res.energy_drift)) < 1e-6
    np.testing.assert_allclose(runs[0].q, runs[1].q, rtol=0, atol=1e-8)
    np.testing.assert_allclose(runs[1].q, runs[2].q, rtol=0, atol=1e-8)
    assert "singular passages were not watched" in runs[2].message
    assert "not watched" not in runs[1].message


def test_mass_properties_from_shapes():
    """A rectangle by its formula and as a polygon; a right triangle's polygon against
    m (a² + b² + c²)/36 about its centroid; a disc against a polygon of 2000 sides."""
    r = ms.RigidBody.rectangle("r", (1.0, 2.0), 0.2, 0.1, 2.0, angle=0.3)
    assert r.inertia == pytest.approx(2.0 * (0.04 + 0.01) / 12, rel=1e-15)
    assert r.angle == 0.3 and tuple(r.position) == (1.0, 2.0)
    square = ms.RigidBody.polygon("p", [(0.9, 1.95), (1.1, 1.95), (1.1, 2.05), (0.9, 2.05)], 2.0)
    assert square.inertia == pytest.approx(r.inertia, rel=1e-10)
    np.testing.assert_allclose(square.position, (1.0, 2.0), atol=1e-14)
    clockwise = ms.RigidBody.polygon("t", [(0, 0), (0, 4), (3, 0)], 6.0)
    assert clockwise.inertia == pytest.approx(6.0 * (9 + 16 + 25) / 36, rel=1e-13)
    np.testing.assert_allclose(clockwise.position, (1.0, 4 / 3), atol=1e-14)
    th = np.linspace(0.0, 2 * np.pi, 2001)[:-1]
    many = ms.RigidBody.polygon("d", np.c_[0.3 * np.cos(th), 0.3 * np.sin(th)], 5.0)
    assert many.inertia == pytest.approx(ms.RigidBody.disc("d", (0, 0), 0.3, 5.0).inertia,
                                         rel=1e-5)      # (2 + cos(2π/n))/3 of it: 1.6e-6 short
    for make, match in [(lambda: ms.RigidBody.polygon("q", [(0, 0), (1, 1)], 1.0),
                         "at least 3 `vertices`"),
                        (lambda: ms.RigidBody.polygon("q", [(0, 0), (1, 1), (2, 2)], 1.0),
                         "enclose no area"),
                        (lambda: ms.RigidBody.disc("q", (0, 0), -1.0, 1.0),
                         "`radius` must be positive")]:
        with pytest.raises(ms.ModelError, match=match):
            make()


def test_a_plate_pinned_at_a_corner_swings_as_its_compound_pendulum():
    """A 0.4 × 0.2 m plate pinned at a corner: (I_c + m d²) θ̈ = −m g d cos(θ + φ), d the
    centre's distance from the pin, against an independent integration."""
    w, h, m, g = 0.4, 0.2, 3.0, 9.81
    mech = ms.Mechanism("plate")
    plate = mech.add(ms.RigidBody.rectangle("plate", (w / 2, -h / 2), w, h, m))
    mech.add(ms.Revolute(mech.ground, plate, at=(0.0, 0.0), name="corner"))
    res = mech.simulate(1.5, rtol=1e-10, atol=1e-12, output_step=0.05)
    d, phi = math.hypot(w / 2, h / 2), math.atan2(-h / 2, w / 2)
    inertia = m * (w * w + h * h) / 12 + m * d * d
    exact = solve_ivp(lambda t, y: [y[1], -m * g * d * math.cos(y[0] + phi) / inertia],
                      (0.0, 1.5), [0.0, 0.0], t_eval=res.t, rtol=1e-13, atol=1e-13)
    assert res.status == "success", res.message
    np.testing.assert_allclose(res.coordinate("plate.angle"), exact.y[0], atol=1e-7)
