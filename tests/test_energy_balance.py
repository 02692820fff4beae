"""The energy balance E(t) − E(0) − W(t) measures the solver, whatever the output grid.

The work W of each damper, load and driver is integrated along the integrator's steps
(`mechsim.results.work`). Integrated over the output samples instead (`work=False`, the
former behaviour), the balance of a damped spring-mass at rtol 1e-10 read 3.1e-4 with one
sample per step and a driven slider-crank's 0.9 at samples 10 ms apart."""

import math

import numpy as np
import pytest
from scipy.integrate import simpson

import mechsim as ms
from mechsim.formulations import METHODS

RTOL = 1e-10
OUTPUTS = (None, 1e-2, 1e-3)


def damped_spring_mass():
    return ms.examples.spring_mass(mass=2.0, stiffness=800.0, stretch=0.05, damping=4.0)


def torque_driven_four_bar():
    """A Grashof crank-rocker under gravity whose crank is turned by a varying torque, with a
    damper from the coupler's end to the ground."""
    mech = ms.examples.general_four_bar(0.2, 0.6, 0.5, 0.7, 0.3,
                                        name="torque-driven four-bar")
    mech.add(ms.Torque(mech.body("crank"), lambda t: 3.0 + 2.0 * math.sin(5.0 * t),
                       name="motor"))
    mech.add(ms.Spring(mech.ground, mech.body("coupler"), at_a=(0.4, 0.8),
                       at_b=mech.joint("B").at, stiffness=0.0, damping=0.5, name="damper"))
    return mech


CASES = {
    "damped spring-mass": (damped_spring_mass, 2.0),
    "driven slider-crank": (lambda: ms.examples.slider_crank(driven=True), 0.1),
    "torque-driven four-bar": (torque_driven_four_bar, 2.0),
}


@pytest.mark.parametrize("output_step", OUTPUTS)
@pytest.mark.parametrize("case", CASES)
def test_energy_balance_is_within_100_rtol_whatever_the_output(case, output_step):
    build, t_end = CASES[case]
    res = build().simulate(t_end=t_end, rtol=RTOL, atol=1e-12, output_step=output_step)
    assert res.success, res.message
    assert np.max(np.abs(res.energy_drift)) <= 100 * RTOL
    assert "integrated with the motion" in res.energy.includes
    # Something really did work: the balance is not trivially zero.
    assert np.max(np.abs(res.energy.work)) > 1e-3 * res.energy_scale


def test_the_damper_dissipates_the_closed_form_energy():
    """W of the damper against the exact damped oscillation: E(t) − E(0) of x(t) in closed
    form, at samples 0.1 s apart (between steps)."""
    m, k, c, x0 = 2.0, 800.0, 4.0, 0.05
    res = damped_spring_mass().simulate(t_end=2.0, rtol=RTOL, atol=1e-12, output_step=0.1)
    wn, zeta = math.sqrt(k / m), c / (2 * math.sqrt(k * m))
    wd = wn * math.sqrt(1 - zeta**2)
    t = res.t
    decay = np.exp(-zeta * wn * t)
    x = x0 * decay * (np.cos(wd * t) + zeta * wn / wd * np.sin(wd * t))
    xd = -x0 * decay * (wn**2 / wd) * np.sin(wd * t)
    energy = 0.5 * m * xd**2 + 0.5 * k * x**2
    assert res.energy.channels == ("spring 'spring' (damping)",)
    np.testing.assert_allclose(res.energy.work_by[:, 0], energy - energy[0],
                               atol=100 * RTOL * energy[0])


def test_each_channel_is_kept_apart():
    """The torque's work against ∫ τ ω dt over the run's own motion sampled every 0.1 ms
    (Simpson, fourth order: ~1e-13 here); the damper only dissipates."""
    res = torque_driven_four_bar().simulate(t_end=2.0, rtol=RTOL, atol=1e-12,
                                            output_step=1e-4)
    assert res.energy.channels == ("spring 'damper' (damping)", "load 'motor'")
    omega = res.v[:, res.coordinate_names.index("crank.angle")]
    power = (3.0 + 2.0 * np.sin(5.0 * res.t)) * omega
    assert res.energy.work_by[-1, 1] == pytest.approx(simpson(power, x=res.t), abs=1e-8)
    damper = res.energy.work_by[:, 0]
    assert damper[-1] < -1e-3 and np.all(np.diff(damper) <= 1e-13)
    np.testing.assert_allclose(res.energy.work, res.energy.work_by.sum(axis=1))


@pytest.mark.parametrize("method", sorted(m for m in METHODS if m != "ss-newmark"))
def test_every_method_balances_the_damped_spring_mass(method):
    res = damped_spring_mass().simulate(t_end=1.0, rtol=1e-9, atol=1e-11, method=method,
                                        output_step=1e-2)
    assert res.success, res.message
    assert np.max(np.abs(res.energy_drift)) <= 100 * 1e-9


