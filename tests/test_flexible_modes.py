"""Finite-element beam and modal basis against Euler–Bernoulli closed forms."""

import math

import numpy as np
import pytest

from mechsim.flexible import beam_modes

# The seed's elastic coupler: 1 m, 10 elements, 8910 kg/m³, E = 117 GPa, 10 mm × 10 mm.
L, E, RHO = 1.0, 117e9, 8910.0
A, I = 1e-4, 1e-2**4 / 12
C = math.sqrt(E * I / (RHO * A))


def test_pinned_pinned_frequencies_of_the_seed_coupler():
    basis = beam_modes(L, E, RHO, A, I, n_elements=10, n_modes=2, boundary="pinned-pinned")
    exact = [(k * math.pi / L) ** 2 * C for k in (1, 2)]
    np.testing.assert_allclose(basis.frequencies, exact, rtol=1e-3)


@pytest.mark.parametrize("boundary, betas", [("clamped-free", (1.875104, 4.694091)),
                                             ("free-free", (4.730041, 7.853205))])
def test_cantilever_and_free_free_frequencies(boundary, betas):
    basis = beam_modes(L, E, RHO, A, I, n_elements=10, n_modes=2, boundary=boundary)
    np.testing.assert_allclose(basis.frequencies, [(b / L) ** 2 * C for b in betas], rtol=1e-3)


def test_modes_are_mass_normalised_and_respect_the_reference_conditions():
    basis = beam_modes(L, E, RHO, A, I, n_elements=10, n_modes=3, boundary="pinned-pinned")
    Phi = basis.matrix()
    np.testing.assert_allclose(Phi.T @ basis.M @ Phi, np.eye(3), atol=1e-10)
    np.testing.assert_allclose(Phi.T @ basis.K @ Phi, np.diag(basis.frequencies**2),
                               rtol=1e-9, atol=1e-10 * basis.frequencies.max() ** 2)
    assert np.all(basis.shapes[0, :2] == 0.0) and np.all(basis.shapes[-1, 1] == 0.0)
    # The first pinned–pinned mode is a half sine: symmetric about the middle.
    v = basis.shapes[:, 1, 0]
    np.testing.assert_allclose(v, v[::-1], atol=1e-10 * np.abs(v).max())


def test_modal_bad_input_names_the_beam():
    with pytest.raises(ValueError, match="coupler: `n_modes` must be between 1 and"):
        beam_modes(L, E, RHO, A, I, n_elements=2, n_modes=50, owner="coupler")
    with pytest.raises(ValueError, match="coupler: `density` must be positive"):
        beam_modes(L, E, -1.0, A, I, owner="coupler")
    with pytest.raises(ValueError, match="unknown boundary 'hinged'"):
        beam_modes(L, E, RHO, A, I, boundary="hinged")
