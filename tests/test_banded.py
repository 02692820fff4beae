"""The banded Schur complement of large rigid mechanisms (`mechsim.linalg.banded`): the same numbers
as the dense path, from a factor whose band does not grow with the mechanism."""

import math

import numpy as np
import pytest

import mechsim as ms
from mechsim.linalg import sparse
from mechsim.linalg.banded import BandedSchur
from mechsim.app.bench import Problem
from mechsim.examples import parallelogram_constants
from mechsim.formulations.monitor import SingularityMonitor
from mechsim.formulations.projection import Projection


def chain_state(n, theta, w=-2.0):
    """A consistent state of the N-window chain on its parallelogram branch, all cranks at
    θ turning at w."""
    c, s = math.cos(theta), math.sin(theta)
    q, v = [], []
    for i in range(n + 1):
        q += [i + 0.5 * c, 0.5 * s, theta]
        v += [-0.5 * s * w, 0.5 * c * w, w]
    for i in range(n):
        q += [i + c + 0.5, s, 0.0]
        v += [-s * w, c * w, 0.0]
    return np.array(q), np.array(v)


@pytest.fixture(scope="module")
def ten_window():
    return ms.examples.double_four_bar(10).problem()


def test_band_does_not_grow_with_the_chain(ten_window):
    """Ordered by reverse Cuthill–McKee, S of an N-window chain has the same half-bandwidth
    for every N; the small double four-bar stays on the dense path."""
    assert ten_window.m == 62 and ten_window.schur is not None
    eight = ms.examples.double_four_bar(8).problem()
    assert eight.m == 50
    assert ten_window.schur.kd == eight.schur.kd <= 6
    assert ms.examples.double_four_bar(2).problem().schur is None


def test_banded_schur_solves_and_extremes_match_dense(ten_window, rng):
    prob = ten_window
    band = BandedSchur(prob.model.JACOBIAN_ROWS, prob.model.JACOBIAN_COLS,
                       (prob.m, prob.n), prob.inverse_mass_diagonal)
    q, v = chain_state(10, 0.4)
    q = q + 0.05 * rng.standard_normal(q.size)           # off the branch: a generic Φ_q
    J = prob.phi_q(q, 0.0)
    S = (J * prob.inverse_mass_diagonal) @ J.T
    c = band.factor(J)
    r = rng.standard_normal(prob.m)
    np.testing.assert_allclose(band.solve(c, r), np.linalg.solve(S, r), rtol=1e-10,
                               atol=1e-12 * np.abs(np.linalg.solve(S, r)).max())
    lam = np.linalg.eigvalsh(S)
    lo, u_lo = band.smallest(c)
    hi, u_hi = band.largest()
    assert lo == pytest.approx(lam[0], rel=1e-3)
    assert hi == pytest.approx(lam[-1], rel=1e-12)
    assert np.linalg.norm(S @ u_lo - lam[0] * u_lo) <= 1e-2 * lam[0]
    assert np.linalg.norm(S @ u_hi - hi * u_hi) <= 1e-8 * hi
    assert lam[-1] <= band.largest_bound() <= 3.0 * lam[-1]
    # Scaled form (the monitor's J̃ = Φ_q M^{-1/2}) is the same matrix.
    Jt = J * np.sqrt(prob.inverse_mass_diagonal)
    assert np.allclose(band.assemble(Jt, scaled=True), band.assemble(J), rtol=1e-12, atol=0)


