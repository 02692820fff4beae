"""The singularity monitor's search for a passage inside a step, in the compiled engine
(`ConstraintAlgebra.anchored`, `passage_minimum`): the Python search's numbers, and
Brent's bounded minimum as scipy finds it."""


import numpy as np
import pytest
from conftest import needs_compiler
from scipy.optimize import minimize_scalar

from mechsim.app.bench import PROBLEMS
from mechsim.formulations.partitioned import Partitioned
from mechsim.problem.algebra import DenseAlgebra


def _run(name, method, rtol):
    p = PROBLEMS[name]
    mech = p.build()
    return mech, dict(t_end=p.t_end, method=method, rtol=rtol, atol=rtol * 1e-2,
                      output_step=p.t_end / 1000, max_step=p.max_step)


@needs_compiler
@pytest.mark.parametrize("name, method, rtol", [
    ("double-four-bar", "lu", 3e-3),          # positions solved on the partition
    ("double-four-bar", "projection", 1e-6),  # positions the state's first entries
    ("double-four-bar", "hybrid", 1e-8),
    ("parallelogram", "hybrid", 1e-6),
])
def test_the_compiled_search_is_the_python_search_to_the_bit(name, method, rtol,
                                                             monkeypatch):
    """With the search in the engine and without it (Python's `_anchored` on the same
    positions and singular values) the runs are the same to the bit: samples, steps and
    every passage's span, minimum and time; and the engine searched. The loop's own steps
    (the segments, which search in the engine themselves, compare with the loop in
    `test_segment`)."""
    from mechsim.run import segment
    monkeypatch.setattr(segment, "enabled", False)
    mech, run = _run(name, method, rtol)
    searched = []
    anchored = DenseAlgebra.anchored

    def counted(self, *args):
        got = anchored(self, *args)
        searched.append(got is not None)
        return got
    monkeypatch.setattr(DenseAlgebra, "anchored", counted)
    fast = mech.simulate(**run)
    monkeypatch.setattr(DenseAlgebra, "anchored", lambda self, *args: None)
    slow = mech.simulate(**run)
    assert fast.success and sum(searched) >= 10
    for a, b in ((fast.t, slow.t), (fast.q, slow.q), (fast.v, slow.v)):
        assert a.shape == b.shape and a.tobytes() == b.tobytes()
    assert fast.stats["steps"] == slow.stats["steps"]
    assert len(fast.singular_passages) >= 3
    assert [(p.t_start, p.t_end, p.min_sigma, p.t_min) for p in fast.singular_passages] == \
        [(p.t_start, p.t_end, p.min_sigma, p.t_min) for p in slow.singular_passages]


def _brent_by_scipy(algebra, dense, ta, tb, k, xatol, positions):
    """(t, s) of scipy's bounded minimum of (σ_k/σ_max)² over [ta, tb] of the step `dense`,
    the configurations by `positions(t, y)`, the singular values the engine's; s there."""
    def s_at(t):
        smin, smax = algebra.singular_extremes([t], positions(t, dense(t))[None, :], k)[0]
        return smin / smax
    found = minimize_scalar(lambda t: s_at(t) ** 2, bounds=(ta, tb), method="bounded",
                            options={"xatol": xatol})
    return float(found.x), float(s_at(found.x))


@needs_compiler
def test_a_passage_s_minimum_is_brent_s_as_scipy_finds_it(monkeypatch):
    """The engine's minimum of σ_min/σ_max over an interval of a step (Brent's bounded
    search on its square, smooth where it is V-shaped), the positions solved on the
    partition, lands where scipy's `minimize_scalar(method="bounded")` lands on the same
    function (the engine's positions and singular values, called from Python), to the
    bit; and its minimum is a passage's: under 1e-6 at the double four-bar's change
    points."""
    from mechsim.run import segment
    monkeypatch.setattr(segment, "enabled", False)    # the loop's steps
    mech, run = _run("double-four-bar", "lu", 3e-3)
    forms, compared = [], []
    context = Partitioned.positions_context

    def recorded(self):
        forms.append(self)
        return context(self)
    monkeypatch.setattr(Partitioned, "positions_context", recorded)
    minimum = DenseAlgebra.passage_minimum

    def checked(self, lu_context, dense, ta, tb, k, xatol):
        got = minimum(self, lu_context, dense, ta, tb, k, xatol)
        compared.append((got, _brent_by_scipy(self, dense, ta, tb, k, xatol,
                                              lambda t, y: forms[-1].engine.state(t, y)[0])))
        return got
    monkeypatch.setattr(DenseAlgebra, "passage_minimum", checked)
    res = mech.simulate(**run)
    assert res.success and len(compared) >= 5
    for got, expected in compared:
        assert got == expected
        assert got[1] < 1e-6


