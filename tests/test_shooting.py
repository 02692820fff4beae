"""Periodic steady states by shooting (seed 002): Tables 1 and 2."""

import math

import numpy as np
import pytest

import mechsim as ms
from mechsim.shooting.oscillators import CoulombOscillator, LinearOscillator, equivalent_damping_amplitude

PAPER = dict(zeta=0.05, omega_n=100.0, delta_st=0.1, omega=100.0)


def repeats_itself(osc, x0, periods=5, tol=2e-6):
    """Integrate period after period (the forcing is T-periodic): the state comes back. A
    state shot to max|g| < 1e-6 lies within |g| / (1 − |λ|) of the fixed point (λ its
    largest Floquet multiplier, 0.4 for μ = 0.08), so later periods may differ from it by
    up to ~1.7e-6: the tolerance is 2e-6."""
    x = np.array(x0, float)
    for _ in range(periods):
        x = osc.flow(x).x[-1]
        if np.max(np.abs(x - x0)) >= tol:
            return False
    return True


def close(actual, expected, atol):
    """|actual − expected| ≤ atol componentwise (atol per component: printed digits)."""
    return bool(np.all(np.abs(np.asarray(actual) - np.asarray(expected)) <= np.asarray(atol)))


@pytest.mark.parametrize("guess, paper_nit", [((1.0, 150.0), 2), ((100.0, 900.0), 2),
                                              ((10000.0, 90000.0), 3)])
def test_table_1_linear_oscillator(guess, paper_nit):
    osc = LinearOscillator(**PAPER)
    sol = ms.shooting.solve(osc, guess, method="warner", tol=1e-6)
    assert sol.converged and sol.iterations <= paper_nit
    np.testing.assert_allclose(sol.x0, [0.0, 100.0], atol=1e-6)   # analytic, ν = 1
    assert osc.steady_amplitude() == pytest.approx(1.0)           # δ_st/(2ζ) at resonance
    # Floquet multipliers of a linear oscillator: e^{−ζ ω_n T} (twice, complex pair).
    np.testing.assert_allclose(np.abs(sol.floquet_multipliers),
                               math.exp(-0.05 * 100.0 * osc.period), rtol=1e-5)
    assert sol.stable


def test_coulomb_flow_matches_table_2_terminal_values():
    """The paper's Case 1 guesses and their printed terminal values x(2π/ω)."""
    osc = CoulombOscillator(**PAPER, mu=0.08)
    for guess, terminal in [((-0.014, 2.7), (-0.01468, 2.7180)),
                            ((-0.01414, 2.727), (-0.01475, 2.7292))]:
        xT = osc.flow(np.array(guess)).x[-1]
        assert close(xT, terminal, [6e-6, 6e-5]), xT


@pytest.mark.parametrize("method", ["warner", "newton"])
@pytest.mark.parametrize("guess", [(-0.014, 2.7), (-0.07, 10.0)])
def test_table_2_coulomb_mu_008(method, guess):
    osc = CoulombOscillator(**PAPER, mu=0.08)
    sol = ms.shooting.solve(osc, guess, method=method, tol=1e-6)
    assert sol.converged, sol.message
    assert close(sol.x0, [-0.01469, 2.7201], [5e-6, 5e-5]), sol.x0   # to the printed digits
    assert any(kind == "stick" for _, kind in sol.trajectory.events)
    assert repeats_itself(osc, sol.x0)
    assert sol.stable


def test_table_2_case_3_warner_fails_newton_succeeds():
    osc = CoulombOscillator(**PAPER, mu=0.08)
    bad = ms.shooting.solve(osc, (-1.1, 15.0), method="warner", max_iter=50)
    assert not bad.converged and "50 iterations" in bad.message and bad.x0.shape == (2,)
    good = ms.shooting.solve(osc, (-1.1, 15.0), method="newton")
    assert good.converged
    assert close(good.x0, [-0.01469, 2.7201], [5e-6, 5e-5]), good.x0


