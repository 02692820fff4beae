"""The compiled evaluation of the partitioned formulations (`mechsim.codegen.engine`)
against the Python path it stands in for."""

import math
import os
import shutil
import sysconfig
import time
from pathlib import Path

import numpy as np
import pytest

from scipy.integrate import DOP853

import mechsim as ms
from mechsim.app.bench import PROBLEMS
from mechsim.codegen import cache, engine
from mechsim.integrators import CompiledDOP853
from mechsim.formulations.basis import ConstraintSolveError
from mechsim.formulations.partitioned import Partitioned
from mechsim.integrators.compiled import Interpolant
from mechsim.run import segment

from conftest import seeded_cache

needs_compiler = pytest.mark.skipif(
    shutil.which((os.environ.get("CC") or sysconfig.get_config_var("CC") or "cc").split()[0])
    is None or bool(os.environ.get("MECHSIM_NO_COMPILE")), reason="no C compiler")


ROOT = Path(__file__).resolve().parents[1]


def _pair(result, rtol=1e-9):
    """Two LU formulations partitioned at the end of `result`: compiled and Python."""
    prob = result.problem
    t, q, v = result.t[-1], result.q[-1], result.v[-1]
    pair = []
    for compiled in (True, False):
        f = Partitioned(prob, rtol, 1e-2 * rtol)
        y = f.initial_state(t, q, v)
        if not compiled:
            f.engine = None
        f.after_step(t, y, 0.0)
        pair.append(f)
    return pair, t, y


def _driven_slider_crank_with_pendulum():
    """One degree of freedom under rheonomic constraints (Φ_t ≠ 0): a pendulum hanging
    from the slider of a slider-crank whose crank is driven at 20 rad/s."""
    mech = ms.examples.slider_crank(driven=True, crank_speed=20.0)
    slider = next(b for b in mech.bodies if b.name == "slider")
    c = np.asarray(slider.position, float)
    bob = mech.add(ms.RigidBody.rod("bob", c, c + np.array([0.05, -0.2]), 0.1))
    mech.add(ms.Revolute(slider, bob, at=c, name="hang"))
    return mech


@needs_compiler
@pytest.mark.parametrize("build", [
    PROBLEMS["crank-rocker"].build,
    lambda: ms.examples.double_four_bar(2),
    lambda: _driven_slider_crank_with_pendulum(),
    lambda: ms.load_scene(ROOT / "mechanisms" / "cam_follower.toml").mechanism,
], ids=["crank-rocker", "double-four-bar", "driven-slider-crank-pendulum", "cam-follower"])
def test_the_jacobian_s_pattern_leaves_every_number_as_it_was(build):
    """J W Jᵀ summed over the columns each pair of rows shares in Φ_q's pattern (the
    engine's `complement` with `layout.pair_pattern`), its Cholesky factor and solves on
    the factor's pattern, J̃ and its differences over the pattern's entries alone, give
    the accelerations, the projected states, the multipliers, the passage search's
    floors, chords and singular values of the dense sums (or those over a row's nonzero
    columns found at each call), to the bit, off the constraints too (the chord Newton at
    work); the patterns leave most pairs of rows and entries of the factor out. The
    model's straight-line kernels of the same sums (`kernels.pattern_kernels`) give the
    index loops' numbers to the bit."""
    mech = build()
    prob = mech.problem()
    e = prob.algebra.engine
    assert e is not None and 0 < e.ctx.pairs < prob.m * (prob.m + 1) // 2
    q0 = mech.initial_coordinates()
    runs, pairs, ops = [], e.ctx.pairs, e.ctx.chol_ops
    assert 0 < ops < prob.m * (prob.m + 1) // 2 and e.ctx.kernels == 1
    try:
        for used in ((pairs, ops, 1), (pairs, ops, 0), (0, 0, 0)):
            e.ctx.pairs, e.ctx.chol_ops, e.ctx.kernels = used
            got, states = [], np.random.default_rng(7)
            for _ in range(10):
                t = 1e-4 * states.random()
                q = q0 + 1e-3 * states.standard_normal(prob.n)
                v, Q = states.standard_normal(prob.n), states.standard_normal(prob.n)
                acc = e.accelerations(t, q, v, Q, 1e-12)
                done = e.project_state(t, q, v, 1e-13)
                lam = np.zeros((1, prob.m))
                e.multipliers(np.array([t]), q[None], v[None], Q[None], -1.0, 0.0, lam)
                T, Qs = np.array([t, t + 1e-3]), np.array([q, q + 1e-3])
                got.append([acc, *(done or ()), lam, e.extreme_bounds(T, Qs),
                            e.chords(T, Qs), e.extremes(T, Qs, prob.m - 1)])
            runs.append(got)
    finally:
        e.ctx.pairs, e.ctx.chol_ops, e.ctx.kernels = pairs, ops, 1
    for other in runs[1:]:
        for a, b in zip(runs[0], other):
            assert len(a) == len(b) == 7
            for x, y in zip(a, b):
                assert x is not None and x.tobytes() == np.asarray(y).tobytes()


def _five_bar():
    """Two degrees of freedom: a five-bar (two cranks on the ground, two links pinned
    together) falling under gravity; its reduced mass is 2 x 2."""
    mech = ms.Mechanism("five-bar", gravity=(0.0, -9.81))
    A, B, C, D, E = (0.0, 0.0), (0.3, 0.4), (0.7, 0.9), (1.2, 0.5), (1.0, 0.0)
    crank = mech.add(ms.RigidBody.rod("crank1", A, B, mass=1.0))
    left = mech.add(ms.RigidBody.rod("link1", B, C, mass=1.0))
    right = mech.add(ms.RigidBody.rod("link2", C, D, mass=2.0))
    other = mech.add(ms.RigidBody.rod("crank2", E, D, mass=0.5))
    mech.add(ms.Revolute(mech.ground, crank, at=A))
    mech.add(ms.Revolute(crank, left, at=B))
    mech.add(ms.Revolute(left, right, at=C))
    mech.add(ms.Revolute(right, other, at=D))
    mech.add(ms.Revolute(other, mech.ground, at=E))
    return mech