def test_without_the_integral_the_result_says_the_balance_follows_the_samples(tmp_path):
    mech = ms.examples.slider_crank(driven=True)
    res = mech.simulate(t_end=0.1, rtol=RTOL, atol=1e-12, output_step=1e-2, work=False)
    assert "output samples" in res.energy.includes
    assert np.max(np.abs(res.energy_drift)) > 1e-3          # the samples' spacing, not the solver
    full = mech.simulate(t_end=0.1, rtol=RTOL, atol=1e-12, output_step=1e-2)
    back = ms.load_result(full.save(tmp_path / "r"))
    np.testing.assert_array_equal(back.energy.work_by, full.energy.work_by)
    assert back.energy.includes == full.energy.includes
    np.testing.assert_allclose(back.energy_drift, full.energy_drift, atol=1e-15)


def test_samples_hold_the_constraints_as_the_steps_do():
    """Output samples between steps (dense output, and a passage bridge's polynomial) are
    projected like the steps: on the double four-bar through its two passages, samples
    1 ms apart held 6e-10 where the steps held 4e-15."""
    mech = ms.examples.double_four_bar()
    for method in ("projection", "hybrid"):
        steps = mech.simulate(t_end=2.0, rtol=1e-8, atol=1e-10, method=method)
        samples = mech.simulate(t_end=2.0, rtol=1e-8, atol=1e-10, method=method,
                                output_step=1e-3)
        assert len(samples.singular_passages) == 2
        assert samples.constraint_violation.max() <= max(
            10 * steps.constraint_violation.max(), 1e-11)


def _powers(mech, t_end):
    """The powers of a run's samples in one call (`work_rates_many`) and state by state
    (`work_rates`), and the run."""
    res = mech.simulate(t_end=t_end, rtol=1e-8, atol=1e-10, output_step=1e-3)
    assert res.success, res.message
    p = mech.problem()
    many = p.work_rates_many(res.t, res.q, res.v)
    one = np.array([p.work_rates(t, q, v) for t, q, v in zip(res.t, res.q, res.v)])
    assert many.shape == one.shape == (len(res.t), len(res.energy.channels))
    return many, one, res


def _powers_alike(mech, t_end):
    """(largest difference of `_powers`' two ways, largest power)."""
    many, one, _ = _powers(mech, t_end)
    return np.max(np.abs(many - one)), np.max(np.abs(one))


def test_many_states_powers_equal_each_state_s_through_a_singular_configuration():
    """A parallelogram driven through its aligned position (Φ_q loses rank there) and
    pulled by a damper: the drivers' λᵀΦ_t of all samples at once (compiled where the
    engine takes the problem) equal each sample's to round-off, which λ's condition
    scales (the aligned position's neighbours: cond(J̃) up to 1e6, differences of 2e-11 W
    in 10 W under another BLAS kernel's round-off), the damper's to its own round-off."""
    from mechsim.linalg import sparse
    mech = ms.examples.turning_parallelogram(1.0, 2.0, 0.5, 2.0)
    mech.add(ms.Driver(mech.joint("A"), "0.5 + 2*t + 0.3*sin(3*t)"))
    mech.add(ms.Spring(mech.ground, mech.body("coupler"), at_a=(1.0, 2.0),
                       at_b=mech.joint("B").at, stiffness=0.0, damping=0.5, name="damper"))
    with pytest.warns(UserWarning, match="initial velocit"):
        many, one, res = _powers(mech, 2.0)
    peak = np.max(np.abs(one))
    assert peak > 1.0
    p = mech.problem()
    cond = np.array([(lambda s: s[0] / s[-1])(np.linalg.svd(
        sparse.dense(p.algebra.scaled_jacobian(q, t)), compute_uv=False))
        for t, q in zip(res.t, res.q)])
    damper, driver = ([k for k, c in enumerate(res.energy.channels) if kind in c]
                      for kind in ("damper", "driver"))
    eps = np.finfo(float).eps
    assert np.all(np.abs(many - one)[:, damper] <= 16 * eps * peak)
    assert np.all(np.abs(many - one)[:, driver] <= 64 * eps * cond[:, None] * peak)


def test_many_states_powers_with_friction_equal_each_state_s():
    """A driven slider-crank with friction in all four joints: the frictions' and the
    driver's powers of all samples at once (friction solved at all states together,
    `FrictionModel.solve_many`) equal each sample's alone."""
    mech = ms.examples.slider_crank(driven=True, crank_speed=100.0)
    for j in mech.joints:
        size = {"radius": 0.01} if j.kind == "revolute" else {"length": 0.02}
        mech.add(ms.Friction(j, mu=0.15, **size))
    difference, peak = _powers_alike(mech, 0.03)
    assert peak > 100.0 and difference <= 1e-12 * peak          # (3.5 kW at the motor)