def test_mu_007_moves_without_stops_near_the_equivalent_damping_amplitude():
    osc = CoulombOscillator(**PAPER, mu=0.07)
    sol = ms.shooting.solve(osc, (0.0, 10.0), method="newton")
    assert sol.converged
    assert not any(kind == "stick" for _, kind in sol.trajectory.events)
    amplitude = np.max(np.abs(sol.trajectory.x[:, 0]))
    assert equivalent_damping_amplitude(osc) == pytest.approx(0.1265, abs=2e-4)   # the paper
    assert amplitude == pytest.approx(0.1265, rel=0.01)
    assert repeats_itself(osc, sol.x0)


@pytest.mark.parametrize("mu", [0.07, 0.08, 0.09])
def test_coulomb_brute_force_from_rest_settles_on_the_shooting_solution(mu):
    """Iterating the period map from rest (a simulation to steady state) ends where Newton
    shooting lands; the sampled trajectory ends on the period map's state."""
    osc = CoulombOscillator(**PAPER, mu=mu)
    sol = ms.shooting.solve(osc, (0.0, 0.0), method="newton", tol=1e-10)
    x = np.zeros(2)
    for _ in range(150):                       # μ = 0.07 contracts by 0.73 per period
        x = CoulombOscillator(**PAPER, mu=mu).period_map(x)
    assert np.max(np.abs(x - sol.x0)) < 1e-9
    assert np.array_equal(sol.trajectory.x[0], sol.x0)
    assert np.max(np.abs(sol.trajectory.x[-1] - osc.period_map(sol.x0))) < 1e-13


def test_mu_009_has_stops():
    osc = CoulombOscillator(**PAPER, mu=0.09)
    sol = ms.shooting.solve(osc, (-0.01, 2.0), method="newton")
    assert sol.converged
    stops = [t for t, kind in sol.trajectory.events if kind == "stick"]
    assert len(stops) == 2
    # While stuck the mass really is inside the band |x − δ cos ωt| < μg/ω_n² (eq. 13).
    for t, kind in sol.trajectory.events:
        if kind == "stick":
            x = np.interp(t, sol.trajectory.t, sol.trajectory.x[:, 0])
            assert abs(x - 0.1 * math.cos(100.0 * t)) <= osc.limit * (1 + 1e-9)
    assert repeats_itself(osc, sol.x0)


def test_stick_events_are_located_exactly():
    """The end of a stick phase solves |x − δ cos ωt| = μg/ω_n² to round-off."""
    osc = CoulombOscillator(**PAPER, mu=0.09)
    sol = ms.shooting.solve(osc, (-0.01, 2.0), method="newton")
    for t, kind in sol.trajectory.events:
        if kind == "slip":
            x = np.interp(t, sol.trajectory.t, sol.trajectory.x[:, 0])
            assert abs(abs(x - 0.1 * math.cos(100.0 * t)) - osc.limit) < 1e-9 * osc.limit + 1e-12


def test_bad_shooting_input():
    osc = LinearOscillator(**PAPER)
    with pytest.raises(ValueError, match="must have 2 unknowns"):
        ms.shooting.solve(osc, [1.0, 2.0, 3.0])
    with pytest.raises(ValueError, match="`omega` must be positive"):
        LinearOscillator(0.05, 100.0, 0.1, 0.0)
    with pytest.raises(ValueError, match="unknown method 'bisect'"):
        ms.shooting.solve(osc, [1.0, 2.0], method="bisect")
    with pytest.raises(ValueError, match="`mu` must be non-negative"):
        CoulombOscillator(**PAPER, mu=-0.1)


# --- the impact pair (Table 3) ----------------------------------------------------------------
TABLE3_CASE1 = np.array([[.16188, 6.5203, 10.372, -.74856], [.16204, 6.5268, 10.383, -.74931],
                         [.16220, 6.5333, 10.393, -.75006], [.16236, 6.5398, 10.403, -.75081],
                         [.16252, 6.5464, 10.414, -.75156]])
TABLE3_TRUE = np.array([.14716, 5.9275, 9.4294, -.68051])


def impact_pair(e=0.7, amplitude=0.189):
    return ms.oscillators.ImpactPair(m1=0.2799, m2=0.000545, clearance=0.028,
                                     amplitude=amplitude, omega=50.0, restitution=e)