@needs_compiler
@pytest.mark.parametrize("build", [
    lambda: ms.examples.double_four_bar(2),
    lambda: _driven_slider_crank_with_pendulum(),
    _five_bar,
], ids=["double-four-bar", "driven-slider-crank-pendulum", "five-bar"])
def test_compiled_evaluation_agrees_with_the_python_path(build, rng):
    """rhs, state and the output samples from the compiled engine equal the Python path's
    to round-off at states off the last step's path (the chord Newton has work to do);
    the five-bar's reduced accelerations solve a 2 x 2 reduced mass."""
    mech = build()
    res = mech.simulate(t_end=0.3, method="lu", rtol=1e-9, atol=1e-11)
    (fast, slow), t, y = _pair(res)
    assert fast.engine is not None and fast.engine.ready and slow.engine is None
    ts, ys = [], []
    for _ in range(20):
        tk = t + 2e-3 * rng.random()
        yk = y + 1e-4 * rng.normal(size=y.size) * (1.0 + np.abs(y))
        a, b = fast.rhs(tk, yk), slow.rhs(tk, yk)
        np.testing.assert_allclose(a, b, rtol=1e-11, atol=1e-11 * (1.0 + np.abs(b).max()))
        for x, z in zip(fast.state(tk, yk), slow.state(tk, yk)):
            np.testing.assert_allclose(x, z, rtol=0, atol=1e-12 * (1.0 + np.abs(z).max()))
        ts.append(tk)
        ys.append(yk)
    # Φ = 0 at the compiled state, to Newton's tolerance.
    q, _ = fast.state(ts[0], ys[0])
    assert np.abs(res.problem.phi(q, ts[0])).max() <= fast.newton_tol
    for x, z in zip(fast.states(np.array(ts), np.array(ys)), slow.states(np.array(ts), np.array(ys))):
        np.testing.assert_allclose(x, z, rtol=0, atol=1e-12 * (1.0 + np.abs(z).max()))
    # The end of a step in one call (`PartitionedEngine.end`): Φ_q D's inverse, A⁻¹ Φ_q B,
    # the sign of its determinant and its condition, as numpy's.
    for tk, yk in zip(ts[:5], ys[:5]):
        A, B = fast._block_at(tk, yk)[4], slow._block_at(tk, yk)[4]
        assert A.reduced is not None and B.reduced is None
        np.testing.assert_allclose(A.inverse(), B.inverse(), rtol=1e-10,
                                   atol=1e-12 * np.abs(B.inverse()).max())
        JB = slow.basis.JB(slow.full_state(tk, yk)[2])
        np.testing.assert_allclose(A.reduced, B.chord(JB), rtol=1e-10,
                                   atol=1e-12 * np.abs(B.chord(JB)).max())
        assert A.sign() == B.sign() != 0
        assert A.condition() == pytest.approx(B.condition(), rel=1e-10)
    # The signs of det(Φ_q D) the engine takes from its LU factors (which branch each
    # sample is on, `Partitioned.states`) are numpy's determinant's.
    Q, _, signs = fast.engine.states(np.array(ts), np.array(ys))
    J = np.array([res.problem.phi_q(q, tk) for q, tk in zip(Q, ts)])
    np.testing.assert_array_equal(signs, np.linalg.slogdet(fast.basis.JD(J))[0])


@needs_compiler
def test_runs_with_and_without_the_engine_agree():
    """A whole LU run (the slider-crank through its dead centres, with Adams) compiled and
    in Python: positions within 1e-8 m or rad (ten times rtol: the two paths round off
    differently, so a step may fall a little differently)."""
    mech = ms.examples.slider_crank(crank_angle=np.radians(60.0))
    run = dict(t_end=0.15, method="lu", rtol=1e-9, atol=1e-11, output_step=5e-4,
               integrator="adams")
    fast = mech.simulate(**run)
    model = fast.problem.model
    assert engine.library(model) is not None
    with engine.python_path(model):               # as without a compiler
        slow = mech.simulate(**run)
    assert fast.status == slow.status == "success"
    np.testing.assert_array_equal(fast.t, slow.t)                 # the output grid
    np.testing.assert_allclose(fast.q, slow.q, rtol=0, atol=1e-8)


def test_the_engine_applies_only_where_its_assumptions_hold(tmp_path, monkeypatch):
    """Not for a flexible mechanism (mass depends on q), a long chain (sparse Φ_q D and the
    banded Schur complement), or without a compiler: there the Python path runs, and the
    run still succeeds."""
    flexible = ms.examples.flexible_four_bar()
    res = flexible.simulate(t_end=0.01, method="lu")
    (f, _), _, _ = _pair(res, 1e-6)
    assert f.engine is None
    chain = ms.examples.double_four_bar(10)
    res = chain.simulate(t_end=0.01, method="lu")
    (f, _), _, _ = _pair(res, 1e-6)
    assert f.engine is None
    monkeypatch.setenv("MECHSIM_CACHE_DIR", str(tmp_path))
    monkeypatch.setenv("CC", str(tmp_path / "no-such-compiler"))
    cache.clear_memory_cache()
    try:
        mech = ms.examples.four_bar()
        res = mech.simulate(t_end=0.5, method="lu", rtol=1e-8, atol=1e-10)
        assert res.status == "success"
        assert engine.library(res.problem.model) is None
        assert not list(tmp_path.glob("*.so"))
        theta, _ = ms.examples.parallelogram_exact(res.t, np.radians(10.0), 0.0)
        assert np.abs(res.coordinate("crank.angle") - theta).max() < 1e-7
    finally:
        cache.clear_memory_cache()


def test_an_entry_compiled_with_other_flags_is_never_taken(tmp_path, monkeypatch):
    """The compile's flags (`-ffp-contract=off` decides how the C sums round) are part of
    the name of every compiled entry: the engine's object, a small model's engine library
    and a large model's kernel library. Other flags give other names, and the compile
    takes the flags the names say."""
    import subprocess
    from mechsim.codegen import compiled
    module = tmp_path / "mechsim_model_0123456789abcdef.py"
    names = lambda: (engine._object_path(tmp_path, ["cc"]), engine.library_path(module),
                     compiled.kernel_library_path(module))
    before = names()
    monkeypatch.setattr(compiled, "FLAGS", ("-O2", "-fPIC", "-ffp-contract=fast"))
    after = names()
    assert all(a != b and a.parent == b.parent == tmp_path for a, b in zip(before, after))
    commands = []
    monkeypatch.setattr(subprocess, "run", lambda command, **_: commands.append(command)
                        or subprocess.CompletedProcess(command, 1, b"", b"refused"))
    assert compiled.build_library("int x;", tmp_path / "x.so", ["cc"]) == "refused"
    assert commands[0][1:4] == ["-O2", "-fPIC", "-ffp-contract=fast"]


