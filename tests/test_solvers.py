"""The constrained solvers (issue: partitioning, projection, hybrid, Adams PECE).

Every method of the registry passes the same analytic tests; the hybrid manager passes the
singular configurations of the seed's parallelogram and of the IFToMM double four-bar on the
right branch and reports them; the Adams integrator shows its order."""

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.special import ellipk

import mechsim as ms
from mechsim.examples import parallelogram_exact, slider_crank_position
from mechsim.formulations import METHODS
from mechsim.integrators import AdamsPECE

# Tolerance-driven methods; the fixed-step "ss-newmark" has its own convergence test.
ALL_METHODS = tuple(sorted(m for m, cls in METHODS.items() if cls.default_integrator != "trapezoidal"))
INTEGRATORS = ("adams", "DOP853")


def crossing_times(t, theta):
    """Times where the crank passes horizontal (θ ≡ 0 mod π): the singular configurations."""
    s = np.sin(theta)
    idx = np.flatnonzero(np.sign(s[:-1]) * np.sign(s[1:]) < 0)
    return t[idx] - s[idx] * (t[idx + 1] - t[idx]) / (s[idx + 1] - s[idx])


# --- the same analytic tests for every method ----------------------------------------------
@pytest.mark.parametrize("integrator", INTEGRATORS)
@pytest.mark.parametrize("method", ALL_METHODS)
def test_double_four_bar_before_its_first_singularity(method, integrator):
    res = ms.examples.double_four_bar().simulate(t_end=0.6, method=method, rtol=1e-9,
                                                 atol=1e-11, output_step=0.02,
                                                 integrator=integrator)
    assert res.status == "success", res.message
    theta, _ = parallelogram_exact(res.t, math.pi / 2, -1.0, n=2)
    tip = res.point("crank3", (0.5, 0.0)) - (2.0, 0.0)
    assert np.max(np.hypot(tip[:, 0] - np.cos(theta), tip[:, 1] - np.sin(theta))) < 1e-7
    assert np.max(np.abs(res.energy_drift)) < 1e-7
    assert res.constraint_violation.max() < 1e-8
    assert res.singular_passages == [] and res.switches == []


@pytest.mark.parametrize("method", ALL_METHODS)
def test_pendulum_period_every_method(method):
    L, m, g, alpha = 0.8, 1.5, 9.81, math.radians(120)
    mech = ms.examples.pendulum(length=L, mass=m, angle=-math.pi / 2 + alpha)
    period = 4.0 * math.sqrt((L**2 / 3) / (g * L / 2)) * ellipk(math.sin(alpha / 2) ** 2)
    res = mech.simulate(t_end=period, method=method, rtol=1e-10, atol=1e-12,
                        output_step=period / 2, integrator="adams")
    angle = res.coordinate("rod.angle")
    assert abs(angle[1] - (-math.pi / 2 - alpha)) < 1e-6
    assert abs(angle[2] - angle[0]) < 1e-6


@pytest.mark.parametrize("method", ALL_METHODS)
def test_driven_crank_and_energy_balance_every_method(method):
    """A driver does work: the total energy changes by ~5.7 J, the balance with the driver's
    work (λᵀΦ_t integrated over time) stays closed."""
    mech = ms.examples.pendulum(length=0.5, mass=2.0, angle=0.3)
    mech.add(ms.Driver(mech.joint("pivot"), "2*t + 0.5*sin(3*t)"))
    res = mech.simulate(t_end=2.0, method=method, rtol=1e-9, atol=1e-11, output_step=0.005)
    t = res.t
    np.testing.assert_allclose(res.coordinate("rod.angle") - 0.3, 2 * t + 0.5 * np.sin(3 * t),
                               atol=1e-8)
    assert np.ptp(res.energy.total) > 5.0
    assert np.max(np.abs(res.energy_drift)) < 1e-7


def test_damper_work_closes_the_energy_balance():
    res = ms.examples.spring_mass(damping=12.0).simulate(t_end=1.0, rtol=1e-10, atol=1e-12,
                                                        output_step=0.002)
    assert res.energy.work[-1] < -0.9            # the damper took almost all of the 1 J
    assert np.max(np.abs(res.energy_drift)) < 1e-6


# --- singular configurations ----------------------------------------------------------------
@pytest.fixture(scope="module")
def parallelogram_runs():
    mech = ms.examples.four_bar()
    runs = {m: mech.simulate(t_end=2.0, method=m, rtol=1e-8, atol=1e-10, max_step=0.01,
                             output_step=0.002)
            for m in ("hybrid", "projection")}
    # LU alone with the Adams integrator grinds through the first passage (~90k steps, see
    # the issue notes); DOP853 shows its behaviour in a fraction of the time.
    runs["lu"] = mech.simulate(t_end=2.0, method="lu", rtol=1e-8, atol=1e-10, max_step=0.01,
                               output_step=0.002, integrator="DOP853")
    return runs