def test_table_3_restitution_is_07_not_007():
    """Table 3's printed true solution is a fixed point for e = 0.7 (residual at the level of
    its printed digits), not for the extracted 0.07."""
    assert np.max(np.abs(impact_pair(0.7).residual(TABLE3_TRUE))) < 1e-4
    assert impact_pair(0.7).mode(TABLE3_TRUE) == (3, 3)
    # With e = 0.07 the same state ends in chatter against a wall (impacts accumulating)
    # or, at best, far from periodic: either way not Table 3's solution.
    try:
        far = np.max(np.abs(impact_pair(0.07).residual(TABLE3_TRUE))) > 1.0
    except ValueError as chatter:
        far = "chatter" in str(chatter)
    assert far


def test_impact_pair_flow_matches_table_3_terminal_values():
    xT = impact_pair().flow(TABLE3_CASE1[0]).x[-1]
    assert close(xT, [.17556, 6.5226, .16196, 9.1426], [2e-5, 2e-4, 2e-5, 2e-4]), xT


def test_table_3_case_1_converges_to_the_33_mode():
    pair = impact_pair()
    sol = ms.shooting.solve(pair, TABLE3_CASE1[0], method="warner", guesses=TABLE3_CASE1)
    assert sol.converged, sol.message
    # Without a spring to ground the pair may be shifted as a whole: x1(0) is free (a family
    # of periodic solutions); velocities and phase are fixed.
    assert close(sol.x0[1:], TABLE3_TRUE[1:], [5e-4, 5e-4, 5e-5]), sol.x0
    assert pair.mode(sol.x0) == (3, 3) and sol.mode == (3, 3)
    shifted = sol.x0 + np.array([0.05, 0.0, 0.0, 0.0])
    assert np.max(np.abs(pair.residual(shifted))) < 1e-6
    # Three periods in one flow come back to the start (the unknowns hold φ, not x2).
    three = pair.flow(sol.x0, t_span=(0.0, 3 * pair.period))
    assert np.max(np.abs(three.x[-1] - three.x[0])) < 1e-5


TABLE3_CASE3 = np.array([[.73580, 29.638, 47.147, -3.4026], [.73948, 29.786, 47.382, -3.4196],
                         [.74318, 29.935, 47.619, -3.4367], [.74689, 30.084, 47.857, -3.4538],
                         [.75063, 30.235, 48.097, -3.4711]])


def test_table_3_case_3_where_the_paper_failed_warner_ends_without_an_error():
    """The paper reports no convergence within 50 iterations from Case 3's guesses
    (velocities five times too large). Warner's iteration from there wanders through other
    impact modes, some of whose flows chatter (more than 10000 impacts a period): such a
    guess is a bad iterate, not the end of the run. Whatever round-off decides, the result
    is either Table 3's (3, 3) solution or a report of no convergence."""
    pair = impact_pair()
    sol = ms.shooting.solve(pair, TABLE3_CASE3[0], method="warner", guesses=TABLE3_CASE3,
                            max_iter=50, floquet=False)
    if sol.converged:
        assert close(sol.x0[1:], TABLE3_TRUE[1:], [5e-4, 5e-4, 5e-5]) and sol.mode == (3, 3)
    else:
        assert sol.iterations == 50 and "no convergence" in sol.message


class _FailingFlows:
    """g(x) = A x − b with its root at x* = (1, 2), whose flow 'chatters' (raises, as
    `ImpactPair.flow` does) wherever x₀ > 1.5: Warner's first secant step from these
    guesses lands there."""
    n = 2
    A = np.array([[2.0, 1.0], [1.0, 3.0]])
    root = np.array([1.0, 2.0])

    def residual(self, x):
        if x[0] > 1.5:
            raise ValueError("more than 10000 impacts in one period (chatter)")
        return self.A @ (np.asarray(x) - self.root) + 0.3 * (np.asarray(x) - self.root) ** 2

    def check(self, guess):
        return np.asarray(guess, float)


