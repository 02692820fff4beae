"""Rotor–bearing model: element matrices against beam theory, gyroscopic whirl, unbalance."""

import math

import numpy as np
import pytest

import mechsim as ms
from mechsim.linear.rotor import Bearing, Disk, Rotor, ShaftElement

E, RHO, NU = 2.0e11, 7800.0, 0.3


def section(d):
    return math.pi * d**2 / 4, math.pi * d**4 / 64


def timoshenko_ss(k, L, d):
    """Simply supported Timoshenko beam, mode k: the lower root of
    (ρ²I/κG) ω⁴ − (ρA + ρIβ²(1 + E/κG)) ω² + EIβ⁴ = 0, β = kπ/L."""
    A, I = section(d)
    G = E / (2 * (1 + NU))
    kap = 6 * (1 + NU) / (7 + 6 * NU)
    b = k * math.pi / L
    a2, a1, a0 = RHO**2 * I / (kap * G), -(RHO * A + RHO * I * b**2 * (1 + E / (kap * G))), E * I * b**4
    return math.sqrt((-a1 - math.sqrt(a1**2 - 4 * a2 * a0)) / (2 * a2))


@pytest.mark.parametrize("L, d", [(1.0, 0.02), (0.3, 0.06)])     # slender and stubby
def test_simply_supported_shaft_against_timoshenko_theory(L, d):
    ne = 40      # finite elements converge from above; 40 bring mode 3 within 0.1 %
    r = Rotor([ShaftElement(L / ne, d)] * ne, E, RHO, NU,
              bearings=[Bearing(1, 1e15, 1e15), Bearing(ne + 1, 1e15, 1e15)])
    w = r.natural_frequencies(0.0)[::2][:3]          # each mode appears in both planes
    exact = [timoshenko_ss(k, L, d) for k in (1, 2, 3)]
    np.testing.assert_allclose(w, exact, rtol=2e-3)
    A, I = section(d)
    eb = (math.pi / L) ** 2 * math.sqrt(E * I / (RHO * A))
    if L / d > 40:     # slender: Euler–Bernoulli within 0.1 %
        assert w[0] == pytest.approx(eb, rel=1e-3)
    else:              # stubby: shear and rotary inertia lower the frequency visibly
        assert w[0] < 0.98 * eb


def test_free_free_shaft_against_beam_theory():
    # Slender (L/d = 80): the element's rotary inertia, absent from the Euler–Bernoulli
    # closed form, lowers mode 2 by only ~0.05 %.
    L, d, ne = 1.2, 0.015, 20
    r = Rotor([ShaftElement(L / ne, d)] * ne, E, RHO, NU, shear=False)
    w = r.natural_frequencies(0.0)
    w = w[w > 1.0][::2][:2]                          # drop the rigid-body modes
    A, I = section(d)
    beta = np.array([4.730041, 7.853205])
    np.testing.assert_allclose(w, (beta / L) ** 2 * math.sqrt(E * I / (RHO * A)), rtol=1e-3)


def test_whirl_split_grows_with_speed():
    """A symmetric shaft with an overhung disk: at rest the two planes share each frequency;
    spinning splits the pair into backward and forward whirl, more at higher speed."""
    r = Rotor([ShaftElement(0.1, 0.04)] * 5, E, RHO, NU,
              disks=[Disk(6, 8.0, 0.05, 0.1)],
              bearings=[Bearing(1, 5e7, 5e7), Bearing(4, 5e7, 5e7)])
    splits = []
    for speed in (0.0, 500.0, 1000.0, 2000.0):
        w = r.natural_frequencies(speed, 2)
        splits.append(w[1] - w[0])
    assert splits[0] < 1e-6 * r.natural_frequencies(0.0, 1)[0]
    assert 0 < splits[1] < splits[2] < splits[3]


def test_gyroscopic_matrix_is_skew_and_mass_positive():
    r = ms.rotor.turbo_compressor()
    assert np.abs(r.G + r.G.T).max() == 0.0
    assert np.linalg.eigvalsh(r.M).min() > 0.0


def test_unbalance_response_reaches_the_harmonic_orbit():
    """Turbo-compressor at 30,000 rpm: starting on the harmonic steady state (K − Ω²M +
    iΩ(C + ΩG))X = F the exact integrator stays on it; from rest, ss-Newmark at a fine step
    settles onto the same orbit amplitude at station 1."""
    rotor = ms.rotor.turbo_compressor()
    speed = 30000 * 2 * math.pi / 60
    system = rotor.linear_system(speed)
    X = rotor.steady_unbalance_response(speed)
    r = system.simulate(0.01, 1e-4, "exact", x0=np.real(X), v0=np.real(1j * speed * X))
    orbit = np.real(np.outer(np.exp(1j * speed * r.t), X))
    assert np.abs(r.x - orbit).max() < 1e-8 * np.abs(X).max()
    i = rotor.dof(1, "ux")
    # The slowest mode (backward whirl, time constant ~0.2 s) has decayed by e^-10 after 2 s.
    r = system.simulate(2.0, 2.5e-5, "ss-newmark")
    last = r.t > 2.0 - 2 * 2 * math.pi / speed
    assert np.abs(r.x[last, i]).max() == pytest.approx(abs(X[i]), rel=0.005)
    # The unbalances are at 0° and 180° on both disks, of 7.2 g·mm: the force amplitude.
    assert abs(rotor.unbalance_force(speed)(0.0)[i]) == pytest.approx(7.2e-6 * speed**2)


def test_rotor_bad_input():
    with pytest.raises(ValueError, match="station 9, stations are 1 … 3"):
        Rotor([ShaftElement(0.1, 0.02)] * 2, E, RHO, bearings=[Bearing(9, 1e7, 1e7)])
    with pytest.raises(ValueError, match="shaft element 2 needs positive"):
        Rotor([ShaftElement(0.1, 0.02), ShaftElement(0.1, -0.02)], E, RHO)
    with pytest.raises(ValueError, match="`E` must be positive"):
        Rotor([ShaftElement(0.1, 0.02)], -1.0, RHO)
