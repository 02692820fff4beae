"""A new constraint algebra is one class against `mechsim.problem.algebra.ConstraintAlgebra`'s
contract: this test writes one (pivots from column-pivoted QR of Φ_q, the Schur complement
from QR of J̃ᵀ, J̃J̃ᵀ = RᵀR), installs it, and the partitioned, projection and hybrid methods
run the double four-bar through its passages on it as on the dense algebra."""

import numpy as np
import pytest
import scipy.linalg as sla

import mechsim as ms
from mechsim.linalg import sparse
from mechsim.problem.algebra import BandedAlgebra, ConstraintAlgebra, DenseAlgebra


class QRAlgebra(ConstraintAlgebra):
    name = "qr"

    def __init__(self, problem):
        super().__init__(problem)
        self.calls = {"pivots": 0, "clear": 0}

    def pivots(self, J):
        self.calls["pivots"] += 1
        return sla.qr(sparse.dense(J), pivoting=True, mode="r")[1]

    def clear_solver(self, J, f, cut, bound):
        Jt = f.cols(sparse.dense(J))
        if not Jt.shape[0]:
            return None
        R = sla.qr(Jt.T, mode="r")[0][:Jt.shape[0]]
        s = np.linalg.svd(R, compute_uv=False)       # J̃'s singular values
        if not s[-1] > 10.0 * cut * s[0]:
            return None
        return lambda r: sla.cho_solve((R, False), r)

    def clear_accelerations(self, J, Q, gamma, q, cut, bound, far):
        self.calls["clear"] += 1
        f = self.problem.mass_factor(q)
        solve = self.clear_solver(J, f, cut, bound)
        if solve is None:
            return None
        Jt = f.cols(sparse.dense(J))
        x = f.left(Q)
        return f.right(x - Jt.T @ solve(Jt @ x - gamma))


def test_the_problem_chooses_its_algebra_once():
    prob = ms.examples.double_four_bar().problem()
    assert isinstance(prob.algebra, DenseAlgebra) and prob.algebra is prob.algebra
    chain = ms.examples.double_four_bar(n=40).problem(build="assembled")
    assert isinstance(chain.algebra, BandedAlgebra)
    chain.schur = None                                   # forcing the dense path chooses again
    assert isinstance(chain.algebra, DenseAlgebra)
    with pytest.raises(ValueError, match="made for this problem"):
        prob.algebra = DenseAlgebra(chain)


@pytest.mark.parametrize("method", ["lu", "projection", "hybrid"])
def test_a_new_algebra_serves_every_method(method):
    mech = ms.examples.double_four_bar()
    settings = dict(method=method, rtol=1e-8, atol=1e-10, output_step=0.01)
    reference = mech.simulate(2.0, **settings)
    prob = mech.problem()
    algebra = QRAlgebra(prob)
    prob.algebra = algebra
    res = mech.simulate(2.0, **settings)
    assert reference.success and res.success, res.message
    assert algebra.calls["pivots" if method == "lu" else "clear"] > 0
    # Another algebra, other round-off: the same motion to the integration tolerance, and
    # the same passages (two in 2 s).
    assert np.max(np.abs(res.q - reference.q)) < 1e-5
    assert len(res.singular_passages) == len(reference.singular_passages) == 2
    for a, b in zip(res.singular_passages, reference.singular_passages):
        assert abs((a.t_min or a.t_start) - (b.t_min or b.t_start)) < 1e-3


def _singular_values(A):
    return np.linalg.svd(A, compute_uv=False)


def test_the_fall_basis_bounds_how_far_a_singular_value_falls(rng):
    """σ_k(A') ≥ σ_k(A) − ‖(A' − A) P‖₂ with P = `fall_basis` (an independent SVD of A'
    checks it) on random wide matrices of unequal column scales, for the smallest and
    for an inner singular value, of full rank and rank-deficient; exact where A' lowers
    σ_k along its own singular vectors, and blind to a change of σ_max alone, which
    Weyl's ‖A' − A‖₂ counts whole."""
    from mechsim.linalg.dense import fall_basis
    for _ in range(400):
        m = int(rng.integers(1, 7))
        n = m + int(rng.integers(0, 4))
        A = rng.normal(size=(m, n)) * np.exp(2.0 * rng.normal(size=n))
        if rng.random() < 0.2 and m > 1:
            A[-1] = A[0] * rng.normal()                   # rank lost
        U, sig, Vt = np.linalg.svd(A, full_matrices=False)
        k = int(rng.integers(0, m))
        E = rng.normal(size=(m, n)) * 10.0 ** rng.uniform(-4, 1) * sig[0]
        P = fall_basis(sig, Vt.T, k)
        assert _singular_values(A + E)[k] >= sig[k] - np.linalg.norm(E @ P, 2) - 1e-12 * sig[0]
    A = np.diag([10.0, 1.0, 0.5]) @ np.eye(3, 4)
    U, sig, Vt = np.linalg.svd(A, full_matrices=False)
    P = fall_basis(sig, Vt.T, 2)
    lower = -0.2 * np.outer(U[:, 2], Vt[2])                # σ_min 0.5 → 0.3
    assert _singular_values(A + lower)[2] == pytest.approx(0.3, rel=1e-12)
    assert np.linalg.norm(lower @ P, 2) == pytest.approx(0.2, rel=1e-12)
    stretch = 3.0 * np.outer(U[:, 0], Vt[0])              # σ_max 10 → 13, σ_min kept
    assert _singular_values(A + stretch)[2] == pytest.approx(0.5, rel=1e-12)
    assert np.linalg.norm(stretch @ P, 2) == pytest.approx(3.0 * 0.5 / 10.0, rel=1e-12)


