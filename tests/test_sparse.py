"""Long chains in O(n): Φ_q as a CSR array of its fixed pattern (`mechsim.linalg.sparse`), the
largest eigenvalue of the banded Schur complement by warm Lanczos, and the partition's
pivoting by banded LU (`mechsim.linalg.banded`), each against its dense counterpart."""

import math

import numpy as np
import pytest
import scipy.linalg as sla

import mechsim as ms
from mechsim.linalg import sparse
from mechsim.formulations.partitioned import Partitioned


@pytest.fixture(scope="module")
def chain():
    """The assembled 40-window chain (243 coordinates) and a state of its motion."""
    mech = ms.examples.double_four_bar(40)
    prob = mech.problem(build="assembled")
    res = mech.simulate(t_end=0.3, method="hybrid", rtol=1e-9, atol=1e-11)
    return mech, prob, res.q[-1], res.v[-1]


def test_the_solvers_take_a_long_chains_jacobian_sparse(chain):
    """The CSR Φ_q equals the dense one exactly (its terms' Φ and γ to round-off: they come
    from other kernels), and every helper gives what the dense array gives."""
    _, prob, q, v = chain
    assert prob.sparse and prob.schur is not None
    J = prob.phi_q(q, 0.3)
    Js = prob.solver_phi_q(q, 0.3)
    assert not sparse.is_dense(Js)
    assert np.array_equal(Js.toarray(), J)
    phi, Jp = prob.solver_position_terms(q, 0.3)
    np.testing.assert_allclose(phi, prob.phi(q, 0.3), rtol=0, atol=1e-14)
    assert np.array_equal(Jp.toarray(), J)
    Jd, gamma = prob.solver_dynamics_terms(q, v, 0.3)
    assert np.array_equal(Jd.toarray(), J)
    np.testing.assert_allclose(gamma, prob.gamma(q, v, 0.3), rtol=1e-14, atol=1e-14)
    rows, cols = prob.model.JACOBIAN_ROWS, prob.model.JACOBIAN_COLS
    assert np.array_equal(sparse.values(Js, rows, cols), J[rows, cols])
    s = np.sqrt(prob.inverse_mass_diagonal)
    assert np.array_equal(sparse.scale_columns(Js, s).toarray(), J * s)
    J2 = prob.phi_q(q + 1e-3, 0.3)
    diff = sparse.difference(prob.solver_phi_q(q + 1e-3, 0.3), Js, 10.0)
    np.testing.assert_allclose(diff.toarray(), (J2 - J) * 10.0, rtol=1e-15, atol=1e-15)
    assert sparse.frobenius(Js) == pytest.approx(np.linalg.norm(J), rel=1e-15)
    np.testing.assert_array_equal(sparse.columns(Js, [5, 7]), J[:, [5, 7]])
    with pytest.raises(ValueError, match="pattern"):
        sparse.positions(Js, [0], [prob.n - 1])
    # Jᵀx without forming Jᵀ: scipy's numbers to the bit; another matrix of the pattern
    # shares its structure, its own values, the first untouched.
    x = np.linspace(-1.0, 1.0, prob.m)
    assert sparse.transpose_times(Js, x).tobytes() == (Js.T @ x).tobytes()
    twice = sparse.with_data(Js, 2.0 * Js.data)
    assert twice.indptr is Js.indptr and np.array_equal(twice.toarray(), 2.0 * J)
    assert np.array_equal(Js.toarray(), J)
    assert sparse.transpose_times(twice, x).tobytes() == (twice.T @ x).tobytes()
    np.testing.assert_allclose(prob.schur.assemble(Js), prob.schur.assemble(J), rtol=1e-15)


def test_warm_lanczos_finds_the_largest_eigenvalue_of_the_complement(chain):
    """The second and later calls of `largest` start Lanczos from the previous vector: the
    eigenvalue agrees with LAPACK's dense one to its contract, 1e-3 (what the monitor's
    ratios need), its vector's residual within 1e-3 of it, after the state has moved."""
    mech, prob, q, v = chain
    band = prob.schur
    band.forget()
    for k in range(4):
        qk = q + 0.01 * k * v
        J = prob.phi_q(qk, 0.3)
        band.factor(J)
        lam, u = band.largest()
        S = (J * prob.inverse_mass_diagonal) @ J.T
        exact = np.linalg.eigvalsh(S)[-1]
        assert lam == pytest.approx(exact, rel=1e-3)
        assert np.linalg.norm(S @ u - lam * u) <= 1e-3 * lam


@pytest.mark.parametrize("n", [10, 40])
def test_banded_lu_picks_a_partition_as_good_as_the_dense_lu(n):
    """The pivots of the banded LU of Φ_qᵀ give a square, non-singular dependent block whose
    condition is within a factor 2 of the dense LU's choice (equal on these chains)."""
    mech = ms.examples.double_four_bar(n)
    prob = mech.problem(build="assembled")
    q = mech.simulate(t_end=0.2, method="lu").q[-1]
    J = prob.phi_q(q, 0.2)
    perm = prob.schur.pivoted_coordinates(prob.solver_phi_q(q, 0.2))
    assert sorted(perm.tolist()) == list(range(prob.n))
    _, piv = sla.lu_factor(J.T)
    dense = np.arange(prob.n)
    for i, p in enumerate(piv):
        dense[i], dense[p] = dense[p], dense[i]
    m = prob.m
    banded_cond = np.linalg.cond(J[:, np.sort(perm[:m])])
    dense_cond = np.linalg.cond(J[:, np.sort(dense[:m])])
    assert banded_cond <= 2.0 * dense_cond
    basis = Partitioned(prob, 1e-8, 1e-10).choose(J)
    assert sorted(basis.dep.tolist()) == sorted(perm[:m].tolist())


def test_sparse_and_dense_jacobians_give_the_same_run(chain):
    """The 40-window chain through its first passage (1 s, hybrid at rtol 1e-8) with the
    CSR Φ_q and with dense arrays: the passage bridged by both, and states equal to 1e-8
    (ten times rtol: the two round off differently)."""
    mech, prob, _, _ = chain
    kw = dict(t_end=1.0, method="hybrid", rtol=1e-8, atol=1e-10, output_step=0.05)
    sparse_run = mech.simulate(**kw)
    prob.sparse = False
    try:
        dense_run = mech.simulate(**kw)
    finally:
        prob.sparse = True
    assert sparse_run.status == dense_run.status == "success"
    assert sparse_run.stats["bridges"] == dense_run.stats["bridges"] == 1
    np.testing.assert_allclose(sparse_run.q, dense_run.q, atol=1e-8)
    theta, _ = ms.examples.parallelogram_exact(sparse_run.t, math.pi / 2, -1.0, n=40)
    np.testing.assert_allclose(sparse_run.coordinate("crank1.angle"), theta, atol=1e-7)