@pytest.mark.parametrize("method", ["hybrid", "projection"])
def test_falling_parallelogram_passes_its_singularities(parallelogram_runs, method):
    res = parallelogram_runs[method]
    assert res.status == "success", res.message
    theta, _ = parallelogram_exact(res.t, math.radians(10), 0.0)
    err = np.abs(np.angle(np.exp(1j * (res.coordinate("crank.angle") - theta))))
    assert err.max() < 1e-6
    # The rocker stays parallel to the crank: no jump to the other branch.
    assert np.max(np.abs(res.coordinate("rocker.angle") - res.coordinate("crank.angle"))) < 1e-6
    assert np.max(np.abs(res.energy_drift)) < 1e-6
    found = [p.t_min for p in res.singular_passages]
    assert len(found) == 3
    # The monitor's minima on the exact crossings (measured within 1e-5 s).
    np.testing.assert_allclose(found, crossing_times(res.t, theta), atol=1e-4)
    assert all(set(p.joints) & {"A", "B", "C", "D"} for p in res.singular_passages)


def test_hybrid_switches_around_each_passage(parallelogram_runs):
    res = parallelogram_runs["hybrid"]
    into = [s for s in res.switches if s.to_method == "projection"]
    back = [s for s in res.switches if s.to_method == "lu"]
    assert len(into) == 3 and len(back) == 3
    for p, s_in, s_out in zip(res.singular_passages, into, back):
        assert s_in.t <= p.t_min <= s_out.t
        assert "singular" in s_in.reason
    assert res.stats["switches"] == 6


def test_lu_alone_reports_its_passages(parallelogram_runs):
    """LU partitioning alone is not guaranteed to keep the branch (the seed paper shows it
    jumping at the second passage); whatever it does, it finishes and says where the
    singular configurations were."""
    res = parallelogram_runs["lu"]
    assert res.status == "success"
    assert res.stats["partitions"] >= 1
    theta, _ = parallelogram_exact(res.t, math.radians(10), 0.0)
    # LU's own motion places its first passage within 2e-3 s of the exact one (measured).
    assert len(res.singular_passages) >= 1 and res.singular_passages[0].t_min == \
        pytest.approx(crossing_times(res.t, theta)[0], abs=5e-3)


def test_double_four_bar_ten_seconds_hybrid():
    """IFToMM A02 over 10 s: ten singular configurations, all passed on the branch."""
    res = ms.examples.double_four_bar().simulate(t_end=10.0, method="hybrid", rtol=1e-8,
                                                 atol=1e-10, output_step=0.01)
    assert res.status == "success", res.message
    theta, _ = parallelogram_exact(res.t, math.pi / 2, -1.0, n=2)
    tip = res.point("crank1", (0.5, 0.0))
    assert np.max(np.hypot(tip[:, 0] - np.cos(theta), tip[:, 1] - np.sin(theta))) <= 1e-6
    assert np.max(np.abs(res.energy_drift)) <= 1e-6
    exact = crossing_times(res.t, theta)
    assert len(exact) == 10 and exact[0] == pytest.approx(0.714, abs=0.002)
    found = np.array([p.t_min for p in res.singular_passages])
    assert len(found) == 10
    np.testing.assert_allclose(found, exact, atol=2e-4)       # measured within 3.1e-5 s


@pytest.mark.slow
def test_forty_window_four_bar_twenty_seconds():
    """243 coordinates, twenty passages, each crossed by the passage bridge, on the exact
    parallelogram branch. A long study (its code generation alone takes most of a minute):
    `python3 -m pytest -m slow`, and `mechsim bench forty-window`."""
    res = ms.examples.double_four_bar(40).simulate(t_end=20.0, method="hybrid", rtol=1e-8,
                                                   atol=1e-10, output_step=0.05)
    assert res.status == "success", res.message
    theta, _ = parallelogram_exact(res.t, math.pi / 2, -1.0, n=40)
    tip = res.point("crank1", (0.5, 0.0))
    assert np.max(np.hypot(tip[:, 0] - np.cos(theta), tip[:, 1] - np.sin(theta))) <= 1e-5
    assert len(res.singular_passages) == 20 and res.stats["bridges"] == 20