def test_warner_moves_back_from_a_guess_whose_flow_fails():
    problem = _FailingFlows()
    guesses = np.array([[0.0, 0.0], [0.2, 0.0], [0.0, 0.3]])
    calls = []
    first = problem.residual
    problem.residual = lambda x: (calls.append(np.array(x)), first(x))[1]
    sol = ms.shooting.solve(problem, guesses[0], method="warner", guesses=guesses,
                            tol=1e-12, floquet=False)
    assert sol.converged and np.allclose(sol.x0, problem.root, atol=1e-10)
    assert any(c[0] > 1.5 for c in calls)          # a failing flow was met on the way
    # From guesses that fail themselves there is nothing to start from: a message, no error.
    bad = ms.shooting.solve(problem, guesses[0], method="warner", floquet=False,
                            guesses=guesses + [2.0, 0.0])
    assert not bad.converged and "guess vector 0" in bad.message


def _dominant_multiplier(pair, u, periods=6, eps=1e-8):
    """The dominant Floquet multiplier of the orbit at u by power iteration of a small
    perturbation through the state flow itself (no monodromy matrix): the perturbation is
    flowed a period, its growth along itself read, and renormalized."""
    y0, phi = pair.initial_state(u), u[3]
    d = np.array([0.3, -0.5, 0.2, 0.7])
    d /= np.linalg.norm(d)
    base = pair.state_flow(y0, phi).x[-1]
    for _ in range(periods):
        moved = (pair.state_flow(y0 + eps * d, phi).x[-1] - base) / eps
        ratio = moved @ d
        d = moved / np.linalg.norm(moved)
    return ratio


def _significant_multipliers(pair, u, step=1e-5):
    """The multipliers other than the neutral pair (the two nearest 1), from a monodromy the
    test forms itself by fourth-order central differences of the state flow (the package
    uses second-order ones at another step)."""
    y0, phi = pair.initial_state(u), u[3]

    def flow(y):
        return pair.state_flow(y, phi).x[-1]
    M = np.empty((4, 4))
    for j in range(4):
        e = np.zeros(4)
        e[j] = h = step * max(1.0, abs(y0[j]))
        M[:, j] = (8.0 * (flow(y0 + e) - flow(y0 - e))
                   - (flow(y0 + 2 * e) - flow(y0 - 2 * e))) / (12.0 * h)
    vals = np.linalg.eigvals(M)
    keep = np.argsort(np.abs(vals - 1.0))[2:]
    return np.sort(vals[keep].real)


def test_impact_pair_floquet_multipliers_match_the_growth_of_a_perturbation():
    """The multipliers come from the state monodromy ∂y(T)/∂y(0) at fixed phase (the
    shooting unknowns hold φ instead of x2, so ∂y(T)/∂u is not a state map). The (3, 3)
    orbit is unstable: a perturbation along the dominant eigenvector, flowed on its own
    with the impacts, is multiplied by −4.77 per period. Translation of the pair as a whole
    is neutral: a double multiplier 1. The dominant multiplier is checked against a power
    iteration through the flow."""
    pair = impact_pair()
    sol = ms.shooting.solve(pair, TABLE3_TRUE, method="newton")
    assert sol.mode == (3, 3) and sol.stable is False
    lam = sol.floquet_multipliers[np.argsort(-np.abs(sol.floquet_multipliers))]
    assert lam[0].real == pytest.approx(_dominant_multiplier(pair, sol.x0), rel=1e-3)
    assert lam[0].real < -4.0 and abs(lam[0].imag) < 1e-9
    assert np.allclose(np.abs(lam[1:3]), 1.0, atol=1e-4) and abs(lam[3]) < 0.01
    vals, vecs = np.linalg.eig(pair.floquet_matrix(sol.x0))
    k = int(np.argmax(np.abs(vals)))
    direction = np.real(vecs[:, k]) / np.linalg.norm(np.real(vecs[:, k]))
    y0, phi = pair.initial_state(sol.x0), sol.x0[3]
    eps = 1e-7
    for periods in (1, 2):
        a, b = y0 + eps * direction, y0.copy()
        for _ in range(periods):
            a, b = pair.state_flow(a, phi).x[-1], pair.state_flow(b, phi).x[-1]
        assert (a - b) @ direction / eps == pytest.approx(vals[k].real ** periods, rel=1e-3)