@needs_compiler
@pytest.mark.parametrize("damage", ["none", "truncated", "verified garbage"])
def test_small_models_link_the_engine_compiled_once(tmp_path, monkeypatch, damage):
    """In a new cache the engine's C is compiled once into an object file that each small
    model's library links. An object truncated is compiled again; one that passes its
    digest but cannot be linked leaves the library to be compiled whole. Either way the
    next model's engine serves, and its run is the one in the suite's cache to the bit.
    (The damaged cases start from the suite's compiled object: `seeded_cache`.)"""
    from mechsim.codegen.cache import adopt, verified_file
    reference = ms.examples.slider_crank().simulate(0.3, method="lu", rtol=1e-8)
    monkeypatch.setenv("MECHSIM_CACHE_DIR",
                       str(tmp_path if damage == "none" else seeded_cache(tmp_path)))
    cache.clear_memory_cache()
    try:
        assert ms.examples.four_bar().compilation().engine
        (obj,) = tmp_path.glob("mechsim_engine-*.o")
        if damage == "truncated":
            obj.write_bytes(obj.read_bytes()[:100])
        elif damage == "verified garbage":
            obj.write_bytes(b"not an object file")
            adopt(obj)
        mech = ms.examples.slider_crank()
        assert mech.compilation().engine
        res = mech.simulate(0.3, method="lu", rtol=1e-8)
        assert res.t.tobytes() == reference.t.tobytes()
        assert res.q.tobytes() == reference.q.tobytes()
        assert len(list(tmp_path.glob("*.evaluations-*.so"))) == 2
        assert verified_file(obj) and (damage == "verified garbage") == \
            (obj.read_bytes() == b"not an object file")
    finally:
        cache.clear_memory_cache()


