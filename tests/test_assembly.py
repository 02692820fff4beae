"""Constraint systems assembled from joint-type kernels (`mechsim.assembly`) against the
fused per-mechanism model on every scene and example mechanism, against finite differences,
and the build choice ("auto": fused where cached, else assembled with the fused model built
in the background)."""

import importlib.util
import json
import math
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from conftest import mechanism_models, needs_compiler, seeded_cache
from test_gears import train

import mechsim as ms
from mechsim import examples
from mechsim.assembly import AssembledModel
from mechsim.model.expressions import parse

ROOT = Path(__file__).resolve().parents[1]


def _engine_example():
    spec = importlib.util.spec_from_file_location("engine_sizing",
                                                  ROOT / "examples" / "engine_sizing.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.engine(3000.0)


MECHANISMS = {
    **{f"scene {p.stem}": (lambda p=p: ms.load_scene(p).mechanism)
       for p in sorted((ROOT / "mechanisms").glob("*.toml"))},
    "four_bar": examples.four_bar,
    "rigid flexible_four_bar": lambda: examples.flexible_four_bar(rigid=True),
    "flexible_four_bar 3 modes": lambda: examples.flexible_four_bar(n_modes=3),
    "double_four_bar": examples.double_four_bar,
    "10-window": lambda: examples.double_four_bar(10),
    "slider_crank": examples.slider_crank,
    "driven slider_crank": lambda: examples.slider_crank(driven=True, crank_speed=100.0),
    "pendulum": examples.pendulum,
    "spring_mass": examples.spring_mass,
    "general_four_bar": lambda: examples.general_four_bar(1.0, 1.0, 1.0, 1.0, theta=0.6),
    "turning_parallelogram": lambda: examples.turning_parallelogram(0.5, 1.0, 0.4, 2.0),
    **{f"random {kind}": (lambda kind=kind: examples.random_mechanism(
        np.random.default_rng(7), kind)[0]) for kind in examples.RANDOM_KINDS},
    "engine_sizing example": _engine_example,
    "cam through points": lambda: _spline_cam(),
    "table-driven slider_crank": lambda: _table_driven(),
    "spur gear train": lambda: train()[0],
    "internal ratio gear train": lambda: train("ratio", internal=True)[0],
}


def _table_driven():
    """The driven slider-crank whose crank follows a table of 41 points: the fused model
    evaluates the table's spline by its own printers' calls, the assembled one by the law."""
    mech = examples.slider_crank(driven=True, crank_speed=40.0)
    pivot = mech.joint("O")
    mech.drivers.clear()
    t = np.linspace(-0.1, 0.7, 41)
    mech.add(ms.Driver(pivot, table=(t, 40.0 * t + 0.3 * np.sin(25.0 * t)), name="motor"))
    return mech


def _spline_cam():
    """A cam whose pitch curve is the periodic spline through 12 points (the assembled
    kernel and the fused model evaluate it by their own printers' calls)."""
    phi = np.linspace(0.0, 2 * math.pi, 12, endpoint=False)
    r = 0.05 + 0.01 * np.cos(phi) + 0.003 * np.sin(2 * phi)
    mech = ms.Mechanism("spline cam")
    cam = mech.add(ms.RigidBody.disc("cam", (0, 0), 0.06, 1.0))
    y0 = float(np.interp(math.pi / 2, phi, r))
    follower = mech.add(ms.RigidBody.point_mass("follower", (0, 0.05), 0.3))
    mech.add(ms.Revolute(mech.ground, cam, at=(0, 0)))
    mech.add(ms.Prismatic(mech.ground, follower, axis=(0, 1), at=(0, 0.05)))
    contact = ms.PointOnCurve(cam, follower, at=(0, 0.05), centre=(0, 0),
                              curve=("polar", np.column_stack([phi, r + 0.05 - y0])))
    mech.add(contact)
    return mech


def _state(mech, prob, seed=3):
    rng = np.random.default_rng(seed)
    q = mech.initial_coordinates() + 0.05 * rng.standard_normal(prob.n)
    return q, rng.standard_normal(prob.n), 0.37


@pytest.mark.parametrize("name", list(MECHANISMS))
def test_assembled_equals_fused_to_the_last_bit(name):
    """Φ, Φ_q, Φ_t, γ and the shared-term groups of the fused model (its joint types'
    kernels unrolled, `mechsim.assembly.unrolled`; its C twins where it is large) equal
    the assembled model's to the last bit, drivers' laws included, with the same Jacobian
    pattern; the loads are the same numeric code on both."""
    mech = MECHANISMS[name]()
    fused = mech.problem(build="fused")
    assembled = mech.problem(build="assembled")
    assert isinstance(assembled.model, AssembledModel)
    assert not isinstance(fused.model, AssembledModel)
    assert assembled.p == fused.p and assembled.m == fused.m
    q, v, t = _state(mech, fused)
    a, f, p = assembled.model, fused.model, fused.p
    pairs = [(a.phi(q, t, p), f.phi(q, t, p)), (a.phi_q(q, t, p), f.phi_q(q, t, p)),
             (a.phi_t(q, t, p), f.phi_t(q, t, p)), (a.gamma(q, v, t, p), f.gamma(q, v, t, p)),
             *zip(a.terms(q, v, t, p), f.terms(q, v, t, p)),
             *zip(a.position_terms(q, t, p), f.position_terms(q, t, p)),
             *zip(a.dynamics_terms(q, v, t, p), f.dynamics_terms(q, v, t, p))]
    for x, y in pairs:
        assert x.shape == y.shape
        np.testing.assert_array_equal(x, y)
    assert sorted(zip(a.JACOBIAN_ROWS, a.JACOBIAN_COLS)) == \
        sorted(zip(f.JACOBIAN_ROWS, f.JACOBIAN_COLS))
    assert np.array_equal(a.phi_q_csr(q, t, p).toarray(), a.phi_q(q, t, p))


@needs_compiler
@pytest.mark.parametrize("name", list(MECHANISMS))
def test_a_fused_model_s_c_twins_equal_its_python_to_the_last_bit(name, tmp_path):
    """The C twins of a fused model (the compiled engine's evaluations of a small one, the
    functions themselves of a large one) give its Python functions' numbers to the last
    bit: one text, C's syntax, for both (`mechsim.codegen.printer.neutral_printer`)."""
    import ctypes

    from mechsim.codegen.compiled import shared_library
    mech = MECHANISMS[name]()
    prob = mech.problem(build="fused")
    model, p = prob.model, np.ascontiguousarray(prob.p, dtype=float)
    q, v, t = _state(mech, prob)
    lib = shared_library(model.C_SOURCE, tmp_path / "twins.so")
    assert lib is not None
    python = getattr(model, "PYTHON_KERNELS", {})
    for name_, has_v, shapes in model.C_SIGNATURES:
        outs = [np.zeros(rows * cols) for rows, cols in shapes]
        fn = getattr(lib, f"mechsim_{name_}")
        fn.restype = None
        fn.argtypes = [ctypes.c_void_p] * (2 if has_v else 1) + \
            [ctypes.c_double, ctypes.c_void_p] + [ctypes.c_void_p] * len(outs)
        fn(*([q.ctypes.data] + ([v.ctypes.data] if has_v else []) + [ctypes.c_double(t),
             p.ctypes.data] + [o.ctypes.data for o in outs]))
        own = python.get(name_, getattr(model, name_))
        expected = own(q, v, t, prob.p) if has_v else own(q, t, prob.p)
        for out, value in zip(outs, expected if isinstance(expected, tuple) else (expected,)):
            np.testing.assert_array_equal(out, np.ravel(value))


def test_numpy_s_functions_the_kernels_take_round_as_libm_s():
    """The type kernels evaluate sin, cos, sqrt and fabs by numpy's functions over the
    joints of a type, the fused model by libm's, one joint at a time
    (`mechsim.assembly.unrolled.NUMPY_MATH`): the two builds agree only where these do,
    to the last bit (the others, numpy's tan, atan2, pow … the kernels take from libm)."""
    import math
    from mechsim.assembly.unrolled import NUMPY_MATH
    rng = np.random.default_rng(5)
    x = np.concatenate([rng.uniform(-50.0, 50.0, 20000), rng.uniform(-1e-3, 1e-3, 2000),
                        rng.uniform(-1e6, 1e6, 2000), [0.0, -0.0, math.pi, 1e-300]])
    for name in ("sin", "cos", "fabs"):
        expected = np.array([getattr(math, name)(v) for v in x.tolist()])
        np.testing.assert_array_equal(NUMPY_MATH[name](x), expected, err_msg=name)
    positive = np.abs(x)
    np.testing.assert_array_equal(NUMPY_MATH["sqrt"](positive),
                                  np.array([math.sqrt(v) for v in positive.tolist()]))
    y = rng.uniform(-3.0, 3.0, x.size)
    np.testing.assert_array_equal(NUMPY_MATH["atan2"](y, x),
                                  np.array([math.atan2(a, b) for a, b in zip(y, x)]))


@pytest.mark.parametrize("name", list(MECHANISMS))
def test_many_states_at_once_equal_each_state_bitwise(name):
    """`NumericProblem.phi_many` and `phi_q_many` of the assembled model (each kernel once
    for the joints of all states: the output samples and the passage search) give every
    state's Φ and Φ_q to the last bit, drivers' laws at each state's own time included."""
    mech = MECHANISMS[name]()
    prob = mech.problem(build="assembled")
    rng = np.random.default_rng(3)
    Q, ts = rng.standard_normal((5, prob.n)), rng.uniform(0.0, 0.5, 5)
    one = [(prob.phi(q, t), prob.phi_q(q, t)) for q, t in zip(Q, ts)]
    phis, jacobians = prob.phi_many(Q, ts), prob.phi_q_many(Q, ts)
    assert phis.shape == (5, prob.m) and jacobians.shape == (5, prob.m, prob.n)
    for k, (phi, J) in enumerate(one):
        np.testing.assert_array_equal(phis[k], phi)
        np.testing.assert_array_equal(jacobians[k], J)
    for q, t, csr in zip(Q, ts, prob.model.phi_q_csr_many(Q, ts, prob.p)):
        one = prob.model.phi_q_csr(q, t, prob.p)
        np.testing.assert_array_equal(csr.data, one.data)
        assert csr.indices is one.indices and csr.shape == one.shape
    if mech.drivers:                          # each driver's law at its state's own time
        assert not np.array_equal(prob.phi(Q[0], ts[1]), phis[0])


@pytest.mark.parametrize("name, size", [
    ("scene driven_slider_crank", 1.0), ("scene flexible_slider_crank", 1.0),
    ("flexible_four_bar 3 modes", 1.0), ("random double-rocker", 1.0),
    ("scene cam_follower", 0.03), ("cam through points", 0.03)])
def test_assembled_against_finite_differences(name, size):
    """Φ_q and Φ_t are the derivatives of Φ, and γ = −d²Φ/ds² along q + s v, t + s (the
    path with q̈ = 0), by central differences: first derivatives at h = 1e-5 (truncation
    ~1e-10, round-off ~1e-11), the second at h = 1e-4 (both ~1e-8), times the size of the
    mechanism's features (a cam's 3 cm radius: its contact's derivatives grow as 1/r)."""
    mech = MECHANISMS[name]()
    prob = mech.problem(build="assembled")
    a, p = prob.model, prob.p
    q, v, t = _state(mech, prob, seed=11)
    h = 1e-5 * size
    J = a.phi_q(q, t, p)
    fd = np.column_stack([(a.phi(q + h * e, t, p) - a.phi(q - h * e, t, p)) / (2 * h)
                          for e in np.eye(prob.n)])
    assert np.max(np.abs(J - fd)) < 1e-8 * (1 + np.max(np.abs(J)))
    phi_t = (a.phi(q, t + h, p) - a.phi(q, t - h, p)) / (2 * h)
    assert np.max(np.abs(a.phi_t(q, t, p) - phi_t)) < 1e-7
    h = 1e-4 * size
    second = (a.phi(q + h * v, t + h, p) - 2 * a.phi(q, t, p) + a.phi(q - h * v, t - h, p)) / h**2
    gamma = a.gamma(q, v, t, p)
    assert np.max(np.abs(gamma + second)) < 1e-5 * (1 + np.max(np.abs(gamma)))


def test_driver_laws_share_a_kernel_and_their_jets_are_exact():
    """Two cranks driven by different laws are one kernel group; each law's f, f', f''
    (Φ, −Φ_t, γ's share) equal sympy's derivatives."""
    import sympy as sp
    mech = examples.double_four_bar(2)
    laws = ["2*pi*t + 0.3*sin(3*t)", "atan2(sin(t) + 2, cos(t) + 0.5*t) + exp(-t)*t**2"]
    for name, law in zip(("A1", "A3"), laws):
        mech.add(ms.Driver(mech.joint(name), law))
    a = mech.problem(build="assembled").model
    assert len(a.groups) == 3              # ground pins, coupler pins, drivers
    t = sp.Symbol("t", real=True)
    for law in laws:
        f = parse(law, {"t"}, "law").to_sympy({"t": t})
        want = [float(f.subs(t, 0.8)), float(f.diff(t).subs(t, 0.8)),
                float(f.diff(t, 2).subs(t, 0.8))]
        assert np.allclose(parse(law, {"t"}, "law").jet("t", 0.8), want, rtol=1e-14,
                           atol=1e-14)


@pytest.mark.parametrize("factory, method, t_end", [
    (examples.four_bar, "hybrid", 0.5),
    (lambda: examples.slider_crank(driven=True, crank_speed=100.0), "lu", 0.2),
    (examples.flexible_four_bar, "projection", 0.2),
    (lambda: examples.double_four_bar(4), "hybrid", 1.0),
    (lambda: examples.double_four_bar(10), "hybrid", 0.3),
])
def test_runs_are_alike_to_the_last_bit_on_either_build(factory, method, t_end):
    """The same simulation on the fused and the assembled build gives the same times,
    states and passages to the last bit (through the four-window chain's passages too):
    a mechanism's first run on the assembled build and its later ones on the fused model
    built meanwhile agree. The fused runs take the Python path here, as the assembled ones
    do; the compiled engine (small rigid mechanisms, which "auto" fuses at once) solves
    with its own arithmetic."""
    from mechsim.codegen import engine
    runs = []
    for build in ("fused", "assembled"):
        mech = factory()
        prob = mech.problem(build=build)
        with engine.python_path(prob.model):
            runs.append(mech.simulate(t_end=t_end, method=method, rtol=1e-9,
                                      output_step=t_end / 50))
    fused, assembled = runs
    assert fused.status == assembled.status == "success"
    for x, y in ((fused.t, assembled.t), (fused.q, assembled.q), (fused.v, assembled.v)):
        np.testing.assert_array_equal(x, y)
    assert [s.t_min for s in fused.singular_passages] == \
        [s.t_min for s in assembled.singular_passages]


def _python(code: str, cache: Path, **env) -> str:
    full = {**os.environ, "MECHSIM_CACHE_DIR": str(seeded_cache(cache)), **env}
    full.pop("MECHSIM_BUILD", None)
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          env=full, timeout=300)
    assert done.returncode == 0, done.stderr
    return done.stdout