def test_impact_pair_stability_ignores_its_neutral_multipliers():
    """The impact pair's double multiplier 1 (the pair shifted, or moving uniformly, as a
    whole) says nothing about stability; the other two decide. Continued from Table 3's
    point down to A = 0.175 in, the (3, 3) orbit is stable (its significant multipliers
    agree with a monodromy formed here by differences of its own), and a perturbation of ẋ2 dies out in the relative motion, which both
    symmetries leave alone, by 0.592 a period."""
    u = TABLE3_TRUE
    for A in (0.185, 0.18, 0.175):
        pair = impact_pair(amplitude=A)
        sol = ms.shooting.solve(pair, u, method="newton", tol=1e-10)
        assert sol.converged and sol.mode == (3, 3)
        u = sol.x0
    assert sol.stable is True and sol.neutral == 2
    mu = np.sort(sol.significant_multipliers.real)
    assert mu == pytest.approx(_significant_multipliers(pair, u), abs=1e-5)
    assert -1.0 < mu[0] < mu[1] < 0.0
    assert np.allclose(sol.floquet_multipliers.imag, 0.0, atol=1e-9)
    y0, phi = pair.initial_state(u), u[3]
    y = y0 + np.array([0.0, 0.0, 0.0, 1e-6])

    def relative(y):
        return np.array([y[0] - y[2], y[3] - y[1]]) - np.array([y0[0] - y0[2], y0[3] - y0[1]])
    sizes = []
    for k in range(1, 16):
        y = pair.state_flow(y, phi, samples=3).x[-1]
        if k in (10, 15):
            sizes.append(np.max(np.abs(relative(y))))
    assert sizes[1] / sizes[0] == pytest.approx(abs(mu[0]) ** 5, rel=0.02)


def test_impact_pair_bad_input():
    with pytest.raises(ValueError, match="`restitution` must be in"):
        impact_pair(1.5)
    with pytest.raises(ValueError, match="needs 5 guess vectors of length 4"):
        ms.shooting.solve(impact_pair(), TABLE3_CASE1[0], guesses=TABLE3_CASE1[:3])


# --- driven mechanisms -----------------------------------------------------------------------
def test_mechanism_steady_state_matches_the_harmonic_solution():
    """A block on a prismatic joint, spring–damper to ground, shaken by F₀ cos ωt: shooting
    on the mechanism gives the harmonic steady state, in one Newton iteration (linear)."""
    m, k, c, F0, w = 2.0, 800.0, 6.0, 5.0, 15.0
    mech = ms.examples.spring_mass(mass=m, stiffness=k, stretch=0.0, damping=c)
    mech.add(ms.Force(mech.body("block"), lambda t: (F0 * math.cos(w * t), 0.0), name="shaker"))
    sol = mech.steady_state(2 * math.pi / w)
    X, lag = F0 / math.hypot(k - m * w * w, c * w), math.atan2(c * w, k - m * w * w)
    assert sol.converged and sol.iterations <= 2
    np.testing.assert_allclose(sol.x0, [0.5 + X * math.cos(lag), w * X * math.sin(lag)],
                               rtol=0, atol=1e-8)                 # the shooting tolerance
    np.testing.assert_allclose(np.abs(sol.floquet_multipliers),
                               math.exp(-c / (2 * m) * 2 * math.pi / w), rtol=1e-5)


def test_driven_pendulum_steady_state_repeats_and_agrees_with_brute_force():
    """A damped pendulum under a periodic torque (nonlinear): the shot steady state repeats
    itself, and long simulation from rest settles onto it."""
    mech = ms.examples.pendulum(length=0.6, mass=1.0, angle=-math.pi / 2)
    rod = mech.body("rod")
    w = 4.0
    mech.add(ms.Torque(rod, lambda t: 1.5 * math.cos(w * t)))
    mech.add(ms.Spring(mech.ground, rod, at_a=(0.3, -0.6), at_b=(0.0, -0.6), stiffness=0.0,
                       damping=2.0, name="dashpot"))
    T = 2 * math.pi / w
    sol = mech.steady_state(T)
    assert sol.converged and sol.stable
    prob = sol.trajectory.result
    assert np.ptp(prob.coordinate("rod.angle")) > 0.2             # a real swing
    brute = mech.simulate(t_end=30 * T, rtol=1e-10, atol=1e-12, output_step=T)
    angle_end = brute.coordinate("rod.angle")[-1]
    assert angle_end == pytest.approx(prob.coordinate("rod.angle")[0], abs=1e-5)