@pytest.mark.parametrize("method", ["lu", "qr"])
def test_slider_crank_partitioning_through_dead_centres(method):
    """Free-running slider-crank: the slider coordinate cannot be independent at a dead
    centre; partitioning picks another set instead of failing."""
    r, l = 0.15, 0.30
    mech = ms.examples.slider_crank(crank_angle=math.radians(60))
    res = mech.simulate(t_end=0.15, method=method, rtol=1e-9, atol=1e-11, output_step=5e-4,
                        integrator="adams")
    assert res.status == "success", res.message
    theta = res.coordinate("crank.angle")
    assert theta[-1] - theta[0] > 4 * math.pi
    np.testing.assert_allclose(res.coordinate("slider.x"), slider_crank_position(theta, r, l),
                               atol=1e-8)
    assert np.max(np.abs(res.energy_drift)) < 1e-6


def test_overdriven_slider_crank_fails_with_a_named_joint_and_keeps_its_work():
    """Pushing the slider past full extension: no configuration exists. The run stops with a
    status and a message naming joints, and returns what it computed before."""
    mech = ms.examples.slider_crank(crank_angle=math.pi / 2, crank_speed=0.0)
    mech.add(ms.Driver(mech.joint("slide"), "0.5*t"))
    res = mech.simulate(t_end=1.0, method="lu", rtol=1e-8, atol=1e-10, output_step=0.01)
    assert res.status == "failed"
    assert any(name in res.message for name in ("'O'", "'A'", "'B'", "'slide'", "O, ", "A, "))
    # Full extension (0.45 m) is reached at t = (0.45 − 0.2598)/0.5 ≈ 0.380 s.
    assert 0.3 < res.t[-1] < 0.39 and len(res.t) > 30
    np.testing.assert_allclose(res.coordinate("slider.x"), math.sqrt(0.3**2 - 0.15**2)
                               + 0.5 * res.t, atol=1e-8)


# --- the Adams PECE integrator ---------------------------------------------------------------
@pytest.mark.parametrize("max_order", [2, 4, 6])
def test_adams_order_from_work_precision_slope(max_order):
    """With its order capped at k the PECE pair is of order k+1: the global error falls like
    nfev^−(k+1). Measured as a log–log slope over a tolerance sweep (diffrax-style)."""
    f = lambda t, y: np.array([y[1], -y[0] + 0.1 * np.sin(t)])
    t_end = 10.0
    exact = solve_ivp(f, (0, t_end), [1.0, 0.0], method="DOP853", rtol=1e-13, atol=1e-14).y[:, -1]
    errs, work = [], []
    for tol in np.logspace(-5, -10 + (4 - max_order if max_order < 4 else 0), 6):
        s = solve_ivp(f, (0, t_end), [1.0, 0.0], method=AdamsPECE, rtol=tol, atol=tol * 1e-2,
                      max_order=max_order)
        errs.append(np.max(np.abs(s.y[:, -1] - exact)))
        work.append(s.nfev)
    slope = -np.polyfit(np.log(work), np.log(errs), 1)[0]
    assert abs(slope - (max_order + 1)) < 0.25 * (max_order + 1), slope


def test_adams_dense_output_and_coefficients():
    from mechsim.integrators.adams import integration_weights
    # Uniform nodes reproduce the classical Adams–Moulton and –Bashforth coefficients.
    np.testing.assert_allclose(integration_weights(np.array([1.0, 0, -1, -2]), 1.0)[0] * 24,
                               [9, 19, -5, 1], atol=1e-12)
    np.testing.assert_allclose(integration_weights(np.array([0.0, -1, -2]), 1.0)[0] * 12,
                               [23, -16, 5], atol=1e-12)
    s = solve_ivp(lambda t, y: -y, (0, 5), [1.0], method=AdamsPECE, rtol=1e-9, atol=1e-12,
                  dense_output=True)
    tt = np.linspace(0, 5, 501)
    assert np.max(np.abs(s.sol(tt)[0] - np.exp(-tt))) < 1e-8