_BUILD = """
import json, sys, mechsim as ms
mech = ms.examples.double_four_bar({n})
prob = mech.problem()
print(json.dumps(dict(kind=type(prob.model).__name__, from_cache=mech.from_cache,
                      sympy="sympy" in sys.modules, engine=mech.compilation().engine)))
"""

# What a process says of the background builds it started.
_STARTED = "from mechsim.build import background\nprint(len(background._started))\n"


def test_auto_build_fuses_mechanisms_under_sixty_coordinates_at_once_and_larger_ones_later(
        tmp_path):
    """A new small mechanism (the double four-bar, 15 coordinates) is fused at once, with
    its compiled evaluations: sympy runs only for its joint types' kernels, and a second
    process loads it. A larger one of the same joint types (4 windows, 27 coordinates) is
    fused at once with no sympy at all. A long one (10 windows, 63 coordinates, whose
    fused model's C twins take a compile) runs assembled at once while a background
    process fuses it; a later build loads the fused model."""
    small = json.loads(_python(_BUILD.format(n=2), tmp_path))
    assert small == dict(kind="module", from_cache=False, sympy=True, engine=True)
    again = json.loads(_python(_BUILD.format(n=2), tmp_path))
    assert again == dict(kind="module", from_cache=True, sympy=False, engine=True)
    larger = json.loads(_python(_BUILD.format(n=4), tmp_path))
    assert larger == dict(kind="module", from_cache=False, sympy=False, engine=True)
    first, started = _python(_BUILD.format(n=10) + _STARTED, tmp_path).splitlines()
    assert json.loads(first) == dict(kind="AssembledModel", from_cache=True, sympy=False,
                                     engine=False)
    assert started == "1"                       # the fused build, in the background
    deadline = time.monotonic() + 120
    while True:
        later = json.loads(_python(_BUILD.format(n=10), tmp_path))
        if later["kind"] != "AssembledModel" or time.monotonic() > deadline:
            break
        time.sleep(1.0)
    assert later == dict(kind="module", from_cache=True, sympy=False, engine=False)
    assert len(mechanism_models(tmp_path)) == 3
    assert len(list(tmp_path.glob("mechsim_model_*.py"))) == 5      # and 2 joint types