def test_regime_map_machinery_recovers_the_seed_mode():
    """The continuation and the process pool: the seed's point comes back in the (3, 3)
    mode, and parallel rows give the same states as serial ones."""
    seed = [0.14736333, 5.92750349, 9.42938159, -0.68051311]
    A, W = np.array([0.188, 0.189]), np.array([49.9, 50.0])
    par = ms.shooting.regime_map(A, W, seed, 0.189, 50.0, processes=2)
    ser = ms.shooting.regime_map(A, W, seed, 0.189, 50.0, processes=1)
    assert tuple(par.modes[1, 1]) == (3, 3)
    np.testing.assert_array_equal(par.modes, ser.modes)
    assert np.array_equal(np.isnan(par.x0), np.isnan(ser.x0))
    for name in ("stable", "periods", "cycle_modes"):
        np.testing.assert_array_equal(getattr(par, name), getattr(ser, name))
    assert np.all(par.periods == 1) and not par.stable.any()     # Table 3's (3, 3): unstable


def test_simulation_finds_the_stable_orbit_and_the_irregular_band():
    """Where continuation finds nothing, the map simulates (`settle`). Started from Table 3's
    orbit, the pair at A = 0.175 in settles onto a (3, 3) motion of period 1 in 200
    periods, and Newton from that state converges to a stable orbit
    whose multipliers agree with a monodromy formed here by differences of its own: the mirror
    image of the one continued from Table 3's point (velocities reversed, phase moved by π). At A = 0.121 and 0.128 in the motion
    repeats after no k ≤ 8 periods: irregular (it wanders between (2, 2), (3, 2) and
    (2, 3) periods for at least 1000 periods, measured)."""
    from mechsim.shooting.regime import _unknowns, settle
    pair = impact_pair(amplitude=0.175)
    k, cycle, y, phi = settle(pair, TABLE3_TRUE)
    assert (k, cycle) == (1, (3, 3))
    sol = ms.shooting.solve(pair, _unknowns(pair, y, phi), method="newton", tol=1e-10)
    assert sol.converged and sol.iterations <= 5 and sol.mode == (3, 3) and sol.stable
    assert np.sort(sol.significant_multipliers.real) == pytest.approx(
        _significant_multipliers(pair, sol.x0), abs=1e-5)
    _, v1, v2, phi = sol.x0
    assert np.max(np.abs(pair.residual([0.0, -v1, -v2, phi - math.pi]))) < 1e-8
    assert [-v1, -v2, phi - math.pi] == pytest.approx([6.0709, 9.0933, -0.7696], abs=2e-4)
    for A in (0.121, 0.128):
        k, cycle, _, _ = settle(impact_pair(amplitude=A), TABLE3_TRUE)
        assert k == 0 and cycle is None


def test_regime_map_finds_periodic_states_that_scale_with_frequency():
    """An 8 × 8 map around Table 3's point. In time τ = ωt and lengths x/r the pair's
    equations read x1'' = −(A/r) cos(τ + φ) between impacts, so ω only rescales time: a
    periodic state found at (A, ω), with its velocities scaled by ω'/ω, must be periodic at
    (A, ω') in the same mode — an independent check of every point the map reports."""
    seed = [0.14716, 5.9275, 9.4294, -0.68051]
    A, W = np.linspace(0.16, 0.24, 8), np.linspace(40.0, 60.0, 8)
    rm = ms.shooting.regime_map(A, W, seed, 0.189, 50.0, processes=2)
    found = rm.modes[:, :, 0] >= 0
    assert found.mean() >= 0.9
    assert tuple(rm.modes[np.argmin(abs(A - 0.189)), np.argmin(abs(W - 50.0))]) == (3, 3)
    for i, j in zip(*np.nonzero(found)):
        other = W[(j + 3) % len(W)]
        x1, v1, v2, phi = rm.x0[i, j]
        scaled = np.array([x1, v1 * other / W[j], v2 * other / W[j], phi])
        pair = ms.oscillators.ImpactPair(m1=0.2799, m2=0.000545, clearance=0.028,
                                         amplitude=A[i], omega=other, restitution=0.7)
        g = pair.residual(scaled)
        assert np.max(np.abs(g / [1, other / W[j], 1, other / W[j]])) < 2e-6, (A[i], W[j])
        assert pair.mode(scaled) == tuple(rm.modes[i, j])
        # Stability too is the same at every ω: the scaled orbit's multipliers decide.
        mu = np.linalg.eigvals(pair.floquet_matrix(scaled))
        mu = mu[np.argsort(np.abs(mu - 1.0))[2:]]            # without the neutral pair
        assert rm.stable[i, j] == bool(np.all(np.abs(mu) < 1.0)), (A[i], W[j], mu)
    assert rm.stable[found].any() and not rm.stable[found].all()
    assert np.all(rm.periods[found] == 1)