def _loaded_four_bar(function_load=False):
    """A crank-rocker carrying a damped and an undamped spring, a damped torsion spring,
    a point force and a torque (and, with `function_load`, a force given as a function)."""
    mech = ms.examples.general_four_bar(0.2, 0.6, 0.5, 0.7, 0.3, name="loaded four-bar")
    crank, coupler, rocker = (mech.body(n) for n in ("crank", "coupler", "rocker"))
    mech.add(ms.Spring(mech.ground, coupler, at_a=(0.4, 0.8), at_b=mech.joint("A").at,
                       stiffness=30.0, damping=0.5, name="damper"))
    mech.add(ms.Spring(crank, rocker, at_a=mech.joint("A").at, at_b=mech.joint("B").at,
                       stiffness=20.0, name="spring"))
    mech.add(ms.RotationalSpring(coupler, rocker, 2.0, damping=0.1))
    mech.add(ms.Force(coupler, (1.5, -2.0), at=mech.joint("B").at))
    mech.add(ms.Torque(crank, 0.7, name="motor"))
    if function_load:
        mech.add(ms.Force(rocker, lambda t: (math.sin(t), 0.0), at=mech.joint("B").at))
    return mech


@pytest.mark.parametrize("function_load", [False, True])
def test_the_loads_of_many_states_equal_each_state_s(function_load):
    """Q and the loads' powers at a run's samples in one call (springs, torsion spring,
    constant force and torque: vectorized; with a function load: state by state) against
    `forces` and `powers` state by state."""
    mech = _loaded_four_bar(function_load)
    res = mech.simulate(t_end=1.0, rtol=1e-8, atol=1e-10, output_step=1e-2)
    assert res.success, res.message
    loads = mech.problem().load_model
    assert loads.rigid_only is not function_load
    F = loads.forces_at(res.t, res.q, res.v)
    P = loads.powers_at(res.t, res.q, res.v)
    F1 = np.array([loads.forces(t, q, v) for t, q, v in zip(res.t, res.q, res.v)])
    P1 = np.array([loads.powers(t, q, v) for t, q, v in zip(res.t, res.q, res.v)])
    assert P.shape == P1.shape == (len(res.t), len(loads.work_channels)) == \
        (len(res.t), 4 + function_load)
    np.testing.assert_allclose(F, F1, rtol=0, atol=1e-13 * np.max(np.abs(F1)))
    np.testing.assert_allclose(P, P1, rtol=0, atol=1e-13 * np.max(np.abs(P1)))
    assert np.max(np.abs(P1)) > 0.1 and np.all(P1[:, 0] <= 0.0)     # the damper dissipates


@pytest.mark.parametrize("omega", [4.0, 8.0])
def test_the_integral_of_known_powers_meets_its_tolerance_at_every_sample(omega):
    """Two channels, cos ωt and ½ sin 3ωt e^(−t), over steps of 0.25 s (1 to 6 radians of
    the faster one a step): W at three samples in each step against the closed-form
    integrals, within the tolerance asked of the pieces (1e-10 of the peak power, over the
    run's 2 s; the test on W rather than on the power, `work._SPREAD`, loosens each piece's
    test 8.5×). Where the power is too fast for three halvings the pieces are counted as
    unresolved, which the run's message reports."""
    from mechsim.results.work import WorkIntegral
    k, tol = 3 * omega, 1e-10

    def exact(t):
        return np.array([math.sin(omega * t) / omega,
                         0.5 * (k - math.exp(-t) * (math.sin(k * t) + k * math.cos(k * t)))
                         / (1 + k * k)])

    def powers(T, Q, V):
        return np.column_stack([np.cos(omega * T), 0.5 * np.sin(k * T) * np.exp(-T)])

    work = WorkIntegral(["a", "b"], powers, tol, 0.0, 2.0)
    nowhere = lambda ts: (np.zeros((len(ts), 1)), np.zeros((len(ts), 1)))  # noqa: E731
    error = 0.0
    for a in np.arange(0.0, 2.0, 0.25):
        times = np.linspace(a, a + 0.25, 4)[1:]
        W = work.add(a, a + 0.25, nowhere, times)
        error = max(error, max(np.max(np.abs(w - exact(t))) for t, w in zip(times, W)))
    assert work.unresolved == 0 and work.peak > 0.99
    assert 0.0 < error <= tol * work.peak * 2.0
    too_fast = WorkIntegral(["a", "b"], lambda T, Q, V: powers(4 * T, Q, V), tol, 0.0, 2.0)
    too_fast.add(0.0, 0.25, nowhere)
    assert too_fast.unresolved > 0