def test_adams_warm_restart_in_new_coordinates():
    """After a change of coordinates z = A y the Adams history, re-expressed as A f at the
    earlier times, lets a fresh solver go on at the old order: it needs far fewer steps
    than a cold start from order 1, and ends as accurately."""
    A = np.array([[2.0, 1.0], [-1.0, 3.0]])
    Ainv = np.linalg.inv(A)
    f = lambda t, y: np.array([y[1], -y[0] + 0.1 * np.sin(t)])      # noqa: E731
    g = lambda t, z: A @ f(t, Ainv @ z)                                # noqa: E731
    t_end, kw = 8.0, dict(rtol=1e-10, atol=1e-12)
    exact = solve_ivp(f, (0, t_end), [1.0, 0.0], method="DOP853", rtol=1e-13, atol=1e-14).y[:, -1]
    old = AdamsPECE(f, 0.0, np.array([1.0, 0.0]), t_end, **kw)
    while old.t < 3.0:
        old.step()
    assert old.order >= 6

    def finish(solver):
        steps = 0
        while solver.status == "running":
            solver.step()
            steps += 1
        return steps, np.max(np.abs(Ainv @ solver.y - exact))

    cold_steps, cold_err = finish(AdamsPECE(g, old.t, A @ old.y, t_end, first_step=old.h, **kw))
    warm = AdamsPECE(g, old.t, A @ old.y, t_end, **kw)
    warm.seed_history(old.ts[:-1], [A @ fk for fk in old.fs[:-1]], old.order, old.h)
    assert warm.order == old.order
    warm_steps, warm_err = finish(warm)
    assert warm_steps < 0.8 * cold_steps, (warm_steps, cold_steps)
    assert warm_err < 1e-8 and cold_err < 1e-8
    with pytest.raises(ValueError, match="increase"):
        warm.seed_history([warm.t + 1.0], [np.zeros(2)], 2, 0.1)


def test_hybrid_with_adams_restarts_warm_after_switches_and_bridges(monkeypatch):
    """With the paper's integrator, each switch, new partition and bridge gives the fresh
    Adams solver the history of the last states in the new coordinates (from
    `derivative`), instead of a climb from order 1 at every one of them. On the seed's
    parallelogram (2 s, 3 passages, 6 switches) the run stays on the branch to 1e-9; every
    switch and bridge hands over a history of order 2 or more (`mechsim bench costs`,
    adams-hybrid: 273–278 steps on four BLAS kernels; 470 with cold restarts)."""
    from mechsim.integrators import AdamsPECE
    seeded = []
    seed = AdamsPECE.seed_history
    monkeypatch.setattr(AdamsPECE, "seed_history", lambda self, ts, fs, order, h:
                        seeded.append(order) or seed(self, ts, fs, order, h))
    res = ms.examples.four_bar().simulate(t_end=2.0, method="hybrid", integrator="adams",
                                          rtol=1e-8, atol=1e-10, max_step=0.01,
                                          output_step=0.002)
    assert res.status == "success", res.message
    assert res.stats["bridges"] == 3 and len(res.switches) == 6
    assert len(seeded) >= res.stats["bridges"] + len(res.switches) and min(seeded) >= 2
    theta, _ = parallelogram_exact(res.t, math.radians(10), 0.0, n=1)
    tip = res.point("crank", (0.5, 0.0))
    assert np.max(np.hypot(tip[:, 0] - np.cos(theta), tip[:, 1] - np.sin(theta))) < 1e-9


def test_a_run_stuck_at_a_passage_stops_early_naming_the_joints():
    """LU alone at rtol 1e-6 cannot pass the flexible four-bar's first passage: its steps
    collapse to a few 1e-12 s at 0.172 s. The run stops once 2000 steps have advanced less
    than 1e-7 of its span, with its partial result and a message naming the joints, instead
    of grinding on (it took 20001 steps and 23 s to reach a step limit). (At rtol 1e-8 the
    passage's band is integrated at 1e-9, `Tolerances.through_passage`, and whether LU's
    partition gets through it depends on the BLAS kernel's round-off.)"""
    res = ms.examples.flexible_four_bar().simulate(t_end=1.2, method="lu", rtol=1e-6,
                                                   atol=1e-8, max_step=5e-4,
                                                   integrator="adams")
    assert res.status == "failed" and "the steps collapsed" in res.message
    assert "joints A, B, C, D" in res.message
    # The stall rule stops it (2470–2568 steps on four BLAS kernels, `mechsim bench costs`,
    # stuck-lu, rtol 1e-6), not a step limit: the message above is the rule's.
    assert 0.17 < res.t[-1] < 0.175
    assert len(res.t) > 300                           # the work before the passage is kept