# A study (14 flows of the flexible model): shooting is checked on the driven pendulum above.
@pytest.mark.slow
def test_flexible_slider_crank_steady_state_and_its_modal_floquet_multipliers():
    """The seed's flexible slider-crank, crank driven at 150 rad/s, rod with 2 % modal
    damping: shooting on the modal coordinates finds the periodic steady state without the
    transient. Its Floquet multipliers are the modes' decay over one revolution,
    exp(−ζ ω_k T) (0.343 and 0.0139), each a complex pair — an independent check of the whole chain (modes,
    mass matrix, damping, constraints, monodromy). Flown over two more revolutions, the
    state repeats; its midspan deflection peaks near the quasi-static 1.55 mm."""
    mech = ms.examples.slider_crank(flexible=True, driven=True, gravity=(0.0, 0.0),
                                    damping_ratio=0.02)
    beam = mech.body("rod")
    T = 2 * math.pi / 150.0
    sol = mech.steady_state(T, rtol=1e-6, atol=1e-9)
    assert sol.converged and sol.iterations <= 3, sol.message
    decay = np.exp(-0.02 * beam.frequencies * T)
    mags = np.sort(np.abs(sol.floquet_multipliers))[::-1]
    np.testing.assert_allclose(mags[:2], decay[0], rtol=1e-3)        # measured 1.2e-5
    # The second mode's multiplier is small against the finite-difference monodromy's
    # error at this simulation tolerance (0.0176 measured at rtol 1e-6; 0.0138 at 1e-7).
    np.testing.assert_allclose(mags[2:], decay[1], atol=0.01)
    res = sol.trajectory.result
    from mechsim.run.solver import simulate
    two = simulate(mech.problem(), res.q[0], res.v[0], t_end=2 * T, rtol=1e-8, atol=1e-11,
                   output_step=T / 100)
    assert two.success
    i = two.coordinate_names.index("rod.eta1")
    scale = np.max(np.abs(two.q[:, i]))
    for k in (100, 200):                                # one and two revolutions later
        assert abs(two.q[k, i] - two.q[0, i]) < 1e-4 * scale
        assert abs(two.v[k, i] - two.v[0, i]) < 1e-4 * np.max(np.abs(two.v[:, i]))
    mid = (beam.point_modes((0.15, 0.0)) @ res.q[:, 6:8].T)[1]
    assert 1.4e-3 < np.max(np.abs(mid)) < 1.9e-3


@pytest.mark.parametrize("mu, u", [(0.07, (0.0, 10.0)), (0.08, (-0.0147, 2.72)),
                                   (0.09, (-0.01, 2.0))])
def test_coulomb_closed_form_monodromy_matches_finite_differences(mu, u):
    """The exact monodromy (closed-form slip transitions, saltation diag(1, a⁺/a⁻) at stops,
    (δx, 0) kept through sticks) against central differences of the flow itself; and the
    closed-form flow against scipy integrating the same slip equations."""
    from scipy.integrate import solve_ivp

    from mechsim.shooting.solve import monodromy
    osc = CoulombOscillator(**PAPER, mu=mu)
    traj, M = osc.flow_with_monodromy(np.array(u))
    np.testing.assert_allclose(M, monodromy(osc, u), rtol=1e-5, atol=1e-7)
    # The first slip phase integrated numerically up to the first event.
    t_first = traj.events[0][0] if traj.events else osc.period
    d = 1 if u[1] > 0 else -1
    ref = solve_ivp(lambda t, y: osc.rhs(t, y, d * osc.mu * osc.g), (0.0, t_first), u,
                    method="DOP853", rtol=1e-12, atol=1e-14)
    k = np.searchsorted(traj.t, t_first)
    np.testing.assert_allclose(traj.x[k], ref.y[:, -1], atol=1e-9)


