"""State-space Newmark method, linear systems and the accuracy analysis (seed 000)."""

import math

import numpy as np
import pytest

import mechsim as ms
from mechsim import analysis

ZETAS = (0.0, 0.01, 0.05, 0.1, 0.5)


def two_dof(force=True):
    """Seed 000, example 1: ground–k1,c1–m1–k2,c2–m2, c_i = 2 ζ_i √(k_i m_i)."""
    m1, m2, k1, k2, z1, z2 = 2000.0, 50.0, 1e3, 1e4, 0.01, 0.2
    c1, c2 = 2 * z1 * math.sqrt(k1 * m1), 2 * z2 * math.sqrt(k2 * m2)
    M = np.diag([m1, m2])
    C = np.array([[c1 + c2, -c2], [-c2, c2]])
    K = np.array([[k1 + k2, -k2], [-k2, k2]])
    f = (lambda t: np.array([0.0, 10.0 * np.cos(3.0 * t)])) if force else None
    return ms.LinearSystem(M, C, K, force=f)


def closed_form(system, t, omega=3.0, amplitude=(0.0, 10.0)):
    """Independent solution for f = F₀ cos ωt from rest: the harmonic particular solution
    X = (K − ω²M + iωC)⁻¹ F₀ plus the homogeneous part through the eigenvectors of A."""
    M, C, K = system.M, system.C, system.K
    X = np.linalg.solve(K - omega**2 * M + 1j * omega * C, np.asarray(amplitude, complex))
    xp = np.real(np.outer(np.exp(1j * omega * t), X))
    vp = np.real(np.outer(1j * omega * np.exp(1j * omega * t), X))
    lam, V = np.linalg.eig(system.A)
    q0 = -np.concatenate([vp[0], xp[0]])               # the homogeneous part cancels q_p(0)
    c = np.linalg.solve(V, q0)
    qh = np.real((V[None, :, :] * np.exp(np.outer(t, lam))[:, None, :]) @ c)
    n = system.n
    return xp + qh[:, n:], vp + qh[:, :n]


def test_ss_newmark_equals_classical_newmark_to_round_off():
    sys2 = two_dof()
    a = sys2.simulate(30.0, 0.05, "ss-newmark")
    b = sys2.simulate(30.0, 0.05, "newmark")
    scale = np.abs(a.x).max()
    assert np.max(np.abs(a.x - b.x)) < 1e-11 * scale     # 600 steps of round-off
    assert np.max(np.abs(a.v - b.v)) < 1e-11 * np.abs(a.v).max()


def test_exact_method_against_the_closed_form():
    sys2 = two_dof()
    r = sys2.simulate(30.0, 0.05, "exact")
    x, v = closed_form(sys2, r.t)
    assert np.max(np.abs(r.x - x)) < 1e-10 * np.abs(x).max()
    assert np.max(np.abs(r.v - v)) < 1e-10 * np.abs(v).max()


@pytest.mark.parametrize("method, order", [("ss-newmark", 2), ("newmark", 2), ("rk4", 4)])
def test_convergence_order_on_the_two_dof_system(method, order):
    sys2 = two_dof()
    hs = [0.04, 0.02, 0.01, 0.005]
    errs = []
    for h in hs:
        r = sys2.simulate(10.0, h, method)
        x, _ = closed_form(sys2, r.t)
        errs.append(np.max(np.abs(r.x - x)))
    slope = np.polyfit(np.log(hs), np.log(errs), 1)[0]
    assert abs(slope - order) < 0.15 * order, slope


def test_amplification_matrix_is_eq_11():
    w, z, h = 2.0, 0.05, 0.1
    D = 4 + 4 * z * w * h + (w * h) ** 2
    expected = np.array([[4 - 4 * z * w * h - (w * h) ** 2, -4 * w**2 * h],
                         [4 * h, 4 + 4 * z * w * h - (w * h) ** 2]]) / D
    np.testing.assert_allclose(analysis.amplification_matrix("ss-newmark", w, z, h), expected,
                               atol=1e-14)