def test_hybrid_with_adams_does_not_creep_up_to_a_passage():
    """Ahead of a passage each LU step is held to half the way to the predicted entry; with
    short Adams steps that used to go on until the 1 µs floor (the double four-bar's second
    passage at 1.21 s: 20 steps halving to 1e-6 s, 20 more climbing back). After two held
    steps the manager switches to projection instead: from the return to LU after the
    first passage up to the second passage no step is shorter than 1e-4 s (the shortest
    3.5e-3 to 4.1e-3 s on four BLAS kernels, 50–52 steps). (After a bridge, before that
    return, Adams starts again from the bridge's own step, 8e-5 to 2e-4 s: not the held
    LU steps this is about.)"""
    res = ms.examples.double_four_bar(2).simulate(t_end=1.6, method="hybrid", rtol=1e-8,
                                                  atol=1e-10, integrator="adams")
    assert res.status == "success" and len(res.switches) == 4 and res.stats["bridges"] == 2
    second = res.singular_passages[1].t_start
    back = res.switches[1]                   # to LU, after the first passage
    assert back.to_method == "lu" and back.t < second
    ends = res.t[1:]
    h = np.diff(res.t)[(ends > back.t) & (ends <= second)]  # the LU phase up to it
    assert h.min() > 1e-4, h.min()


def test_adams_runs_do_not_depend_on_the_runs_before_them():
    """The Adams weights are cached by node pattern across solvers and runs (the patterns
    recur after each restart); they are computed from the snapped pattern itself, so what
    earlier runs cached cannot change a run."""
    mech = ms.examples.four_bar()
    kw = dict(t_end=1.0, integrator="adams", rtol=1e-8, atol=1e-10, max_step=0.01,
              output_step=0.01)
    first = mech.simulate(method="hybrid", **kw)
    mech.simulate(method="projection", **{**kw, "rtol": 3e-9})
    again = mech.simulate(method="hybrid", **kw)
    assert first.stats["steps"] == again.stats["steps"]
    np.testing.assert_array_equal(first.q, again.q)


def test_ss_newmark_on_a_mechanism_is_second_order():
    """The average-velocity (trapezoidal) rule on the LU-reduced ODE: error ∝ h²."""
    mech = ms.examples.double_four_bar()
    hs = [0.004, 0.002, 0.001]
    errs = []
    for h in hs:
        res = mech.simulate(t_end=0.6, method="ss-newmark", h=h, rtol=1e-9, atol=1e-11,
                            output_step=0.02)
        assert res.status == "success" and res.stats["steps"] == round(0.6 / h)
        theta, _ = parallelogram_exact(res.t, math.pi / 2, -1.0, n=2)
        tip = res.point("crank1", (0.5, 0.0))
        errs.append(np.max(np.hypot(tip[:, 0] - np.cos(theta), tip[:, 1] - np.sin(theta))))
    slope = np.polyfit(np.log(hs), np.log(errs), 1)[0]
    assert abs(slope - 2.0) < 0.1, slope
    with pytest.raises(ValueError, match="fixed size: give `h`"):
        mech.simulate(t_end=0.1, method="ss-newmark")


@pytest.mark.parametrize("theta", [0.0, 1e-7, 2e-5, 1e-3])
def test_projection_accelerations_on_and_near_the_singular_configuration(theta):
    """The parallelogram at crank angle θ (θ = 0: all bars aligned, Φ_q loses rank) on its
    branch, where the crank's angular acceleration is −K/M_eff cos θ exactly. Inside the
    truncation band the lost direction's constraint acceleration (0/0 on the configuration)
    comes from the slopes across it; dropping it instead was off by 5 % on the double
    four-bar and collapsed the step size there."""
    from mechsim.formulations.projection import Projection
    mech = ms.examples.four_bar()
    prob = mech.problem()
    w = -2.0
    c, s = math.cos(theta), math.sin(theta)
    q = np.array([0.5 * c, 0.5 * s, theta, c + 0.5, s, 0.0, 1 + 0.5 * c, 0.5 * s, theta])
    v = np.array([-0.5 * s * w, 0.5 * c * w, w, -s * w, c * w, 0.0, -0.5 * s * w,
                  0.5 * c * w, w])
    m_eff, k = ms.examples.parallelogram_constants(1)
    acc = Projection(prob, 1e-8, 1e-10).accelerations(0.0, q, v)
    exact = -k / m_eff * math.cos(theta)
    # In the band the value comes from slopes across it and carries round-off amplified
    # there: 3e-8 to 1.1e-7 relative, depending on the order of the generated code's sums.
    assert acc[2] == pytest.approx(exact, rel=5e-7)          # crank
    assert acc[8] == pytest.approx(exact, rel=5e-7)          # rocker
    assert abs(acc[5]) < 5e-7 * abs(exact)                   # the coupler does not turn