def test_the_extreme_bounds_hold_the_extreme_singular_values(rng):
    """`extreme_bounds` (σ_min from below, σ_max from above, without an SVD; the engine's
    in numpy) on random wide matrices of unequal column scales and magnitudes from 1e-20
    to 1e20: each within m^⅛ of the singular value (an independent SVD) where it gives
    them, which it does wherever round-off cannot reach their margins; exact but for
    those margins for orthogonal rows; None where the rank is lost."""
    from mechsim.linalg.dense import extreme_bounds
    for _ in range(300):
        m = int(rng.integers(1, 15))
        n = m + int(rng.integers(0, 4))
        A = rng.normal(size=(m, n)) * np.exp(2.0 * rng.normal(size=n))
        A *= 10.0 ** rng.uniform(-20, 20)
        sig = _singular_values(A)
        got = extreme_bounds(A)
        if got is None:           # round-off of 4 (m + n) ε cond(J J^T) could reach 1e-7
            assert 4 * (m + n) * np.finfo(float).eps * m ** 0.5 * (sig[0] / sig[-1]) ** 2 > 1e-7
            continue
        lo, hi = got
        assert sig[-1] * m ** -0.125 * (1 - 1.1e-6) <= lo <= sig[-1]
        assert sig[0] <= hi <= sig[0] * m ** 0.125 * (1 + 2e-12)
    Q = np.linalg.qr(rng.normal(size=(5, 5)))[0][:3] * 7.0      # σ all 7
    assert extreme_bounds(Q) == pytest.approx(
        (7.0 * 3 ** -0.125 * (1 - 1e-6), 7.0 * 3 ** 0.125 * (1 + 1e-12)), rel=1e-12)
    A = rng.normal(size=(4, 6))
    A[3] = 2.0 * A[1]
    assert extreme_bounds(A) is None


def test_the_engine_s_fall_is_the_python_algebra_s():
    """The compiled measurement's fall (dJ̃/dt, P) equals the Python algebra's at states of
    the double four-bar (P up to the signs of singular vectors: PPᵀ is compared)."""
    prob = ms.examples.double_four_bar().problem()
    if prob.algebra.engine is None:
        pytest.skip("no compiled engine here (no C compiler)")
    res = ms.examples.double_four_bar().simulate(0.5, output_step=0.1)
    k = prob.m - 1
    for t, q, v in zip(res.t, res.q, res.v):
        eps = 1e-7 / np.max(np.abs(v))
        got = prob.algebra.measure(q, t, v, eps, k)
        ref = ConstraintAlgebra.measure(prob.algebra, q, t, v, eps, k)
        np.testing.assert_allclose(got[:2], ref[:2], rtol=1e-12)
        (D, P), (D_ref, P_ref) = got[-1], ref[-1]
        np.testing.assert_allclose(D, D_ref, rtol=0, atol=1e-6 * np.abs(D_ref).max())
        np.testing.assert_allclose(P @ P.T, P_ref @ P_ref.T, rtol=0, atol=1e-9)


def test_one_lu_gives_the_inverse_and_the_sign_of_the_determinant(rng):
    """`inv_and_sign`: the inverse to round-off and det's sign, against numpy's `inv` and
    `slogdet`, on random matrices with rows permuted (every parity of row swaps) and
    negative pivots; (None, 0) for an exactly singular matrix, 1 for an empty one."""
    from mechsim.linalg.dense import inv_and_sign
    signs = set()
    for _ in range(300):
        n = int(rng.integers(1, 9))
        A = rng.normal(size=(n, n))[rng.permutation(n)] * rng.choice([-1.0, 1.0], size=n)
        Ai, sign = inv_and_sign(A)
        assert sign == int(np.linalg.slogdet(A)[0])
        np.testing.assert_allclose(Ai @ A, np.eye(n), rtol=0, atol=1e-9 * np.linalg.cond(A))
        signs.add(sign)
    assert signs == {-1, 1}
    singular = np.array([[1.0, 2.0, 0.0], [2.0, 4.0, 0.0], [0.0, 0.0, 1.0]])
    assert inv_and_sign(singular) == (None, 0)
    empty, sign = inv_and_sign(np.zeros((0, 0)))
    assert empty.shape == (0, 0) and sign == 1