@pytest.mark.parametrize("zeta", ZETAS)
def test_unconditional_stability(zeta):
    T = 2 * math.pi
    for ratio in np.logspace(-3, 2, 26):
        rho = analysis.spectral_radius("ss-newmark", 1.0, zeta, ratio * T)
        assert rho <= 1.0 + 1e-12, (zeta, ratio, rho)
    # RK4, for contrast, is unstable beyond Δt/T ≈ 0.45.
    assert analysis.spectral_radius("rk4", 1.0, 0.0, 0.5 * T) > 1.0


def _slope(fun, ratios):
    vals = [abs(fun(r)) for r in ratios]
    return np.polyfit(np.log(ratios), np.log(vals), 1)[0]


@pytest.mark.parametrize("zeta, order", [(0.0, 2), (0.01, 2), (0.05, 2), (0.1, 2), (0.5, 4)])
def test_period_error_order(zeta, order):
    """Eq. 22: the h² term has the factor 4ζ² − 1, which vanishes at ζ = 0.5."""
    wd = math.sqrt(1 - zeta**2)
    ratios = np.array([0.004, 0.008, 0.016, 0.032])
    slope = _slope(lambda r: analysis.period_error("ss-newmark", 1.0, zeta, r * 2 * math.pi / wd),
                   ratios)
    assert abs(slope - order) < 0.1 * order, slope
    # Small-step limit of eq. 22 for the light-damping case: e_p ≈ (1 − 4ζ²)(ωh)²/12 · 100.
    if order == 2:
        h = 0.004 * 2 * math.pi / wd
        assert analysis.period_error("ss-newmark", 1.0, zeta, h) == \
            pytest.approx((1 - 4 * zeta**2) * h**2 / 12 * 100, rel=0.01)


@pytest.mark.parametrize("zeta", [0.01, 0.05, 0.1, 0.5])
def test_amplitude_error_order(zeta):
    """e_A at a fixed time (one undamped period) falls like h²."""
    T = 2 * math.pi
    steps = np.array([50, 100, 200, 400])
    errs = [abs(analysis.amplitude_error("ss-newmark", 1.0, zeta, T / n, int(n))) for n in steps]
    slope = np.polyfit(np.log(T / steps), np.log(errs), 1)[0]
    assert abs(slope - 2) < 0.2, slope


def test_newmark_and_ss_newmark_have_the_same_analysis():
    for zeta in (0.0, 0.1):
        np.testing.assert_allclose(analysis.amplification_matrix("newmark", 3.0, zeta, 0.2),
                                   analysis.amplification_matrix("ss-newmark", 3.0, zeta, 0.2),
                                   atol=1e-14)


def test_bad_linear_input():
    I2 = np.eye(2)
    with pytest.raises(ValueError, match="`M` must be symmetric"):
        ms.LinearSystem([[1.0, 0.5], [0.0, 1.0]], I2, I2)
    with pytest.raises(ValueError, match="`M` must be positive definite"):
        ms.LinearSystem([[1.0, 0.0], [0.0, -1.0]], I2, I2)
    with pytest.raises(ValueError, match=r"`K` must have shape \(2, 2\)"):
        ms.LinearSystem(I2, I2, np.eye(3))
    with pytest.raises(ValueError, match="`h` must be a positive step"):
        two_dof().simulate(1.0, 0.0)
    with pytest.raises(ValueError, match="unknown method 'euler'; valid methods: ss-newmark"):
        two_dof().simulate(1.0, 0.1, "euler")
    with pytest.raises(ValueError, match=r"`x0` must have shape \(2,\)"):
        two_dof().simulate(1.0, 0.1, x0=[1.0])
    with pytest.raises(ValueError, match=r"`force\(t\)` must return shape \(2,\)"):
        ms.LinearSystem(I2, I2, I2, force=lambda t: [1.0]).simulate(1.0, 0.1)
    with pytest.raises(ValueError, match="`zeta` must be non-negative"):
        analysis.period_error("ss-newmark", 1.0, -0.1, 0.1)