@pytest.mark.parametrize("theta", [0.0, 1e-7, 2e-5, 6e-5, 1e-3])
def test_projection_accelerations_through_a_double_singularity(theta):
    """The double four-bar loses two constraint directions at once (both windows flatten
    together, two singular values cross zero side by side). On its branch every crank has
    θ̈ = −K/M_eff cos θ exactly; inside the truncation band both lost directions'
    accelerations must be recovered together."""
    from mechsim.formulations.projection import Projection
    n, w = 2, -2.0
    prob = ms.examples.double_four_bar(n).problem()
    c, s = math.cos(theta), math.sin(theta)
    q, v = [], []
    for i in range(n + 1):                                    # cranks
        q += [i + 0.5 * c, 0.5 * s, theta]
        v += [-0.5 * s * w, 0.5 * c * w, w]
    for i in range(n):                                        # couplers
        q += [i + c + 0.5, s, 0.0]
        v += [-s * w, c * w, 0.0]
    q, v = np.array(q), np.array(v)
    assert np.max(np.abs(prob.phi(q, 0.0))) < 1e-15
    m_eff, k = ms.examples.parallelogram_constants(n)
    acc = Projection(prob, 1e-8, 1e-10).accelerations(0.0, q, v)
    exact = -k / m_eff * math.cos(theta)
    for i in range(n + 1):
        assert acc[3 * i + 2] == pytest.approx(exact, rel=1e-6), i
    for i in range(n):
        assert abs(acc[3 * (n + 1) + 3 * i + 2]) < 1e-5


def test_bench_repeat_keeps_each_runs_shortest_time():
    """`mechsim bench --repeat N` runs every case N times in rounds and reports one row per
    case with the same run (error, steps, evaluations) as a single repeat."""
    from mechsim.app import bench

    kw = dict(problems=["parallelogram"], methods=["projection", "lu"], rtols=[1e-5],
              progress=None)
    once = bench.run(**kw)
    thrice = bench.run(**kw, repeat=3)
    assert [(r.method, r.rtol) for r in thrice] == [("projection", 1e-5), ("lu", 1e-5)]
    for a, b in zip(once, thrice):
        assert (a.error, a.steps, a.rhs, a.passages) == (b.error, b.steps, b.rhs, b.passages)
        assert a.error < 1e-3 and b.passages == 3
    with pytest.raises(ValueError, match="repeat"):
        bench.run(**kw, repeat=0)


def test_bench_runs_the_seeds_projection_as_a_variant(monkeypatch, capsys):
    """`projection-svd` in `mechsim bench` is the projection method with
    factorization="svd": an SVD at almost every evaluation (all but the passage bridge's),
    the motion of the default projection, and the hybrid's ratio to it printed."""
    import mechsim.linalg.dense as dense
    from mechsim.app import bench

    calls = []
    svd = dense.svd
    monkeypatch.setattr(dense, "svd", lambda A: calls.append(A.shape) or svd(A))
    [seed] = bench.run(["parallelogram"], ["projection-svd"], [1e-6], progress=None)
    assert (seed.method, seed.status) == ("projection-svd", "success")
    assert len(calls) >= 0.8 * seed.rhs
    monkeypatch.setattr(dense, "svd", svd)
    rows = bench.run(["parallelogram"], ["projection", "hybrid"], [1e-6], progress=None)
    # The same motion to round-off (the two factorizations' round-off may move a step-size
    # decision: 204 against 205 steps with the Haswell and Sandybridge BLAS kernels).
    assert abs(rows[0].error - seed.error) < 1e-10
    ratios = bench.ratios(rows + [seed], 1e-6)["parallelogram"]
    assert ratios["hybrid/projection-svd"] == rows[1].wall_time / seed.wall_time
    with pytest.raises(ValueError, match="'projektion'; methods: .*projection-svd"):
        bench.run(["parallelogram"], ["lu", "projektion"], [1e-6], progress=None)
    from mechsim.app.cli import main
    capsys.readouterr()
    assert main(["bench", "parallelogram", "--methods", "lu,projektion"]) == 2
    out, err = capsys.readouterr()
    assert out == "" and "unknown method 'projektion'" in err      # refused before any run