_RUN = """
import hashlib, mechsim as ms
mech = ms.examples.double_four_bar(2)
res = mech.simulate(2.0, rtol=1e-8, atol=1e-10, output_step=0.01)
print(mech.from_cache, res.stats["steps"],
      hashlib.sha256(res.t.tobytes() + res.q.tobytes() + res.v.tobytes()).hexdigest())
"""


def test_a_small_mechanism_runs_bitwise_alike_in_every_process(tmp_path):
    """The first process (empty cache: the fused model built at once) and a later one
    (loading it) run the double four-bar through its passages to the same bits."""
    first = _python(_RUN, tmp_path).split()
    later = _python(_RUN, tmp_path).split()
    assert first[0] == "False" and later[0] == "True"
    assert first[1:] == later[1:]


def test_background_builds_can_be_switched_off(tmp_path):
    """With MECHSIM_BACKGROUND false a long chain's first build runs assembled and starts
    no background build (the process's record of the builds it started, one by default:
    above), so only the joint types' kernels are cached."""
    kind, count = _python(_BUILD.format(n=10) + _STARTED, tmp_path,
                          MECHSIM_BACKGROUND="0").splitlines()
    assert json.loads(kind)["kind"] == "AssembledModel" and count == "0"
    assert mechanism_models(tmp_path) == []
    assert len(list(tmp_path.glob("mechsim_model_*.py"))) == 2       # the kernels