def test_coulomb_shooting_bench_counts_flows_against_periods():
    """`mechsim bench coulomb`: both runs reach the accuracy asked for, from the same start
    on the same motion. Brute force needs one more period per factor ρ = 0.73 of accuracy
    (μ = 0.07 slips all the time, so it contracts linearly), Newton at most one more flow;
    at 1e-10 shooting takes more than 10 times fewer flows. With sticking (μ = 0.09) brute
    force settles within a few periods, as shooting does."""
    from mechsim.app import bench
    rows = bench.shooting_run(cases=((0.07, (0.0, 0.0)), (0.09, (0.0, 0.0))),
                              accuracies=(1e-6, 1e-10), repeat=1, progress=None)
    for r in rows:
        assert r.shooting_error <= r.accuracy and r.brute_error <= r.accuracy
        assert r.shooting_time > 0 and r.brute_time > 0
    slow = {r.accuracy: r for r in rows if r.mu == 0.07}
    per_decade = (slow[1e-10].brute_periods - slow[1e-6].brute_periods) / 4
    assert abs(per_decade - 1 / math.log10(1 / 0.73)) < 1.0        # 7.3 periods a decade
    assert slow[1e-10].shooting_flows - slow[1e-6].shooting_flows <= 1
    assert slow[1e-10].brute_periods >= 10 * slow[1e-10].shooting_flows
    sticking = [r for r in rows if r.mu == 0.09]
    assert all(r.brute_periods <= 5 and r.shooting_flows <= 5 for r in sticking)


def test_shooting_pays_only_for_the_flows_it_needs():
    """Newton with the exact monodromy takes one flow per iterate (the start's included);
    the sampled period is computed only when asked for, from the last flow's phases."""
    osc = CoulombOscillator(**PAPER, mu=0.07)
    sol = ms.shooting.solve(osc, (0.0, 10.0), method="newton", tol=1e-7, floquet=False)
    assert osc.flows == sol.iterations + 1
    traj = sol.trajectory
    assert osc.flows == sol.iterations + 1             # sampled from the remembered motion
    assert sol.trajectory is traj
    assert np.array_equal(traj.x[0], sol.x0)
    # The brute-force map needs no monodromy, and gives the same state to round-off.
    fresh = CoulombOscillator(**PAPER, mu=0.07)
    np.testing.assert_allclose(fresh.period_map(sol.x0), traj.x[-1], rtol=0, atol=1e-14)
    assert fresh._motion(sol.x0, monodromy=False)[2] is None


def test_newton_xtol_stops_on_its_predicted_step():
    """With `xtol` and the exact monodromy, Newton stops where its step predicts the state
    within xtol, without a flow at the last iterate: one flow fewer than the residual test
    that guarantees the same accuracy, and the state is still within xtol (here far
    inside: the convergence is quadratic)."""
    ref = ms.shooting.solve(CoulombOscillator(**PAPER, mu=0.07), (0.0, 0.0), method="newton",
                            tol=1e-13, floquet=False).x0
    by_g, by_step = CoulombOscillator(**PAPER, mu=0.07), CoulombOscillator(**PAPER, mu=0.07)
    a = ms.shooting.solve(by_g, (0.0, 0.0), method="newton", tol=1e-6 / 24, floquet=False)
    b = ms.shooting.solve(by_step, (0.0, 0.0), method="newton", tol=1e-6 / 24, xtol=1e-6,
                          floquet=False)
    assert a.converged and b.converged and "xtol" in b.message
    assert by_step.flows == by_g.flows - 1 == b.iterations
    assert np.max(np.abs(b.x0 - ref)) < 1e-9
    assert b.residual > 1e-6 / 24                      # the last residual evaluated
    with pytest.raises(ValueError, match="xtol"):
        ms.shooting.solve(by_step, (0.0, 0.0), method="newton", xtol=0.0)