@needs_compiler
def test_the_engine_compiles_beside_a_new_mechanism_s_sympy_run(tmp_path, monkeypatch):
    """In a new cache the engine's object file starts compiling before the small
    mechanism's model is derived (its compile thread has begun before the derivation
    ends: both instants taken in this process, so a slow shell around the compiler
    cannot reorder them) and is compiled once; the model's library links it and the run
    is the suite cache's to the bit."""
    import shlex
    from mechsim.build import background
    from mechsim.codegen import engine
    from mechsim.codegen.compiled import compiler
    reference = ms.examples.four_bar().simulate(0.3, method="lu", rtol=1e-8)
    log = tmp_path / "calls"
    wrapper = tmp_path / "cc"
    wrapper.write_text(f'#!/bin/sh\necho "$*" >> {log}\n'
                       f'exec {shlex.join(compiler())} "$@"\n')
    wrapper.chmod(0o755)
    derived, compiling = [], []
    real_source, real_compile = background.fused_source, engine._compile_object

    def timed_source(*args):
        source = real_source(*args)
        derived.append(time.perf_counter())
        return source

    def timed_compile(*args):
        compiling.append(time.perf_counter())
        return real_compile(*args)
    monkeypatch.setattr(background, "fused_source", timed_source)
    monkeypatch.setattr(engine, "_compile_object", timed_compile)
    monkeypatch.setenv("MECHSIM_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.setenv("CC", str(wrapper))
    cache.clear_memory_cache()
    try:
        mech = ms.examples.four_bar()
        assert mech.compilation().engine
        res = mech.simulate(0.3, method="lu", rtol=1e-8)
    finally:
        cache.clear_memory_cache()
    calls = log.read_text().splitlines()
    objects = [args for args in calls if " -c " in f" {args} "]
    assert len(objects) == 1 and len(derived) == 1 and compiling[0] < derived[0]
    assert len(calls) == 2                      # the object file, then the model's library
    assert res.q.tobytes() == reference.q.tobytes()


@needs_compiler
def test_compiled_projection_accelerations_agree_with_the_python_path():
    """Across the double four-bar's first passage (t* ≈ 0.714 s, sampled every 1 µs
    around it): clear of the truncation band the compiled accelerations equal the Python
    path's to round-off amplified by the condition (≤ 1e6 for the Cholesky factor); where
    LAPACK's condition estimate declines the Cholesky factor, the compiled path takes
    them by the Householder QR of J̃ᵀ (its extreme singular values deciding the band),
    equal to Python's SVD to round-off; in the band (a singular value under the cut) the compiled path declines and
    Python truncates and interpolates."""
    from mechsim.formulations.monitor import SingularityMonitor
    from mechsim.formulations.projection import Projection
    from mechsim.run.solver import simulate

    mech = ms.examples.double_four_bar(2)
    run = dict(method="projection", rtol=1e-9, atol=1e-11)
    res = mech.simulate(t_end=0.8, output_step=1e-3, **run)
    prob = res.problem
    k = int(np.searchsorted(res.t, 0.712))
    near = simulate(prob, res.q[k], res.v[k], t_start=res.t[k], t_end=res.t[k] + 4e-3,
                    output_step=1e-6, **run)
    fast = Projection(prob, 1e-9, 1e-11)
    slow = Projection(python_only(prob), 1e-9, 1e-11)
    assert fast.engine is not None and slow.engine is None
    min_rcond = max(100, prob.m) * fast.rcond ** 2
    monitor = SingularityMonitor(prob)
    counts = {"cholesky": 0, "svd": 0, "band": 0}
    samples = [(res, range(600, len(res.t), 3)), (near, range(0, len(near.t), 7))]
    for run_, ks in samples:
        for k in ks:
            t, q, v = run_.t[k], run_.q[k], run_.v[k]
            a = fast.accelerations(t, q, v, far=False)
            b = slow.accelerations(t, q, v, far=False)
            np.testing.assert_allclose(a, b, rtol=0, atol=1e-9 * np.abs(b).max())
            Q = prob.forces(t, q, v)
            if fast.engine.accelerations(t, q, v, Q, min_rcond) is not None:
                counts["cholesky"] += 1
            elif fast.engine.accelerations(t, q, v, Q, min_rcond, fast.rcond) is not None:
                counts["svd"] += 1
                assert monitor.measure(q, t)[0] > fast.rcond
            else:
                counts["band"] += 1
                assert monitor.measure(q, t)[0] <= fast.rcond
    assert counts["cholesky"] >= 20 and counts["svd"] >= 20 and counts["band"] >= 2, counts


@needs_compiler
def test_compiled_state_projection_agrees_with_the_python_path(rng):
    """States pushed off the double four-bar's constraints by 1e-6 (as an integrator's
    error would) projected by the compiled chord Newton and by
    `NumericProblem.project_state`: the same (q, v) to round-off, Φ at the tolerance and
    Φ_q v = 0; declined in the truncation band when asked for the condition estimate,
    and untouched within the skip tolerance."""
    from mechsim.formulations.projection import Projection

    mech = ms.examples.double_four_bar(2)
    res = mech.simulate(t_end=0.8, method="projection", rtol=1e-9, atol=1e-11,
                        output_step=1e-3)
    prob = res.problem
    proj = Projection(prob, 1e-9, 1e-11)
    eng = proj.engine
    assert eng is not None
    min_rcond = max(100, prob.m) * proj.rcond ** 2
    taken = declined = 0
    for k in [*range(0, 600, 10), *range(600, len(res.t), 3)]:     # t* ≈ 0.714 s
        t = res.t[k]
        q = res.q[k] + 1e-6 * rng.normal(size=prob.n)
        v = res.v[k] + 1e-6 * rng.normal(size=prob.n)
        before = prob.counters.projections
        fast = eng.project_state(t, q, v, 1e-13, min_rcond, extra=1)
        if fast is None:
            declined += 1
            continue
        taken += 1
        iterations = prob.counters.projections - before
        slow = prob.project_state(q, v, t, 1e-13, extra=1)
        assert prob.counters.projections - before == 2 * iterations >= 4
        # Round-off amplified by the complement's condition (≤ 1e6 where taken).
        for x, z in zip(fast, slow):
            np.testing.assert_allclose(x, z, rtol=0, atol=1e-10 * (1.0 + np.abs(z).max()))
        qf, vf = fast
        assert np.abs(prob.phi(qf, t)).max() <= 1e-13
        # One factor at the given q: Φ_q v is left at (1e-6 change of Φ_q)² × its condition.
        assert np.abs(prob.phi_q(qf, t) @ vf).max() <= 1e-10 * (1.0 + np.abs(vf).max())
    assert taken >= 60 and declined >= 1
    t, q, v = res.t[10], res.q[10], res.v[10]
    assert eng.project_state(t, q, v, 1e-13, skip_tol=1e-9) is False


def python_only(problem):
    """A copy of `problem` whose constraint algebra runs without the compiled engine."""
    import copy
    from mechsim.problem.algebra import DenseAlgebra
    other = copy.copy(problem)
    other.algebra = DenseAlgebra(other)
    other.algebra.engine = None
    return other


@needs_compiler
def test_compiled_singularity_measure_agrees_with_the_python_path():
    """The monitor's measurement over the double four-bar's first passage (t* ≈ 0.714 s),
    compiled (one SVD and two Jacobians in C) and in Python: σ_min/σ_max and σ_min to
    round-off, the rate (a difference quotient over 1e-7 of motion) to 1e-6 of its
    scale, the same left singular vector (up to sign) and the same J̃."""
    from mechsim.formulations.monitor import SingularityMonitor

    mech = ms.examples.double_four_bar(2)
    res = mech.simulate(t_end=0.8, method="projection", rtol=1e-9, atol=1e-11,
                        output_step=1e-3)
    prob = res.problem
    fast, slow = SingularityMonitor(prob), SingularityMonitor(python_only(prob))
    assert prob.algebra.engine is not None
    rate_scale = 0.0
    pairs = []
    for k in range(0, len(res.t), 5):
        t, q, v = res.t[k], res.q[k], res.v[k]
        a, b = fast._measure(q, t, v), slow._measure(q, t, v)
        pairs.append((a, b))
        rate_scale = max(rate_scale, abs(b[1]))
    assert min(b[0] for _, b in pairs) < 1e-3            # the passage is among them
    for a, b in pairs:
        assert a[0] == pytest.approx(b[0], rel=1e-9, abs=1e-14)
        assert a[3] == pytest.approx(b[3], rel=1e-9, abs=1e-14)
        assert abs(a[1] - b[1]) <= 1e-6 * rate_scale
        if b[0] > 1e-6:                      # the vector is defined away from the passage
            assert abs(abs(a[2] @ b[2]) - 1.0) < 1e-8
        np.testing.assert_allclose(a[5], b[5], rtol=0, atol=1e-14)
    # The passage search's grid: chords of J̃ between consecutive states and the extreme
    # singular values, compiled and in numpy; each chord bounds the spectral norm of the
    # difference (its largest singular value).
    T, Q = res.t[::20], res.q[::20]
    chords = prob.algebra.chords(T, Q)
    np.testing.assert_allclose(chords, python_only(prob).algebra.chords(T, Q), rtol=1e-12)
    J = np.array([prob.algebra.scaled_jacobian(q, t) for t, q in zip(T, Q)])
    spectral = np.linalg.svd(np.diff(J, axis=0), compute_uv=False)[:, 0]
    assert np.all(chords >= spectral * (1 - 1e-12))
    assert np.all(chords <= np.sqrt(np.sum(np.diff(J, axis=0) ** 2, axis=(1, 2))) * (1 + 1e-12))
    k = prob.m - 1
    np.testing.assert_allclose(prob.algebra.singular_extremes(T, Q, k),
                               python_only(prob).algebra.singular_extremes(T, Q, k),
                               rtol=1e-10, atol=1e-14)
    # The skip's bounds: J̃, how far it moved since an earlier J̃ (Weyl) and its Gram floor
    # of σ_min/σ_max, compiled and in numpy; the floor below the ratio and within m^¼ of
    # it.
    for (ta, qa), (tb, qb) in zip(zip(T, Q), zip(T[1:], Q[1:])):
        Jm = prob.algebra.scaled_jacobian(qa, ta)
        (Ja, Ea), (Jb, Eb) = (x.change(qb, tb, Jm) for x in (prob.algebra,
                                                              python_only(prob).algebra))
        np.testing.assert_allclose(Ja, Jb, rtol=0, atol=1e-14)
        assert Ea == pytest.approx(Eb, rel=1e-12) and Ea > 0.0
        sig = np.linalg.svd(Ja, compute_uv=False)
        lo, hi = prob.algebra.extreme_bounds(Ja)
        np.testing.assert_allclose(
            (lo, hi), python_only(prob).algebra.extreme_bounds(Ja), rtol=1e-10)
        assert sig[-1] * prob.m ** -0.125 * (1 - 1e-6) <= lo <= sig[-1]
        assert sig[0] <= hi <= sig[0] * prob.m ** 0.125 * (1 + 1e-12)


@needs_compiler
@pytest.mark.parametrize("build", [
    PROBLEMS["crank-rocker"].build,                                     # 8 rows: Jacobi
    lambda: ms.examples.double_four_bar(2),                             # 14 rows: Jacobi
    lambda: ms.examples.double_four_bar(4),                             # 26 rows: dgesdd
    lambda: ms.examples.general_four_bar(0.3, 0.9, 0.7, 1.0, math.radians(60.0),
                                         masses=(1e150, 1.5e150, 1e150))],  # J~ ~ 1e-75
    ids=["crank-rocker", "double-four-bar", "four-windows", "heavy-crank-rocker"])
def test_the_compiled_measure_s_svd_is_numpy_s_to_round_off(build):
    """The compiled measure's SVD of J̃ (one-sided Jacobi up to JACOBI_ROWS rows, LAPACK's
    dgesdd above; J̃ of 1e-75 too, whose squared norms' products would underflow) against
    numpy's along a run: σ_min and σ_max to 1e-12, the left singular vector of σ_min up
    to its sign, the rates' difference quotients to 1e-7 of their scale, and the fall
    basis P (every right singular vector, scaled by σ_min/σ_l) through P Pᵀ, which no
    vector's sign changes."""
    mech = build()
    res = mech.simulate(t_end=0.6, method="lu", rtol=1e-8, atol=1e-10, output_step=0.05)
    prob = res.problem
    fast, slow = prob.algebra, python_only(prob).algebra
    assert fast.engine is not None
    k = prob.m - 1
    for t, q, v in zip(res.t, res.q, res.v):
        a = fast.measure(q, t, v, 1e-7, k)
        b = slow.measure(q, t, v, 1e-7, k)
        assert a[0] == pytest.approx(b[0], rel=1e-12) and a[1] == pytest.approx(b[1], rel=1e-12)
        sig = np.linalg.svd(np.asarray(b[5]), compute_uv=False)
        assert a[0] == pytest.approx(sig[-1], rel=1e-12) and a[1] == pytest.approx(sig[0],
                                                                                  rel=1e-12)
        assert abs(abs(a[4] @ b[4]) - 1.0) < 1e-10
        scale = max(abs(b[2]), abs(b[3]), 1e-3 * b[6])
        assert abs(a[2] - b[2]) <= 1e-7 * scale and abs(a[3] - b[3]) <= 1e-7 * scale
        if prob.algebra.small:
            Pa, Pb = a[7][1], b[7][1]
            np.testing.assert_allclose(Pa @ Pa.T, Pb @ Pb.T, rtol=0, atol=1e-11)


@needs_compiler
@pytest.mark.parametrize("build", [PROBLEMS["crank-rocker"].build,
                                   lambda: ms.examples.double_four_bar(2)],
                         ids=["crank-rocker", "double-four-bar"])
def test_the_measure_from_the_last_svd_s_rotation_is_the_measure_afresh(build):
    """The monitor's Jacobi SVD starts from the rotation its last one ended with: along a
    run (the double four-bar's through its first passage, where σ_min/σ_max falls to a
    hundredth of its peak and below) each measure so started agrees with one started afresh (`forget` first) to
    round-off of σ_max, its singular vector up to sign; and after `forget` a measure is a
    new engine's to the bit (what a run's start relies on)."""
    mech = build()
    res = mech.simulate(t_end=0.8, method="projection", rtol=1e-9, atol=1e-11,
                        output_step=1e-3)
    prob = res.problem
    engine = prob.algebra.engine
    assert engine is not None
    ratios = []
    engine.forget()
    for t, q, v in zip(res.t, res.q, res.v):
        warm = engine.measure(t, q, v, 1e-7)
        state = (engine.ctx.jacobi_warm, engine.buffers["jacobi_from"].copy())
        engine.forget()
        fresh = engine.measure(t, q, v, 1e-7)
        engine.ctx.jacobi_warm, engine.buffers["jacobi_from"][:] = state  # the warm path on
        assert abs(warm[0] - fresh[0]) <= 8 * prob.m * 2.2e-16 * fresh[1]
        assert warm[1] == pytest.approx(fresh[1], rel=8 * prob.m * 2.2e-16)
        assert abs(abs(warm[4] @ fresh[4]) - 1.0) < 1e-9 or fresh[0] < 1e-6 * fresh[1]
        ratios.append(fresh[0] / fresh[1])
    assert len(ratios) > 100
    if prob.m == 14:
        assert min(ratios) < 1e-2 * max(ratios)          # through the passage
    t, q, v = res.t[-1], res.q[-1], res.v[-1]
    engine.forget()
    again = engine.measure(t, q, v, 1e-7)
    first = type(engine)(engine.lib, prob).measure(t, q, v, 1e-7)
    assert all(np.array_equal(np.asarray(x), np.asarray(y)) for x, y in
               zip(again[:7], first[:7]))


@needs_compiler
def test_the_extreme_singular_values_of_many_states_agree_with_one_by_one_measures():
    """(σ_min, σ_max) at many states in one call, compiled (dgesdd without vectors) and by
    a stacked numpy SVD (`singular_extremes`, the passage search's anchors), give the
    monitor's measure state by state to round-off, through the double four-bar's first
    passage (where the ratio falls under 1e-3)."""
    from mechsim.formulations.monitor import SingularityMonitor

    mech = ms.examples.double_four_bar(2)
    res = mech.simulate(t_end=0.8, method="projection", rtol=1e-9, atol=1e-11,
                        output_step=1e-3)
    prob = res.problem
    assert prob.algebra.engine is not None
    slow = SingularityMonitor(python_only(prob))
    each = np.array([slow.measure(q, t)[0] for t, q in zip(res.t, res.q)])
    assert each.min() < 1e-3 and each.max() > 0.1
    for algebra in (prob.algebra, python_only(prob).algebra):
        sig = algebra.singular_extremes(res.t, res.q, prob.m - 1)
        np.testing.assert_allclose(sig[:, 0] / sig[:, 1], each, rtol=1e-9, atol=1e-14)


@needs_compiler
def test_output_samples_settle_alike_in_c_and_in_python(rng):
    """A step's samples pushed off the constraints by 1e-4 (a long step's error) are put
    back by the compiled engine in one call and by the stacked Python Newton alike: on
    the constraints to round-off, velocities consistent, the two within (1e-4)²."""
    from mechsim.formulations.full import settle_samples
    from mechsim.formulations.projection import Projection

    mech = ms.examples.double_four_bar(2)
    res = mech.simulate(t_end=0.5, method="projection", rtol=1e-9, atol=1e-11,
                        output_step=0.01)
    prob = res.problem
    eng = Projection(prob, 1e-6, 1e-8).engine
    assert eng is not None
    Q0 = res.q + 1e-4 * rng.standard_normal(res.q.shape)
    V0 = res.v + 1e-4 * rng.standard_normal(res.v.shape)
    (Qc, Vc), (Qp, Vp) = (Q0.copy(), V0.copy()), (Q0.copy(), V0.copy())
    settle_samples(prob, res.t, Qc, Vc, 1e-6, compiled=True)
    settle_samples(prob, res.t, Qp, Vp, 1e-6)
    for Q, V in ((Qc, Vc), (Qp, Vp)):
        for t, q, v in zip(res.t, Q, V):
            assert np.abs(prob.phi(q, t)).max() < 1e-12
            assert np.abs(prob.phi_q(q, t) @ v + prob.phi_t(q, t)).max() < 1e-10
    # Both land on the constraints; the chord and the full Newton stop at points that
    # differ by second order in the 1e-4 offset (the nearest point is not solved exactly).
    np.testing.assert_allclose(Qc, Qp, rtol=0, atol=1e-8)
    np.testing.assert_allclose(Vc, Vp, rtol=0, atol=1e-8)
    assert np.abs(Qc - Q0).max() > 1e-5                  # they were moved


@pytest.fixture(scope="module")
def first_passage():
    """The double four-bar over its first passage (projection, rtol 1e-9, a sample every
    ms), where its engine is built."""
    mech = ms.examples.double_four_bar(2)
    res = mech.simulate(t_end=0.8, method="projection", rtol=1e-9, atol=1e-11,
                        output_step=1e-3)
    if engine.library(res.problem.model) is None:
        pytest.skip("no C compiler: the engine is not built")
    return res


@needs_compiler
def test_compiled_lu_condition_agrees_with_the_python_path(first_passage):
    """The hybrid's test for a return to LU (`Hybrid._lu_ready`): cond₁ of the block LU
    pivoting picks, compiled (the algebra's `lu_condition`) and from `Partitioned.choose`,
    over the double four-bar's first passage, to round-off; with the block it picks near
    the passage ill-conditioned enough to matter (cond ≥ 1e3 there)."""
    from mechsim.formulations.hybrid import Hybrid

    res = first_passage
    prob = res.problem
    hybrid = Hybrid(prob, 1e-8, 1e-10)
    conds = []
    for k in range(0, len(res.t), 4):
        t, q = res.t[k], res.q[k]
        J = prob.phi_q(q, t)
        slow = hybrid.lu.choose(J, prob.m).block(J).condition()
        assert prob.algebra.lu_condition(t, q) == pytest.approx(slow, rel=1e-9)
        conds.append(slow)
    assert max(conds) >= 1e3 and min(conds) < 100


@needs_compiler
def test_a_partition_s_choice_compiled_is_the_python_path_s(first_passage):
    """`Partitioned.choose`'s rank and pivots in one engine call (`ConstraintAlgebra.choice`:
    dgesdd's singular values of Φ_qᵀ against the rank threshold, dgetrf's row swaps of Φ_qᵀ)
    equal to the integer to scipy's `rank` and `pivots` over the double four-bar's first
    passage, and on a Φ_q with a row repeated (rank m − 1), where the rank decides which
    coordinate turns independent."""
    from mechsim.problem.algebra import RANK_FACTOR, ConstraintAlgebra

    res = first_passage
    prob = res.problem
    alg = prob.algebra
    Js = [prob.phi_q(q, t) for q, t in zip(res.q[::20], res.t[::20])]
    deficient = Js[0].copy()
    deficient[-1] = deficient[0]
    for J in [*Js, deficient]:
        compiled = alg.engine.choice(J, np.finfo(float).eps, RANK_FACTOR)
        assert compiled is not None
        rank, perm = compiled
        assert rank == alg.rank(J) and np.array_equal(perm, alg.pivots(J))
        assert alg.choice(J)[0] == rank
        assert ConstraintAlgebra.choice(alg, J)[0] == rank
    assert rank == prob.m - 1 and alg.rank(Js[0]) == prob.m


def test_compiled_multipliers_agree_with_the_python_path():
    """Reactions of the double four-bar through its passages: λ from the compiled batch
    (Cholesky, its pivots checked outside the passages, LAPACK's condition estimate inside)
    and from the Python path, sample by sample, equal to round-off, with the same samples
    flagged."""
    mech = ms.examples.double_four_bar()
    res = mech.simulate(6.0, rtol=1e-9, atol=1e-11, output_step=2e-3)
    assert res.success and res.singular_passages
    model = res.problem.model
    if engine.library(model) is None:
        pytest.skip("no C compiler: the engine is not built")
    compiled = res.problem.multipliers(res.t, res.q, res.v,
                                       [(p.t_start, p.t_end) for p in res.singular_passages])
    with engine.python_path(model):
        plain = res.problem.multipliers(res.t, res.q, res.v,
                                        [(p.t_start, p.t_end) for p in res.singular_passages])
    scale = np.max(np.abs(plain.lam))
    assert np.max(np.abs(compiled.lam - plain.lam)) < 1e-9 * scale
    np.testing.assert_array_equal(compiled.indeterminate, plain.indeterminate)


@needs_compiler
def test_compiled_fresh_newton_agrees_with_the_python_path():
    """Where the chord on the last step's Φ_q D contracts too slowly (a crank-rocker's
    state a long stage ahead of its last step, near its toggle positions), every later
    Newton iteration takes a fresh Φ_q D, compiled as in Python: the same count of them
    and the same positions and velocities, to round-off; where Newton fails from the
    prediction, both follow the motion from the last step in pieces (`_follow`) alike."""
    mech = ms.examples.general_four_bar(0.3, 0.9, 0.7, 1.0, math.radians(60.0),
                                        masses=(1.0, 1.5, 1.0), name="crank-rocker")
    res = mech.simulate(t_end=3.0, method="lu", rtol=1e-9, atol=1e-11, output_step=0.15)
    fresh = followed = 0
    for k in range(len(res.t)):
        sample = ms.SimulationResult(res.t[:k + 1], res.q[:k + 1], res.v[:k + 1],
                                     res.coordinate_names, problem=res.problem)
        (fast, slow), t, y = _pair(sample)
        f = fast.basis.f
        for dt in (0.05, 0.1):
            yk = y.copy()
            yk[:f] += dt * y[f:]
            a = fast.engine.state(t + dt, yk)
            try:
                slow._newton(yk[:f], t + dt, slow._predict(t + dt, yk[:f]))
            except ConstraintSolveError:
                followed += 1
            b = slow.full_state(t + dt, yk)
            assert a is not None and a[3] == b[3]
            fresh += a[3] > 0
            for x, z in zip(a[:2], b[:2]):
                np.testing.assert_allclose(x, z, rtol=0, atol=1e-12 * (1.0 + np.abs(z).max()))
    assert fresh >= 3 and followed >= 1      # both were exercised


def _interpolant_cases(kernel=None):
    """(scipy's DOP853 dense output, `Interpolant` of the same coefficients evaluated by
    `kernel` or by numpy): on coefficients with zeros of both signs and on a real step."""
    from scipy.integrate._ivp.rk import Dop853DenseOutput
    rng = np.random.default_rng(11)
    F = rng.standard_normal((7, 9)) * 10.0 ** rng.integers(-8, 3, (7, 9))
    F[:, 0], F[:, 1], F[-1, 2] = 0.0, -0.0, -0.0
    y_old = np.concatenate([[0.0, -0.0], rng.standard_normal(7)])
    cases = [(Dop853DenseOutput(0.25, 0.25 + 3e-3, y_old, F),
              Interpolant(0.25, 0.25 + 3e-3, y_old, F, kernel))]
    solver = DOP853(lambda t, y: np.array([y[1], -np.sin(y[0])]), 0.0, [1.0, 0.0], 5.0)
    solver.step()
    solver.step()
    scipy_dense = DOP853.dense_output(solver)
    of = Interpolant.of(scipy_dense)
    cases.append((scipy_dense, of if kernel is None else
                  Interpolant(of.t_old, of.t, of.y_old, of.F, kernel)))
    return cases, rng


def test_the_step_s_interpolant_is_scipy_s_to_the_bit():
    """`Interpolant` at a time and at many times equals scipy's DOP853 dense output to the
    last bit (signs of zero included), on a real step of the crank-rocker's integrator
    and on coefficients with zeros of both signs; from scipy's stages the same."""
    cases, rng = _interpolant_cases()
    _same_to_the_bit(cases, rng)


@needs_compiler
def test_the_engine_s_interpolant_is_scipy_s_to_the_bit():
    """The engine's `mechsim_interpolate` (the compiled steps' interpolant) gives scipy's
    numbers to the last bit too, at one time and at many, also where the times are
    integers; and the compiled steps' interpolants use it."""
    prob = PROBLEMS["crank-rocker"].build().problem()
    kernel = prob.algebra.engine.lib.mechsim_interpolate
    cases, rng = _interpolant_cases(kernel)
    assert all(lean._kernel is not None for _, lean in cases)
    _same_to_the_bit(cases, rng)
    ref, lean = cases[1]
    assert lean(np.array([0, 1])).tobytes() == ref(np.array([0, 1])).tobytes()
    used = []
    original = CompiledDOP853.dense_output

    def dense(self):
        out = original(self)
        used.append(out._kernel is not None)
        # its coefficients, formed in the engine from the stages, are scipy's formulas'
        # (`Dop853DenseOutput`'s F) to round-off
        K, h, dy = self.K_extended, self.h_previous, self.y - self.y_old
        ref = np.vstack([dy, h * K[0] - dy, 2 * dy - h * (self.f + K[0]), h * (self.D @ K)])
        scale = np.vstack([np.abs(dy), np.abs(h * K[0]) + np.abs(dy),
                           np.abs(h * (self.f + K[0])) + 2 * np.abs(dy),
                           np.abs(h) * (np.abs(self.D) @ np.abs(K))])
        assert np.all(np.abs(out.F - ref) <= 4 * np.finfo(float).eps * scale)
        return out
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(CompiledDOP853, "dense_output", dense)
        mp.setattr(segment, "enabled", False)          # the loop's own steps, one by one
        res = PROBLEMS["crank-rocker"].build().simulate(0.5, method="lu", output_step=0.01)
    assert res.success and used and all(used)


def _same_to_the_bit(cases, rng):
    for ref, lean in cases:
        times = np.concatenate([[ref.t_old, ref.t], rng.uniform(ref.t_old, ref.t, 30)])
        assert lean(times).tobytes() == ref(times).tobytes()
        for t in times:
            assert lean(t).tobytes() == ref(t).tobytes()
            assert lean(float(t)).tobytes() == ref(float(t)).tobytes()


@needs_compiler
@pytest.mark.parametrize("method", ["projection", "lu"])
def test_compiled_dop853_steps_are_scipy_s_steps(method, monkeypatch):
    """The crank-rocker's 3 s with its steps and dense output taken in the engine
    (`CompiledDOP853`) and with scipy's Python step on the same compiled rate: the same
    steps and the same motion to round-off (the two sum the stages in different orders;
    a step whose stage the engine declines is taken again by scipy, its compiled stages
    spent)."""
    mech = PROBLEMS["crank-rocker"].build()
    run = dict(method=method, rtol=1e-6, atol=1e-8, output_step=0.01)
    monkeypatch.setattr(segment, "enabled", False)     # the loop's own steps, one by one
    taken = []
    compiled_step = CompiledDOP853.step

    def counting(self):
        taken.append(self.rate() is not None)
        return compiled_step(self)
    monkeypatch.setattr(CompiledDOP853, "step", counting)
    fast = mech.simulate(3.0, **run)
    # Every accepted step went through the compiled step, on the engine's rate.
    assert fast.success and len(taken) >= fast.stats["steps"] and all(taken)
    monkeypatch.setattr(CompiledDOP853, "step", DOP853.step)
    monkeypatch.setattr(CompiledDOP853, "dense_output", DOP853.dense_output)
    slow = mech.simulate(3.0, **run)
    assert slow.success
    assert fast.stats["steps"] == slow.stats["steps"]
    np.testing.assert_allclose(fast.q, slow.q, rtol=0, atol=1e-9)     # rtol 1e-6


@needs_compiler
def test_stages_the_engine_declines_are_the_python_rate_s(monkeypatch):
    """With the engine made to decline every state (a condition bound no factor meets),
    each stage of the compiled steps is the formulation's Python rate, called back from
    C: the run equals scipy's own Python steps to round-off, with the same steps, and a
    rate that raises inside the callback reaches the caller."""
    from mechsim.formulations.projection import Projection
    from mechsim.integrators.compiled import CompiledRate
    mech = PROBLEMS["crank-rocker"].build()
    run = dict(method="projection", rtol=1e-6, atol=1e-8, output_step=0.01)
    original = Projection.compiled_rate

    def declining(self):
        rate = original(self)
        return None if rate is None else CompiledRate(
            self.problem.algebra.engine.lib, rate.context, 0, rate.counted, 2.0, 0.0)
    monkeypatch.setattr(Projection, "compiled_rate", declining)
    called = []
    rhs = Projection.rhs
    monkeypatch.setattr(Projection, "rhs", lambda self, t, y: called.append(t) or rhs(self, t, y))
    back = mech.simulate(1.0, **run)
    # Every evaluation the run counted was the Python rate's (called back from C).
    assert back.success and len(called) == back.stats["rhs_evaluations"]
    monkeypatch.setattr(CompiledDOP853, "step", DOP853.step)
    monkeypatch.setattr(CompiledDOP853, "dense_output", DOP853.dense_output)
    plain = mech.simulate(1.0, **run)
    assert back.stats["steps"] == plain.stats["steps"]
    np.testing.assert_allclose(back.q, plain.q, rtol=0, atol=1e-9)
    def failing(self, t, y):
        if t > 0.5:
            raise FloatingPointError("the rate failed here")
        return rhs(self, t, y)
    monkeypatch.undo()
    monkeypatch.setattr(Projection, "compiled_rate", declining)
    monkeypatch.setattr(Projection, "rhs", failing)
    failed = mech.simulate(1.0, **run)
    assert failed.status == "failed" and "the rate failed here" in failed.message
    assert 0.4 < failed.t[-1] <= 0.5


def test_a_run_leaves_the_engine_s_shared_rates_as_it_found_them():
    """The compiled rate of an engine is one object per engine and settings, shared by
    every run and bridge: a bridge that counts its history's evaluations does so on a copy
    (changing the shared one chained a counter per bridge, until a later run in the same
    process failed with a RecursionError). After runs through the double four-bar's
    passages, each shared rate still books to the problem's own counter, and a later run
    is the first one to the bit."""
    mech = ms.examples.double_four_bar()
    first = mech.simulate(1.5, rtol=1e-4, atol=1e-6)
    assert first.status == "success" and first.stats["bridges"] == 2
    again = mech.simulate(1.5, rtol=1e-4, atol=1e-6)
    np.testing.assert_array_equal(again.q, first.q)
    prob = mech.problem()
    engines = [prob.algebra.engine]
    rates = [rate for e in engines for rate in e.rates.values()]
    assert rates
    for rate in rates:
        assert rate.counted == prob.counters.compiled_rates


@needs_compiler
def test_the_cholesky_shortcut_accepts_only_what_lapack_s_estimate_accepts(rng):
    """The engine skips LAPACK's condition estimate where `mechsim_inverse_norm_bound`
    (from the Cholesky factor's inverse) bounds ‖S⁻¹‖₁ from above so that 1/κ₁ is above
    twice the threshold: the bound holds on matrices from well- to ill-conditioned, and
    wherever it accepts, dpocon's estimate (as `dense.cholesky_rcond` takes it) accepts
    too; it accepts most well-conditioned ones."""
    from mechsim.linalg import dense
    prob = ms.examples.double_four_bar(2).problem()
    lib = engine.library(prob.model)
    bound_of = lib.mechsim_inverse_norm_bound
    accepted = 0
    for trial in range(400):
        m = int(rng.integers(2, 16))
        Q, _ = np.linalg.qr(rng.standard_normal((m, m)))
        lam = np.logspace(0.0, -rng.uniform(0.0, 10.0), m)
        S = (Q * lam) @ Q.T
        R = np.linalg.cholesky(S).T
        Rc = np.asfortranarray(R)
        W = np.zeros((m, m), order="F")
        bound = bound_of(m, Rc.ctypes.data, W.ctypes.data)
        kappa = lam[0] / lam[-1]                    # the round-off of both scales with it
        assert bound >= np.linalg.norm(np.linalg.inv(S), 1) * (1.0 - 1e-13 * kappa)
        anorm = m * S.diagonal().max()
        if anorm * bound * 2e-4 < 1.0:              # the engine's shortcut at 1e-4
            accepted += 1
            _, rcond = dense.cholesky_rcond(S)
            assert rcond > 1e-4
    assert accepted > 50


def test_an_integrator_is_set_up_as_scipy_sets_it_up_or_by_scipy(monkeypatch):
    """`CompiledDOP853`'s own set-up (an integrator is made at every restart and
    crossing) leaves the installed scipy's attributes, values and evaluation count, with
    scipy's first step and with a given one, and integrates to the same numbers; asked
    for what it does not check (a complex or non-finite state, a negative atol), scipy's
    set-up takes it and raises as scipy does; and where the installed scipy sets up
    anything else (an attribute of its own), scipy's set-up serves every integrator."""
    from mechsim.integrators import compiled
    from scipy.integrate import DOP853
    assert compiled._SET_UP.verified()
    rates = np.array([-1.0, 0.5, -3.0])

    def fun(t, y):
        return rates * y + np.sin(t)
    for options in ({"rtol": 1e-8, "atol": 1e-10}, {"rtol": 1e-5, "atol": 1e-8,
                                                    "first_step": 0.02, "max_step": 0.1}):
        ours = compiled.CompiledDOP853(fun, 0.0, np.array([1.0, -1.0, 2.0]), 3.0, **options)
        theirs = DOP853(fun, 0.0, np.array([1.0, -1.0, 2.0]), 3.0, **options)
        assert set(vars(theirs)) <= set(vars(ours))
        assert (ours.h_abs, ours.nfev, ours.direction) == (theirs.h_abs, theirs.nfev,
                                                            theirs.direction)
        while theirs.status == "running":
            ours.step()
            theirs.step()
            assert ours.t == theirs.t and np.array_equal(ours.y, theirs.y)
    with pytest.raises(ValueError, match="finite"):
        compiled.CompiledDOP853(fun, 0.0, np.array([1.0, np.nan, 2.0]), 3.0)
    with pytest.raises(ValueError, match="atol"):
        compiled.CompiledDOP853(fun, 0.0, np.ones(3), 3.0, atol=-1.0)

    class Changed(DOP853):             # a scipy whose set-up keeps something more
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            self.extra = 1
    monkeypatch.setattr(compiled, "DOP853", Changed)
    assert not compiled._ScipySetUp().verified()