def test_the_banded_projection_factor_is_declined_where_sigma_min_nears_the_cut(ten_window,
                                                                                rng):
    """The banded path factors S = Φ_q M⁻¹ Φ_qᵀ for the projection method only where
    σ_min² of J̃ is above (2 cut)² times a Gershgorin bound of σ_max² (certified by the
    Cholesky factor of S less that much of the identity): a cut 0.1 % below that of S's
    exact least eigenvalue is served, one 0.1 % above is declined (the dense path takes
    it), at a generic state and near a singular configuration of the chain; where the
    monitor found the motion far from the band (`far`), S's own factor serves."""
    prob = ten_window
    alg = prob.algebra
    for theta, off in ((0.4, 0.05), (1e-4, 0.0)):
        q, _ = chain_state(10, theta)
        J = prob.phi_q(q + off * rng.standard_normal(q.size), 0.0)
        S = (J * prob.inverse_mass_diagonal) @ J.T
        low = np.linalg.eigvalsh(S)[0]
        assert alg.band.factor(J) is not None
        gershgorin = alg.band.largest_bound()
        cut = 0.5 * math.sqrt(low / gershgorin)
        assert alg.clear_solver(J, None, cut * (1 - 1e-3), None) is not None
        assert alg.clear_solver(J, None, cut * (1 + 1e-3), None) is None
        # Where the monitor found the motion far from the band, S's own factor serves
        # (as on the dense path): the exact accelerations, whatever the cut.
        w, Q = prob.inverse_mass_diagonal, rng.standard_normal(prob.n)
        gamma = rng.standard_normal(prob.m)
        exact = w * Q - w * (J.T @ np.linalg.solve(S, J @ (w * Q) - gamma))
        args = (J, Q, gamma, q, cut * (1 + 1e-3), None)
        assert alg.clear_accelerations(*args, False) is None
        np.testing.assert_allclose(alg.clear_accelerations(*args, True), exact,
                                   rtol=1e-12 * gershgorin / low,
                                   atol=1e-12 * np.abs(exact).max() * gershgorin / low)


def test_the_largest_eigenvalue_from_a_warm_start_is_certified(ten_window, rng):
    """`largest` from the previous call's vector (Lanczos, `top_pair`) along a path of
    perturbed chain states, and from the eigenvector of the second eigenvalue (where two
    of the crowded top eigenvalues cross, the previous vector is that one): within 1e-3
    of λ_max at every state. From the second eigenvector Lanczos alone settles on the
    second eigenvalue: the certificate (a Cholesky factor of θ (1 + 1e-3) I − S) catches
    it and the exact path serves."""
    from mechsim.linalg.banded import top_pair
    prob = ten_window
    band = BandedSchur(prob.model.JACOBIAN_ROWS, prob.model.JACOBIAN_COLS,
                       (prob.m, prob.n), prob.inverse_mass_diagonal)
    q0, _ = chain_state(10, 0.4)
    step = 0.01 * rng.standard_normal(q0.size)
    wrong = 0
    for k in range(40):
        J = prob.phi_q(q0 + k * step, 0.0)
        S = (J * prob.inverse_mass_diagonal) @ J.T
        lam, U = np.linalg.eigh(S)
        band.factor(J)
        if k % 4 == 3:                   # as if the top two eigenvalues had just crossed
            band._high = U[:, -2].copy()
            alone = top_pair(band._matvec, band._high[band.perm])
            wrong += alone is not None and alone[0] < (1.0 - 1e-3) * lam[-1]
        hi, u = band.largest()
        assert lam[-1] * (1.0 - 1e-3) <= hi <= lam[-1] * (1.0 + 1e-12)
        assert np.linalg.norm(S @ u - hi * u) <= 1.1e-3 * hi
    assert wrong >= 1


def test_near_a_chain_s_singular_configuration_the_band_measures_without_an_svd(
        ten_window, monkeypatch):
    """The ten-window chain with every crank at θ → 0 (all windows singular at once): the
    banded extremes without a dense SVD (it costs O(m³)) down to θ = 1e-10, σ_max and,
    while σ_min/σ_max ≥ 1e-7, σ_min as the SVD's to 1e-6; below, a σ_min not under
    the SVD's (to round-off of σ_max) and under 1e-6 σ_max (the monitor's decisions need
    no more), its vector one J̃ᵀ maps to that length."""
    from mechsim.linalg import dense
    from mechsim.problem import algebra as A
    prob = ten_window
    alg = prob.algebra
    exact = {}
    for theta in (1e-2, 1e-4, 1e-6, 1e-8, 1e-10):
        Jt = alg.scaled_jacobian(chain_state(10, theta)[0], 0.0)
        exact[theta] = (Jt, A._svd_extremes(Jt, prob.m - 1)[0])
    alg.band.forget()

    def no_svd(*args, **kwargs):
        raise AssertionError("the dense SVD was called")
    monkeypatch.setattr(dense, "svd", no_svd)
    for theta, (Jt, svd) in exact.items():
        smin, u, v, smax, _, _ = alg.extremes(Jt, prob.m - 1)
        assert smax == pytest.approx(svd[3], rel=1e-3)
        if svd[0] >= 1e-7 * svd[3]:
            assert smin == pytest.approx(svd[0], rel=1e-6)
        else:
            assert svd[0] - 1e-14 * smax <= smin <= 1e-6 * smax      # (round-off of σ_max)
            assert np.linalg.norm(sparse.dense(Jt).T @ u) == pytest.approx(smin, rel=1e-12)