@needs_compiler
def test_a_background_build_compiles_the_engine_s_evaluations_only_where_they_serve(
        tmp_path, monkeypatch):
    """The double four-bar's background build (`background.build`) compiles its model's
    twins with the engine's evaluations; the ten-window chain's only its own twins: its
    banded algebra runs in Python, and the engine's library would compile its model's C
    once more."""
    from mechsim.build import background
    from mechsim.codegen import cache
    monkeypatch.setenv("MECHSIM_CACHE_DIR", str(seeded_cache(tmp_path)))
    cache.clear_memory_cache()
    try:
        for n, libraries in ((2, 1), (10, 1)):          # (the count so far)
            mech = examples.double_four_bar(n)
            background.build(mech.bodies, mech.constraint_items, mech.structure())
            assert len(list(tmp_path.glob("*.evaluations-*.so"))) == libraries
    finally:
        cache.clear_memory_cache()


def test_a_process_runs_one_background_build_at_a_time(tmp_path):
    """Two long chains built one after the other in a process (a study over lengths):
    the second runs assembled without a build of its own while the first's compiles."""
    code = ("import mechsim as ms\nfrom mechsim.build import background\n"
            "for n in (10, 11):\n    ms.examples.double_four_bar(n).problem()\n"
            "print(len(background._started))\n")
    assert _python(code, tmp_path).strip() == "1"


def test_unknown_build_is_an_error(monkeypatch):
    mech = examples.four_bar()
    with pytest.raises(ms.ModelError, match="`build` must be one of auto, fused, assembled"):
        mech.problem(build="fast")
    monkeypatch.setenv("MECHSIM_BUILD", "quick")
    with pytest.raises(ms.ModelError, match="MECHSIM_BUILD must be one of"):
        examples.pendulum().problem()


def test_assembled_kernels_survive_a_damaged_cache_entry(tmp_path):
    """A kernel whose cache entry was edited is rebuilt with a warning."""
    _python(_BUILD.format(n=10), tmp_path, MECHSIM_BACKGROUND="0")
    for path in tmp_path.glob("mechsim_model_*.py"):
        path.write_text(path.read_text().replace("numpy.zeros", "numpy.ones"))
    code = _BUILD.format(n=10) + "print(abs(prob.phi(mech.initial_coordinates(), 0.0)).max())"
    out = _python(code, tmp_path, MECHSIM_BACKGROUND="0")
    report, residual = out.splitlines()
    assert json.loads(report)["from_cache"] is False
    assert float(residual) < 1e-12
    assert math.isfinite(float(residual))
