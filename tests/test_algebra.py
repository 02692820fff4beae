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