@pytest.mark.parametrize("theta", [0.5, 0.05])
def test_banded_accelerations_match_the_svd_path(ten_window, theta):
    """Away from the truncation band the banded Schur complement gives the projection
    method's q̈ (checked against the branch's exact θ̈ = −K/M_eff cos θ) and the dense
    path's to round-off; the monitor's σ_min/σ_max matches the SVD's."""
    prob = ten_window
    q, v = chain_state(10, theta)
    assert prob.schur is not None
    banded = Projection(prob, 1e-8, 1e-10).accelerations(0.0, q, v)
    m_eff, k = parallelogram_constants(10)
    assert banded[2] == pytest.approx(-k / m_eff * math.cos(theta), rel=1e-9)
    band, prob.schur = prob.schur, None
    try:
        dense = Projection(prob, 1e-8, 1e-10).accelerations(0.0, q, v)
        s_dense = SingularityMonitor(prob).measure(q, 0.0, v)[:2]
    finally:
        prob.schur = band
    np.testing.assert_allclose(banded, dense, rtol=0, atol=1e-10 * np.abs(dense).max())
    s_band = SingularityMonitor(prob).measure(q, 0.0, v)[:2]
    assert s_band[0] == pytest.approx(s_dense[0], rel=1e-3)
    assert s_band[1] == pytest.approx(s_dense[1], rel=1e-2)


@pytest.fixture(scope="module")
def ten_window_csr(tmp_path_factory):
    """The ten-window chain's fused model generated as those of `CSR_MIN_COORDINATES` or
    more are (Φ_q also as its non-zero entries), in a cache of its own."""
    from mechsim.codegen import cache, compiled
    patch = pytest.MonkeyPatch()
    patch.setattr(compiled, "CSR_MIN_COORDINATES", 60)
    patch.setenv("MECHSIM_CACHE_DIR", str(tmp_path_factory.mktemp("csr")))
    cache.clear_memory_cache()
    try:
        yield ms.examples.double_four_bar(10).problem(build="fused")
    finally:
        patch.undo()
        cache.clear_memory_cache()


def test_a_long_chain_s_fused_model_gives_its_jacobian_as_csr(ten_window_csr, rng):
    """Φ_q as a CSR array of its pattern from the fused model (its C twins), equal to the
    dense Φ_q to the bit in each function that gives it, with the pattern's indices; the
    solvers then take it so, as they do the assembled model's."""
    prob = ten_window_csr
    model, p = prob.model, prob.p
    assert model.COMPILED and prob.sparse
    assembled = ms.examples.double_four_bar(10).problem(build="assembled").model
    q, v, t = rng.standard_normal(prob.n), rng.standard_normal(prob.n), 0.3
    forms = [(model.phi_q_csr(q, t, p), model.phi_q(q, t, p)),
             (model.position_terms_csr(q, t, p)[1], model.position_terms(q, t, p)[1]),
             (model.dynamics_terms_csr(q, v, t, p)[0], model.dynamics_terms(q, v, t, p)[0])]
    for csr, dense in forms:
        np.testing.assert_array_equal(csr.toarray(), dense)
        np.testing.assert_array_equal(csr.indices, assembled.phi_q_csr(q, t, p).indices)
    np.testing.assert_array_equal(model.position_terms_csr(q, t, p)[0], model.phi(q, t, p))
    np.testing.assert_array_equal(model.dynamics_terms_csr(q, v, t, p)[1],
                                  model.gamma(q, v, t, p))