def test_bench_compares_methods_at_equal_error():
    """The work–precision comparison at equal accuracy takes each method's cheapest
    successful run within each decade of error, skips failed runs however accurate, gives
    consecutive decades served by the same runs once, and stops where fewer than two
    methods get there."""
    from mechsim.app.bench import Row, equal_error, format_within

    def row(method, rtol, error, wall, status="success"):
        return Row("p", method, "DOP853", rtol, status, error, 0.0, wall, 10, 100, 1)

    rows = [row("lu", 1e-5, 9e-3, 1.0), row("lu", 1e-7, 9e-6, 2.0),
            row("projection", 1e-5, 9e-4, 0.5), row("projection", 1e-7, 9e-7, 3.0),
            row("hybrid", 1e-5, 2e-3, 0.4), row("hybrid", 1e-7, 5e-7, 1.5),
            row("hybrid", 1e-9, 1e-9, 0.1, status="failed")]
    table = equal_error(rows)
    assert [e for _, e, _ in table] == pytest.approx([1e-2, 1e-3, 1e-5, 1e-6])
    assert [{m: r.wall_time for m, r in best.items()} for _, _, best in table] == [
        {"lu": 1.0, "projection": 0.5, "hybrid": 0.4},
        {"lu": 2.0, "projection": 0.5, "hybrid": 1.5},
        {"lu": 2.0, "projection": 3.0, "hybrid": 1.5},
        {"projection": 3.0, "hybrid": 1.5}]
    line = format_within(*table[-1])
    assert line == ("within error 1e-06, p: projection 3.000 s (rtol 1e-07), "
                    "hybrid 1.500 s (rtol 1e-07), hybrid/projection = 0.50")
    assert equal_error([row("lu", 1e-5, 9e-3, 1.0)]) == []


def test_bench_says_which_runs_missed_twenty_rtol_and_what_a_loose_rtol_saves():
    """`bench.proportionality`: per method the runs within 20 rtol, naming those over it
    (a failed run counts as over), then each problem's time at its loosest rtol over its
    tightest."""
    from mechsim.app.bench import Row, proportionality

    def row(method, rtol, error, wall, status="success", problem="p"):
        return Row(problem, method, "DOP853", rtol, status, error, 0.0, wall, 10, 100, 1)

    rows = [row("hybrid", 1e-4, 1.5e-3, 0.4), row("hybrid", 1e-7, 2.5e-6, 1.6),
            row("hybrid", 1e-10, 1e-9, 2.0), row("lu", 1e-4, 1e-3, 0.2),
            row("lu", 1e-10, math.nan, 0.5, status="failed"),
            row("hybrid", 1e-6, 1.9e-5, 1.0, problem="q")]
    lines = proportionality(rows)
    assert lines[:2] == [
        "tolerance proportionality, hybrid: error ≤ 20 rtol in 3 of 4 runs; not: p at "
        "1e-07 (25 rtol)",
        "tolerance proportionality, lu: error ≤ 20 rtol in 1 of 2 runs; not: p at 1e-10 "
        "(failed)"]
    assert lines[2:] == ["p, hybrid: t(rtol 1e-04) / t(rtol 1e-10) = 0.20",
                         "p, lu: t(rtol 1e-04) / t(rtol 1e-10) = 0.40"]


@pytest.mark.parametrize("integrator", ["BDF", "LSODA", "Radau", "RK23"])
@pytest.mark.parametrize("method", ["projection", "hybrid"])
def test_every_scipy_integrator_carries_the_projection_method_through_passages(method,
                                                                               integrator):
    """The projection method keeps its state on the constraints after each step. BDF and
    LSODA take the correction into their history (the backward differences; LSODA's
    Nordsieck array, RWORK(21…) in ODEPACK's layout) instead of restarting at first order,
    where the double four-bar collapsed to microsecond steps and failed; LSODA, which reads
    its step bound only at a start, restarts when the bridge's landing needs a new bound.
    Through the first two passages at a local tolerance of 1e-6 (rtol 1e-4,
    `Tolerances.local`) every integrator bridges both."""
    rtol = 1e-4
    res = ms.examples.double_four_bar(2).simulate(t_end=2.0, method=method, rtol=rtol,
                                                  atol=1e-6, output_step=0.01,
                                                  integrator=integrator, max_steps=1200)
    assert res.status == "success", res.message
    # (95–397 steps by integrator on four BLAS kernels, `mechsim bench costs`)
    assert res.stats["bridges"] == 2
    theta, _ = parallelogram_exact(res.t, math.pi / 2, -1.0, n=2)
    tip = res.point("crank1", (0.5, 0.0))
    assert np.max(np.hypot(tip[:, 0] - np.cos(theta), tip[:, 1] - np.sin(theta))) <= 10 * rtol