@needs_compiler
def test_the_minimum_on_a_state_in_all_coordinates_is_brent_s_too(monkeypatch):
    """The projection method's steps (positions the state's first entries): on every step
    the search looks into, the engine's minimum over the step is scipy's to the bit (the
    loop's steps: segments search in the engine themselves)."""
    from mechsim.run import segment
    monkeypatch.setattr(segment, "enabled", False)
    mech, run = _run("double-four-bar", "projection", 1e-6)
    compared = []
    anchored = DenseAlgebra.anchored

    def checked(self, lu_context, dense, ends, budget, known, k, search):
        assert lu_context == 0
        ta, tb = ends
        xatol = 1e-5 * (tb - ta)
        compared.append((self.passage_minimum(0, dense, ta, tb, k, xatol),
                         _brent_by_scipy(self, dense, ta, tb, k, xatol,
                                         lambda t, y: y[:self.problem.n])))
        return anchored(self, lu_context, dense, ends, budget, known, k, search)
    monkeypatch.setattr(DenseAlgebra, "anchored", checked)
    assert mech.simulate(**run).success and len(compared) >= 10
    for got, expected in compared:
        assert got == expected


def _states(name, rtol=1e-6):
    """A run's configurations and its mechanism's constraint algebra (with the engine)."""
    p = PROBLEMS[name]
    mech = p.build()
    res = mech.simulate(t_end=p.t_end, method="hybrid", rtol=rtol, atol=rtol * 1e-2,
                        output_step=p.t_end / 400, max_step=p.max_step)
    return res, mech.problem().algebra


@needs_compiler
@pytest.mark.parametrize("name", ["double-four-bar", "crank-rocker", "parallelogram"])
def test_floor_anchors_bound_the_extreme_singular_values_without_an_svd(name):
    """The passage search's floor anchors (`ProjectionEngine.extreme_bounds`) hold σ_min of
    J̃ from below and σ_max from above at every configuration of a run, through its
    passages, within m^(1/8) of each as their construction promises; they decline (NaN)
    only where J̃J̃ᵀ is ill-conditioned, near a passage."""
    res, algebra = _states(name)
    bounds = algebra.engine.extreme_bounds(res.t, res.q)
    sig = np.array([np.linalg.svd(algebra.scaled_jacobian(q, t), compute_uv=False)
                    for t, q in zip(res.t, res.q)])
    m = sig.shape[1]
    smin, smax = sig[:, -1], sig[:, 0]
    fine = ~np.isnan(bounds[:, 0])
    assert fine.mean() > 0.9
    floor, ceiling = bounds[fine, 0], bounds[fine, 1]
    assert np.all(floor <= smin[fine]) and np.all(ceiling >= smax[fine])
    spread = m ** 0.125 * (1.0 + 1e-6)
    assert np.all(floor * spread >= smin[fine]) and np.all(ceiling <= spread * smax[fine])
    ratio = smin / smax
    assert np.all(ratio[~fine] < 1e-3 * ratio.max())       # declined near passages only


@needs_compiler
@pytest.mark.parametrize("name, method, rtol", [
    ("double-four-bar", "lu", 1e-3),
    ("double-four-bar", "hybrid", 1e-4),
    ("crank-rocker", "lu", 3e-3),
])
def test_floor_anchors_change_no_number_of_a_run(name, method, rtol):
    """Floors only clear where s stays above `enter`, and a step they cannot prove clear is
    searched as without them: runs with and without floor anchors are the same to the bit
    (samples, steps, every passage), and the run with them took floors."""
    mech, run = _run(name, method, rtol)
    search = mech.problem().algebra.engine.steps.search
    runs = []
    for floors in (1, 0):
        search.floors, search.floors_taken = floors, 0
        runs.append((mech.simulate(**run), search.floors_taken))
    search.floors = 1
    (fast, taken), (slow, none) = runs
    assert fast.success and taken > 0 and none == 0
    for a, b in ((fast.t, slow.t), (fast.q, slow.q), (fast.v, slow.v)):
        assert a.shape == b.shape and a.tobytes() == b.tobytes()
    assert [(p.t_start, p.t_end, p.min_sigma, p.t_min) for p in fast.singular_passages] == \
        [(p.t_start, p.t_end, p.min_sigma, p.t_min) for p in slow.singular_passages]