@pytest.mark.parametrize("build", ["fused, Φ_q as CSR", "assembled"])
def test_a_chain_s_samples_settle_together_as_each_would_alone(build, rng, request):
    """A step's output samples of the ten-window chain, pushed off the constraints by 1e-6
    (more than a dense output drifts), are settled side by side (`settle_samples`: each
    its own chord, the evaluations of all in one call on the assembled build) to the
    points each sample's own `project_state` gives, on the constraints to round-off with
    consistent velocities."""
    from mechsim.formulations.full import ROUND_OFF, settle_samples
    prob = request.getfixturevalue("ten_window_csr") if build != "assembled" else \
        ms.examples.double_four_bar(10).problem(build=build)
    assert prob.sparse
    ts = np.linspace(0.0, 0.02, 6)
    states = [chain_state(10, theta, w) for theta, w in zip(np.linspace(0.3, 1.2, 6),
                                                            np.linspace(-2.0, 1.0, 6))]
    Q0 = np.array([q for q, _ in states]) + 1e-6 * rng.standard_normal((6, prob.n))
    V0 = np.array([v for _, v in states]) + 1e-6 * rng.standard_normal((6, prob.n))
    Q0[4] += 0.05 * rng.standard_normal(prob.n)      # too far for a chord: the full way
    Q, V = Q0.copy(), V0.copy()
    settle_samples(prob, ts, Q, V, 1e-6)
    for k, (t, q0, v0, q, v) in enumerate(zip(ts, Q0, V0, Q, V)):
        floor = ROUND_OFF * max(1.0, np.abs(q0).max())
        alone = prob.project_state(q0, v0, t, tol=floor)
        assert (alone is None) == (k == 4)
        if alone is None:
            at, _, _ = prob.project_positions(q0, t, tol=floor)
            alone = at, prob.project_velocities(at, v0, t)
        np.testing.assert_allclose(q, alone[0], rtol=0, atol=1e-14 * np.abs(q0).max())
        np.testing.assert_allclose(v, alone[1], rtol=0, atol=1e-13 * np.abs(v0).max())
        assert np.abs(prob.phi(q, t)).max() <= 1e3 * floor
        assert np.abs(prob.phi_q(q, t) @ v + prob.phi_t(q, t)).max() < 1e-10
        assert np.abs(q - q0).max() > 1e-7                    # it was moved


def test_ten_window_chain_runs_on_the_banded_path_between_passages(monkeypatch):
    """0.5 s of the 10-window chain by the projection method (its first singular passage is
    at 0.70 s): on the branch to 1e-8, and neither the accelerations, the projections nor
    the singularity monitor needed an SVD."""
    from mechsim.linalg import dense
    svds = []
    svd = dense.svd
    monkeypatch.setattr(dense, "svd", lambda A: svds.append(A.shape) or svd(A))
    res = ms.examples.double_four_bar(10).simulate(t_end=0.5, method="projection", rtol=1e-9,
                                                   atol=1e-11, output_step=0.01)
    assert res.status == "success", res.message
    branch = Problem("ten-window", None, 0.5, math.pi / 2, -1.0, 10)
    assert branch.error(res) <= 1e-8                  # largest crank-tip distance off the branch
    assert svds == []


def test_a_run_does_not_depend_on_the_runs_before_it():
    """The banded form keeps eigenvector warm starts between evaluations; a new run starts
    without them (before, a hybrid run after a projection run of the 40-window chain ended
    at another error and evaluation count than the same run alone)."""
    chain = ms.examples.double_four_bar(10)
    kw = dict(t_end=1.5, rtol=3e-9, atol=3e-11, output_step=0.01)
    first = chain.simulate(method="hybrid", **kw)
    chain.simulate(method="projection", **kw)
    again = chain.simulate(method="hybrid", **kw)
    assert first.stats["rhs_evaluations"] == again.stats["rhs_evaluations"]
    np.testing.assert_array_equal(first.q, again.q)