def test_projection_with_the_seeds_svd_at_every_evaluation(parallelogram_runs, monkeypatch):
    """`factorization="svd"`: the seed's projection method, an SVD of J̃ at every evaluation
    and projection instead of the Cholesky factor of the Schur complement clear of the
    band. Both are exact there, so the motion agrees with the default run to round-off
    over the steps, while every evaluation pays an SVD."""
    import mechsim.linalg.dense as dense
    calls = []
    svd = dense.svd
    monkeypatch.setattr(dense, "svd", lambda A: calls.append(A.shape) or svd(A))
    mech = ms.examples.four_bar()
    res = mech.simulate(t_end=2.0, method="projection", rtol=1e-8, atol=1e-10, max_step=0.01,
                        output_step=0.002, factorization="svd")
    ref = parallelogram_runs["projection"]
    assert res.status == "success", res.message
    assert len(calls) >= res.stats["rhs_evaluations"] - res.stats["bridge_evaluations"]
    n_svd = len(calls)
    calls.clear()
    mech.simulate(t_end=2.0, method="projection", rtol=1e-8, atol=1e-10, max_step=0.01,
                  output_step=0.002)
    assert len(calls) < 0.2 * n_svd                 # the default: SVDs near the passages only
    np.testing.assert_allclose(res.coordinate("crank.angle"), ref.coordinate("crank.angle"),
                               atol=1e-10)
    assert [round(p.t_min, 3) for p in res.singular_passages] == \
        [round(p.t_min, 3) for p in ref.singular_passages]
    with pytest.raises(ValueError, match="factorization.*'qr'"):
        mech.simulate(t_end=0.1, method="projection", factorization="qr")


@pytest.mark.parametrize("method", ["lu", "qr", "svd"])
@pytest.mark.parametrize("scene", ["double four-bar", "driven slider-crank"])
def test_partitioned_output_samples_solved_together_match_one_by_one(method, scene,
                                                                      monkeypatch):
    """The output samples inside a step are solved for all at once (one chord Newton,
    stacked velocity solves): the same positions and velocities as solving for each sample
    alone, on the constraints, and the driver's speed exactly (Φ_t)."""
    from mechsim.formulations.base import Formulation
    from mechsim.formulations.partitioned import Partitioned
    if scene == "double four-bar":
        mech, t_end = ms.examples.double_four_bar(2), 1.0
    else:                      # with a pendulum hanging from the slider: one free DOF
        mech, t_end = ms.examples.slider_crank(driven=True, crank_speed=15.0), 0.5
        slider = mech.body("slider")
        x = float(slider.position[0])
        bob = mech.add(ms.RigidBody.rod("bob", (x, 0.0), (x + 0.1, -0.2), 0.5))
        mech.add(ms.Revolute(slider, bob, at=(x, 0.0), name="hang"))
    kw = dict(t_end=t_end, method=method, rtol=1e-9, atol=1e-11, output_step=t_end / 400)
    one_by_one = []
    alone_states = Formulation.states
    monkeypatch.setattr(Formulation, "states", lambda self, ts, Y: one_by_one.append(len(ts))
                        or alone_states(self, ts, Y))
    res = mech.simulate(**kw)
    assert sum(one_by_one) < 0.25 * res.t.size         # most solved together
    monkeypatch.setattr(Partitioned, "states", alone_states)
    alone = mech.simulate(**kw)
    assert res.status == alone.status == "success"
    np.testing.assert_array_equal(res.t, alone.t)
    np.testing.assert_allclose(res.q, alone.q, rtol=0, atol=1e-12)
    np.testing.assert_allclose(res.v, alone.v, rtol=0, atol=1e-9 * np.abs(alone.v).max())
    assert np.max(np.abs(res.constraint_violation)) < 1e-11
    if scene == "driven slider-crank":
        np.testing.assert_allclose(res.coordinate("crank.angle"), 15.0 * res.t, atol=1e-11)
        np.testing.assert_allclose(res.v[:, res.coordinate_names.index("crank.angle")], 15.0,
                                   rtol=1e-12)


def test_bench_driven_slider_crank_and_random_sweep(tmp_path, capsys):
    """`mechsim bench driven-slider-crank random`: the slider against its exact kinematics,
    and random mechanisms by the hybrid and projection, each error within 100 rtol of its
    reference; the summary compares their work."""
    from mechsim.app import bench
    (row,) = bench.run(["driven-slider-crank"], ["hybrid"], [1e-8], progress=None)
    assert row.status == "success" and row.error < 1e-8 and row.passages == 0
    rows = bench.random_run(count=6, rtol=1e-8, t_end=1.0, progress=None)
    assert len(rows) == 12 and {r.method for r in rows} == {"hybrid", "projection"}
    assert all(r.status == "success" and r.error < 100 * 1e-8 for r in rows)
    summary = bench.random_summary(rows)
    assert summary.startswith("random mechanisms (6): hybrid/projection wall time median")
    assert summary.endswith("failed: 0 and 0")
    (path,) = bench.write_random(rows, tmp_path)
    assert path.read_text().count("\n") == 13