@needs_compiler
@pytest.mark.parametrize("name", ["double-four-bar", "crank-rocker", "parallelogram"])
def test_the_engine_s_extreme_singular_values_are_lapack_s_to_round_off(name):
    """The search's σ_k and σ_max (`ProjectionEngine.extremes`: Householder bidiagonal in
    plain loops, LAPACK's dqds) equal numpy's SVD of J̃ to round-off at every
    configuration of a run through its passages: σ_max to a few ulps, σ_min within
    m ε σ_max (both backward stable: an absolute error of ε‖J̃‖, relative near a
    passage)."""
    res, algebra = _states(name, rtol=1e-8)
    m = algebra.problem.m
    got = algebra.engine.extremes(res.t, res.q, m - 1)
    sig = np.array([np.linalg.svd(algebra.scaled_jacobian(q, t), compute_uv=False)
                    for t, q in zip(res.t, res.q)])
    np.testing.assert_allclose(got[:, 1], sig[:, 0], rtol=1e-14)
    assert np.all(np.abs(got[:, 0] - sig[:, -1]) <= 4 * m * 2.2e-16 * sig[:, 0])
    assert (sig[:, -1] / sig[:, 0]).min() < 1e-2 * (sig[:, -1] / sig[:, 0]).max() or \
        name == "crank-rocker"                      # the runs pass their passages


@needs_compiler
def test_the_monitor_s_ratio_is_its_measurement_without_the_vectors():
    """`SingularityMonitor.ratio` (the search's singular values, no vectors: the dips'
    checks and the bridge's landing) is `measure`'s σ_min/σ_max to round-off (m ε) at
    every configuration of a run through the double four-bar's passages."""
    from mechsim.formulations.monitor import SingularityMonitor
    res, algebra = _states("double-four-bar")
    monitor = SingularityMonitor(algebra.problem)
    got = np.array([monitor.ratio(q, t) for t, q in zip(res.t, res.q)])
    want = np.array([monitor.measure(q, t)[0] for t, q in zip(res.t, res.q)])
    assert np.all(np.abs(got - want) <= 4 * algebra.problem.m * 2.2e-16)
    assert want.min() < 1e-2 * want.max()


@needs_compiler
@pytest.mark.parametrize("name, method, rtol", [
    ("crank-rocker", "projection", 3e-4),     # never near the band: long steps skipped
    ("crank-rocker", "lu", 1e-4),
    ("double-four-bar", "hybrid", 1e-10),     # falls from its peak (s has no rate there)
    ("double-four-bar", "lu", 1e-10),
])
def test_a_skipped_measurement_hides_no_approach_to_the_band(name, method, rtol,
                                                              monkeypatch):
    """Where the monitor skips a step's measurement, σ_min/σ_max measured afresh by an
    SVD stays above twice `enter` of the peak at every output sample of that step, and
    the floor the skip took lies below the ratio at the step's end; the run's passages
    are those of a run that measures every step, bridged where those are."""
    from mechsim.formulations.monitor import SingularityMonitor
    from mechsim.run import segment
    skips = []
    may_skip = SingularityMonitor._may_skip

    def logged(self, q, t, t_old, speed):
        got = may_skip(self, q, t, t_old, speed)
        if got[0]:
            skips.append((t_old, t, q.copy(), self._floor[1], self.peak, self.enter))
        return got
    monkeypatch.setattr(SingularityMonitor, "_may_skip", logged)
    monkeypatch.setattr(segment, "enabled", False)
    mech, run = _run(name, method, rtol)
    res = mech.simulate(**run)
    assert res.success and skips
    algebra = mech.problem().algebra

    def ratio(t, q):
        sig = np.linalg.svd(algebra.scaled_jacobian(q, t), compute_uv=False)
        return sig[-1] / sig[0]
    for t_old, t, q, floor, peak, enter in skips:
        assert floor <= ratio(t, q) * (1 + 1e-12)
        inside = (res.t > t_old) & (res.t <= t)
        assert all(ratio(tk, qk) > 2.0 * enter * peak
                   for tk, qk in zip(res.t[inside], res.q[inside]))
    monkeypatch.setattr(SingularityMonitor, "max_skip", 0)
    every = mech.simulate(**run)
    assert len(res.singular_passages) == len(every.singular_passages)
    for a, b in zip(res.singular_passages, every.singular_passages):
        assert a.t_min == pytest.approx(b.t_min, abs=1e-2) and a.bridged == b.bridged