def test_lu_partitioning_factors_a_long_chains_dependent_block_as_a_band(ten_window):
    """Φ_q D of the ten-window chain (62 dependent coordinates), its constraints and
    coordinates ordered window by window, is a band of a few diagonals, factored by
    LAPACK's banded LU; SuperLU's factors (`SparseBlock`) serve where no order makes it a
    narrow band. Both: the dense solve's solution (one right-hand side and several), the
    sign of det Φ_q D as the dense LU gives it (and its change under a swap of two
    dependent coordinates' order), a condition estimate that bounds the exact 1-norm
    condition number from below within a factor of 3, nothing taken from numpy's global
    random generator."""
    from scipy.sparse import csc_matrix

    from mechsim.formulations.basis import BandBlock, SparseBlock, condition_number
    from mechsim.formulations.partitioned import Partitioned

    mech = ms.examples.double_four_bar(10)
    q = mech.simulate(t_end=0.2, method="lu").q[-1]
    J = ten_window.phi_q(q, 0.2)
    basis = Partitioned(ten_window, 1e-8, 1e-10).choose(J)
    band = basis.block(J)
    assert isinstance(band, BandBlock) and basis.r == J.shape[0] == 62
    assert band.kl + band.ku <= 12
    JD = basis.JD(J)
    exact = condition_number(JD)
    sign = int(np.linalg.slogdet(JD)[0])
    b = np.linspace(-1.0, 1.0, basis.r)
    B = np.column_stack([b, np.cos(np.arange(basis.r))])
    for block in (band, SparseBlock(csc_matrix(JD))):
        np.testing.assert_allclose(block.solve(b), np.linalg.solve(JD, b), rtol=1e-10,
                                   atol=1e-12)
        np.testing.assert_allclose(block.solve(B), np.linalg.solve(JD, B), rtol=1e-10,
                                   atol=1e-12)
        assert block.sign() == sign
        np.random.seed(7)
        assert exact / 3 <= block.condition() <= exact * (1 + 1e-9)
        # The estimate takes nothing from numpy's global random generator (runs stay
        # reproducible and a caller's random stream is left alone).
        after = np.random.rand()
        np.random.seed(7)
        assert after == np.random.rand()
    swapped = JD[:, [1, 0, *range(2, basis.r)]]
    assert SparseBlock(csc_matrix(swapped)).sign() == -sign
    # An exactly singular block (a column of zeros: a dependent coordinate no constraint
    # moves) is said so by both: sign 0, condition inf, a solve raises.
    J0 = J.copy()
    J0[:, basis.dep[5]] = 0.0
    for block in (basis.block(J0), SparseBlock(csc_matrix(basis.JD(J0)))):
        assert block.sign() == 0 and block.condition() == np.inf
        with pytest.raises(np.linalg.LinAlgError):
            block.solve(b)


@pytest.mark.parametrize("method", ["hybrid", "lu", "projection"])
def test_a_seven_window_chain_reports_each_passage_at_its_exact_instant(method):
    """The 7-window chain (44 constraint rows, under `SMALL_ROWS`, on the banded path) for
    3 s: its three singular passages, where every crank is flat (sin θ = 0 on the exact
    branch), each reported once and within 0.2 ms of the exact instant (2e-5 s seen), and
    the cranks on the branch within 20 rtol. (Its monitor bounds the search inside a step
    by the rates seen, as for longer chains.)"""
    n, rtol = 7, 1e-6
    res = ms.examples.double_four_bar(n).simulate(t_end=3.0, method=method, rtol=rtol,
                                                  atol=rtol * 1e-2, output_step=0.003)
    assert res.status == "success", res.message
    assert res.problem.schur is not None and res.problem.m == 44
    t = np.linspace(0.0, 3.0, 300001)
    theta, _ = ms.examples.parallelogram_exact(t, math.pi / 2, -1.0, n=n)
    s = np.sin(theta)
    k = np.flatnonzero(np.sign(s[1:]) != np.sign(s[:-1]))
    exact = t[k] - s[k] * (t[k + 1] - t[k]) / (s[k + 1] - s[k])
    got = np.array([p.t_min for p in res.singular_passages])
    assert len(exact) == 3 and got.shape == exact.shape, (got, exact)
    assert np.max(np.abs(got - exact)) < 2e-4, (got, exact)
    branch = Problem("seven-window", None, 3.0, math.pi / 2, -1.0, n)
    assert branch.error(res) <= 20 * rtol
