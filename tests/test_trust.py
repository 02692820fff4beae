"""Trust boundaries: bad input of every kind gets an error naming what is wrong before any
work (or a failed result naming it), nothing a user writes runs as code, and the model cache
cannot crash or poison a run."""

import cmath
import functools
import math
import os
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import mechsim as ms
from mechsim.model.expressions import ExpressionError, parse
from mechsim.app.scene import SceneError

ROOT = Path(__file__).resolve().parents[1]
FOUR_BAR = (ROOT / "mechanisms" / "four_bar.toml").read_text()


# --- a table of bad inputs ---------------------------------------------------------------------
def pendulum():
    return ms.examples.pendulum()


def body(**kw):
    args = dict(name="b", mass=1.0, inertia=0.1)
    args.update(kw)
    return ms.RigidBody(args.pop("name"), args.pop("mass"), args.pop("inertia"), **args)


def driven(expression, name="d"):
    m = pendulum()
    m.add(ms.Driver(m.joint("pivot"), expression, name=name))
    return m


def with_load(load):
    m = pendulum()
    m.add(load(m.body("rod")))
    return m


def broken_four_bar():
    m = ms.Mechanism("broken")
    a = m.add(ms.RigidBody.rod("crank", (0, 0), (0, 1), 1.0))
    b = m.add(ms.RigidBody.rod("coupler", (0, 1), (0.5, 1), 1.0))
    c = m.add(ms.RigidBody.rod("rocker", (3, 0), (3, 1), 1.0))
    m.add(ms.Revolute(m.ground, a, at=(0, 0), name="A"))
    m.add(ms.Revolute(a, b, at=(0, 1), name="B"))
    m.add(ms.Revolute(b, c, local_a=(0.25, 0.0), local_b=(0.5, 0.0), name="C"))
    m.add(ms.Revolute(m.ground, c, at=(3, 0), name="D"))
    return m


def direct(q_change=0.0, v_change=0.0, q_slice=None):
    """ms.solver.simulate on the pendulum's problem with a changed initial state."""
    m = pendulum()
    rep = m.assemble()
    q = rep.q + q_change if q_slice is None else rep.q[q_slice]
    return ms.solver.simulate(m.problem(), q, rep.v + v_change, t_end=0.5)


def scene(text, tmp):
    path = tmp / "bad.toml"
    path.write_text(text)
    return ms.load_scene(path)


def four_bar_with(old, new):
    assert old in FOUR_BAR
    return FOUR_BAR.replace(old, new, 1)


def run_cli(tmp, text):
    """`mechsim run` of a scene in a fresh directory: (exit status, stderr)."""
    from mechsim.app.cli import main
    path = tmp / "scene.toml"
    path.write_text(text)
    cwd = os.getcwd()
    os.chdir(tmp)
    try:
        import contextlib
        import io
        err = io.StringIO()
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
            code = main(["run", str(path), "--no-plots"])
    finally:
        os.chdir(cwd)
    if code != 0:
        raise SceneError(err.getvalue())
    return code


MODEL = [
    ("body name empty", lambda t: body(name=""), "non-empty name"),
    ("body name None", lambda t: body(name=None), "non-empty name"),
    ("body name number", lambda t: body(name=5), "non-empty name"),
    ("mass negative", lambda t: body(mass=-1.0), "body 'b'.*`mass` must be positive"),
    ("mass zero", lambda t: body(mass=0.0), "`mass` must be positive"),
    ("mass nan", lambda t: body(mass=math.nan), "`mass` must be finite"),
    ("mass inf", lambda t: body(mass=math.inf), "`mass` must be finite"),
    ("mass string", lambda t: body(mass="1.5"), "`mass` must be a number"),
    ("mass bool", lambda t: body(mass=True), "`mass` must be a number"),
    ("inertia negative", lambda t: body(inertia=-1.0), "`inertia` must be non-negative"),
    ("position three", lambda t: body(position=(1, 2, 3)), "`position` must have length 2"),
    ("position text", lambda t: body(position="ab"), "`position` must be a 2-vector"),
    ("angle nan", lambda t: body(angle=math.nan), "`angle` must be finite"),
    ("velocity nan", lambda t: body(velocity=(math.nan, 0)), "`velocity` must be finite"),
    ("angular velocity inf", lambda t: body(angular_velocity=math.inf),
     "`angular_velocity` must be finite"),
    ("rod of zero length", lambda t: ms.RigidBody.rod("r", (1, 1), (1, 1), 1.0),
     "body 'r'.*coincide"),
    ("rod mass zero", lambda t: ms.RigidBody.rod("r", (0, 0), (1, 0), 0.0),
     "body 'r'.*`mass` must be positive"),
    ("joint on a non-body", lambda t: ms.Revolute("ground", body(), at=(0, 0)),
     "`body_a` must be a body"),
    ("joint to itself", lambda t: (lambda b: ms.Revolute(b, b, at=(0, 0)))(body()),
     "connects body 'b' to itself"),
    ("joint at nan", lambda t: ms.Revolute(ms.Ground(), body(), at=(math.nan, 0)),
     "`at` must be finite"),
    ("joint name empty", lambda t: ms.Revolute(ms.Ground(), body(), at=(0, 0), name=""),
     "revolute joint.*`name` must be a non-empty string"),
    ("prismatic axis zero", lambda t: ms.Prismatic(ms.Ground(), body(), axis=(0, 0), at=(0, 0)),
     "prismatic joint.*axis"),
    ("prismatic axis three", lambda t: ms.Prismatic(ms.Ground(), body(), axis=(1, 0, 0),
                                                    at=(0, 0)), "`axis` must have length 2"),
    ("spring stiffness negative", lambda t: ms.Spring(ms.Ground(), body(), (0, 0), (1, 0), -1.0),
     "spring.*`stiffness` must be non-negative"),
    ("spring damping nan", lambda t: ms.Spring(ms.Ground(), body(), (0, 0), (1, 0), 1.0,
                                               damping=math.nan), "`damping` must be finite"),
    ("spring rest length negative", lambda t: ms.Spring(ms.Ground(), body(), (0, 0), (1, 0),
                                                        1.0, rest_length=-1),
     "`rest_length` must be non-negative"),
    ("spring on a non-body", lambda t: ms.Spring(None, body(), (0, 0), (1, 0), 1.0),
     "`body_a` must be a body"),
    ("force of three", lambda t: ms.Force(body(), (1, 2, 3)), "force.*`force` must have length 2"),
    ("force nan", lambda t: ms.Force(body(), (math.nan, 0)), "`force` must be finite"),
    ("torque text", lambda t: ms.Torque(body(), "abc"), "torque.*`torque`: unknown name 'abc'"),
    ("torque nan", lambda t: ms.Torque(body(), math.nan), "`torque` must be finite"),
    ("driver on a body", lambda t: ms.Driver(body(), "t"), "`joint` must be a joint"),
    ("driver unknown name", lambda t: driven("10*tt"), "driver 'd'.*unknown name 'tt'"),
    ("driver code", lambda t: driven("__import__('os').system('true')"),
     "driver 'd'.*unknown function"),
    ("driver huge power", lambda t: driven("9**9**9*t"), "driver 'd'.*exponent"),
    ("driver caret", lambda t: driven("t^2"), "driver 'd'.*write `\\*\\*`"),
    ("driver empty", lambda t: driven(""), "driver 'd'.*empty"),
    ("driver None", lambda t: driven(None), "driver 'd': give an `expression` or a `table`"),
    ("driver attribute", lambda t: driven("t.real"), "driver 'd'.*unsupported syntax"),
    ("driver lambda", lambda t: driven("lambda t: t"), "driver 'd'.*unsupported syntax"),
    ("driver arity", lambda t: driven("sin(t, t)"), "driver 'd'.*sin takes 1 argument"),
    ("driver constant overflow", lambda t: driven("1e400*t"), "driver 'd'.*out of range"),
    ("driver name empty", lambda t: driven("t", name=""), "driver.*`name` must be a non-empty"),
    ("beam no elements", lambda t: ms.FlexibleBeam("fb", 1.0, 1e9, 1e3, 1e-4, 1e-8,
                                                   n_elements=0), "beam 'fb'.*n_elements"),
    ("beam half a mode", lambda t: ms.FlexibleBeam("fb", 1.0, 1e9, 1e3, 1e-4, 1e-8,
                                                   n_modes=1.5), "beam 'fb'.*n_modes"),
    ("beam boundary", lambda t: ms.FlexibleBeam("fb", 1.0, 1e9, 1e3, 1e-4, 1e-8,
                                                boundary="pinned"), "beam 'fb'.*boundary"),
    ("beam length", lambda t: ms.FlexibleBeam("fb", -1.0, 1e9, 1e3, 1e-4, 1e-8),
     "beam 'fb'.*`length` must be positive"),
    ("beam modulus nan", lambda t: ms.FlexibleBeam("fb", 1.0, math.nan, 1e3, 1e-4, 1e-8),
     "beam 'fb'.*`youngs_modulus` must be finite"),
    ("gravity of one", lambda t: ms.Mechanism("g", gravity=(0,)), "`gravity` must have length 2"),
    ("duplicate body", lambda t: (lambda m: m.add(body(name="rod")))(pendulum()),
     "a body named 'rod' exists already"),
    ("joint to a foreign body", lambda t: (lambda m: m.add(ms.Revolute(m.ground, body(),
                                                                        at=(0, 0))))(pendulum()),
     "body 'b' is not in mechanism"),
    ("driver before its joint", lambda t: (lambda m: m.add(ms.Driver(
        ms.Revolute(m.ground, m.body("rod"), at=(0, 0), name="j2"), "t")))(pendulum()),
     "joint 'j2' is not in"),
    ("joint driven twice", lambda t: (lambda m: [m.add(ms.Driver(m.joint("pivot"), "t",
                                                                 name=f"d{i}"))
                                                 for i in range(2)])(pendulum()),
     "joint 'pivot' is driven already"),
    ("add a string", lambda t: pendulum().add("rod"), "cannot add 'rod'"),
    ("unknown body", lambda t: pendulum().body("rdo"), "has no body 'rdo'"),
    ("unknown joint", lambda t: pendulum().joint("pviot"), "has no joint 'pviot'"),
    ("cannot assemble", lambda t: broken_four_bar().assemble(), "cannot be assembled.*of '[ABCD]'"),
    ("nothing to simulate", lambda t: ms.Mechanism("empty").simulate(1.0), "no moving bodies"),
    ("driver undefined at the start", lambda t: driven("log(t)").simulate(0.5),
     "driver 'd' prescribes log\\(t\\), whose value, rate or acceleration is not defined at "
     "t = 0.*math domain error.*t_start"),
    ("driver rate infinite at the start", lambda t: driven("sqrt(t)").simulate(0.5),
     "driver 'd' prescribes sqrt\\(t\\).*not defined at t = 0"),
    ("driver with a negative power of t", lambda t: driven("t**-1").simulate(0.5),
     "driver 'd' prescribes t\\*\\*-1.*not defined at t = 0"),
    ("beam of 100000 elements", lambda t: ms.FlexibleBeam(
        "c", length=1.0, youngs_modulus=1e9, density=1e3, area=1e-4, second_moment=1e-8,
        n_elements=100000), "beam 'c': `n_elements` = 100000.*GiB.*use at most 2000"),
]

SIMULATE = [
    ("t_end nan", dict(t_end=math.nan), "`t_end` must be finite"),
    ("t_end negative", dict(t_end=-1.0), "`t_end` must be after t_start"),
    ("t_end text", dict(t_end="1"), "`t_end` must be a number"),
    ("method typo", dict(method="hybird"), "unknown method 'hybird' \\(did you mean 'hybrid'"),
    ("integrator typo", dict(integrator="rk99"), "unknown integrator 'rk99'"),
    ("rtol zero", dict(rtol=0.0), "`rtol` must be positive"),
    ("rtol nan", dict(rtol=math.nan), "`rtol` must be finite"),
    ("rtol bool", dict(rtol=True), "`rtol` must be a number"),
    ("atol negative", dict(atol=-1.0), "`atol` must be positive"),
    ("max_step zero", dict(max_step=0.0), "`max_step` must be positive"),
    ("output_step nan", dict(output_step=math.nan), "`output_step` must be finite"),
    ("output grid too large", dict(output_step=1e-12), "`output_step`.*GiB.*larger output_step"),
    ("first_step nan", dict(first_step=math.nan), "`first_step` must be finite"),
    ("first_step negative", dict(first_step=-1e-3), "`first_step` must be positive"),
    ("max_steps fraction", dict(max_steps=1.5), "`max_steps` must be a whole number"),
    ("max_steps text", dict(max_steps="10"), "`max_steps` must be a whole number"),
    ("max_steps zero", dict(max_steps=0), "`max_steps` must be ≥ 1"),
    ("fixed step negative", dict(method="ss-newmark", h=-1.0), "`h` must be positive"),
    ("fixed step missing", dict(method="ss-newmark"), "steps at a fixed size: give `h`"),
    ("thresholds reversed", dict(singular_thresholds=(0.2, 0.1)),
     "`singular_thresholds` must be two numbers"),
    ("option typo", dict(rtoll=1e-8), "does not take 'rtoll' \\(did you mean 'rtol'\\?\\)"),
    ("option of another method", dict(alpha=1.0), "'alpha' is an option of method.*baumgarte"),
    ("option choice", dict(method="projection", factorization="svdd"),
     "`factorization` of method 'projection' must be one of.*did you mean 'svd'"),
    ("option integer", dict(stable_steps=0), "`stable_steps` of method 'hybrid' must be ≥ 1"),
    ("option flag", dict(method="projection", projection="yes"),
     "`projection` of method 'projection' must be true or false"),
    ("t_start nan", dict(t_start=math.nan), "`t_start` must be finite"),
]

DIRECT = [
    ("q0 unassembled", lambda t: direct(q_change=0.1), "`q0` does not satisfy the constraints.*'pivot'"),
    ("v0 nan", lambda t: direct(v_change=math.nan), "`v0` must be finite.*'rod.x'"),
    ("q0 short", lambda t: direct(q_slice=slice(0, 2)), "`q0` must have 3 entries"),
    ("v0 inconsistent", lambda t: direct(v_change=1.0), "`v0` does not satisfy the velocity"),
]

FAILED_RUNS = [
    ("torque raises", lambda: with_load(lambda b: ms.Torque(
        b, lambda t: 1.0 / 0.0 if t > 0.05 else 0.0, name="motor")),
     "torque 'motor': its function raised ZeroDivisionError", ZeroDivisionError),
    ("force of wrong shape", lambda: with_load(lambda b: ms.Force(b, lambda t: (1.0, 2.0, 3.0),
                                                                  name="push")),
     "force 'push': the function returned", None),
    ("torque nan", lambda: with_load(lambda b: ms.Torque(b, lambda t: math.nan, name="motor")),
     "torque 'motor': the function returned nan", None),
    ("force raises KeyError", lambda: with_load(lambda b: ms.Force(b, lambda t: {}["k"],
                                                                   name="push")),
     "force 'push': its function raised KeyError", KeyError),
    ("driver undefined", lambda: driven("log(1 - t)"),
     "driver 'd' prescribes log\\(1 - t\\), undefined", None),
    ("torque overflows", lambda: with_load(lambda b: ms.Torque(b, 1e300, name="huge")),
     "non-finite|overflow|step size", None),
]

SCENES = [
    ("export leaves the directory", four_bar_with("save = true", 'save = true\nexport = "../../x.vtu"'),
     "\\[output\\] export: must be a relative path"),
    ("absolute directory", four_bar_with("save = true", 'save = true\ndirectory = "/tmp/evil"'),
     "\\[output\\] directory: must be a relative path"),
    ("plot typo", four_bar_with('plots = ["energy"]', 'plots = ["energi"]'),
     "\\[output\\] plots: must be one of 'energy'"),
    ("point body typo", four_bar_with('[["crank", [0.5, 0.0]]]', '[["cranc", [0.5, 0.0]]]'),
     "\\[output\\] points: no body named 'cranc'"),
    ("save as text", four_bar_with("save = true", 'save = "no"'), "\\[output\\] save: must be true or false"),
    ("export format", four_bar_with("save = true", 'save = true\nexport = "x.stl"'),
     "\\[output\\] export: cannot export to 'x.stl'"),
    ("parameter named t", four_bar_with("[parameters]", "[parameters]\nt = 2.0"),
     "\\[parameters\\] 't' is a reserved name \\(time, in driver laws\\)"),
    ("parameter named like a function", four_bar_with("[parameters]", "[parameters]\nsin = 2.0"),
     "\\[parameters\\] 'sin' is a reserved name"),
    ("body as a table", '[body]\nname = "a"\nmass = 1\ninertia = 1\n[simulation]\nt_end = 1\n',
     "`body` must be an array of tables \\[\\[body\\]\\]"),
    ("parameters a number", "parameters = 5\n[simulation]\nt_end = 1\n",
     "`parameters` must be a table"),
    ("output a string", 'output = "x"\n[simulation]\nt_end = 1\n', "`output` must be a table"),
    ("simulation an array", "simulation = [1, 2]\n", "`simulation` must be a table"),
    ("first_step nan", four_bar_with("t_end = 2.0", "t_end = 2.0\nfirst_step = nan"),
     "\\[simulation\\] first_step: expected a finite number"),
    ("max_steps text", four_bar_with("t_end = 2.0", 't_end = 2.0\nmax_steps = "1.5"'),
     "\\[simulation\\].*`max_steps` must be a whole number"),
    ("rtol typo", four_bar_with("rtol = 1e-8", "rtoll = 1e-8"),
     "\\[simulation\\]: unknown key\\(s\\) 'rtoll' \\(did you mean 'rtol'"),
    ("method typo", four_bar_with('method = "hybrid"', 'method = "hybird"'),
     "\\[simulation\\]: unknown method 'hybird'"),
    ("t_end missing", four_bar_with("t_end = 2.0\n", ""), "\\[simulation\\]: needs `t_end`"),
    ("nesting too deep", "a = " + "[" * 3000 + "]" * 3000 + "\n", "nested too deeply|not valid TOML"),
    ("huge expression", '[parameters]\nL = "' + "+".join(["1"] * 3000) + '"\n',
     "\\[parameters\\] L: the expression has"),
    ("driver carries code", four_bar_with("[simulation]", '[[driver]]\njoint = "A"\n'
                                          'expression = "open(\'/etc/passwd\').read()"\n[simulation]'),
     "driver\\[0\\].*unknown function"),
    ("unknown top-level key", four_bar_with('name = "', 'bodys = 1\nname = "'),
     "unknown top-level key\\(s\\) 'bodys'"),
    ("body without name", "[[body]]\nmass = 1\ninertia = 1\n[simulation]\nt_end = 1\n",
     "body\\[0\\]: needs `name`"),
    ("joint type", four_bar_with('type = "revolute"', 'type = "hinge"'),
     "joint\\[0\\].*type: must be one of 'revolute', 'prismatic'"),
    ("joint with one body", four_bar_with('bodies = ["ground", "crank"]', 'bodies = ["ground"]'),
     "joint\\[0\\].*bodies: expected an array of two body names"),
    ("unknown parameter", four_bar_with('mass = "m"', 'mass = "2*M"'),
     "body\\[0\\].*unknown name 'M'"),
    ("parameter name", four_bar_with("L = 1.0", '"1x" = 1.0\nL = 1.0'),
     "\\[parameters\\] '1x' is not a valid name"),
    ("gravity text", four_bar_with("gravity = [0.0, -9.81]", 'gravity = [0, "x"]'),
     "gravity: unknown name 'x'"),
    ("rod of one point", four_bar_with('rod = [[0, 0], ["cx", "cy"]]', "rod = [[0, 0]]"),
     "body\\[0\\].*rod: expected an array of two points"),
    ("driver on no joint", four_bar_with("[simulation]", '[[driver]]\njoint = "Z"\n'
                                         'expression = "t"\n[simulation]'),
     "driver\\[0\\]: no joint named 'Z'"),
    ("spring without stiffness", four_bar_with("[simulation]", '[[spring]]\nbodies = ["ground", '
                                               '"crank"]\nat_a = [0, 1]\nat_b = [0.5, 0]\n'
                                               "[simulation]"),
     "spring\\[0\\]: needs `stiffness`"),
    ("not TOML", "name = \n", "not valid TOML"),
    ("key of the wrong table", four_bar_with('name = "A"', 'name = "A"\nmass = 1'),
     "joint\\[0\\].*unknown key\\(s\\) 'mass'"),
]


class Hang(Exception):
    pass


@pytest.fixture
def no_hang():
    """Each case must end within 60 s: a guard against hangs, not a measure of speed."""
    def alarm(*_):
        raise Hang("the case did not end within 60 s")
    old = signal.signal(signal.SIGALRM, alarm)
    signal.alarm(60)
    yield
    signal.alarm(0)
    signal.signal(signal.SIGALRM, old)


def test_the_table_holds_at_least_eighty_cases():
    assert len(MODEL) + len(SIMULATE) + len(DIRECT) + len(FAILED_RUNS) + len(SCENES) + \
        len(UNCLEAR) + 4 >= 80


@pytest.mark.parametrize("case, make, match", MODEL, ids=[c[0] for c in MODEL])
def test_bad_model_input_is_refused_naming_it(case, make, match, tmp_path, no_hang):
    with pytest.raises((ms.ModelError, KeyError), match=match):
        make(tmp_path)


@pytest.mark.parametrize("case, kw, match", SIMULATE, ids=[c[0] for c in SIMULATE])
def test_bad_simulate_arguments_are_refused_before_any_work(case, kw, match, no_hang):
    mech = pendulum()
    kw = dict(kw)
    t_end = kw.pop("t_end", 0.5)
    with pytest.raises(ValueError, match=match):
        mech.simulate(t_end, **kw)
    # Refused before the model was built (no compilation, no assembly).
    assert mech._problem is None


@pytest.mark.parametrize("case, make, match", DIRECT, ids=[c[0] for c in DIRECT])
def test_bad_initial_states_are_refused(case, make, match, tmp_path, no_hang):
    with pytest.raises(ValueError, match=match):
        make(tmp_path)


@pytest.mark.parametrize("case, make, match, cause", FAILED_RUNS, ids=[c[0] for c in FAILED_RUNS])
@pytest.mark.parametrize("method", ["hybrid", "projection"])
def test_a_run_that_fails_says_why_and_keeps_its_samples(case, make, match, cause, method,
                                                         no_hang):
    res = make().simulate(1.5, method=method)
    assert res.status == "failed"
    assert np.all(np.isfinite(res.q)) and np.all(np.isfinite(res.v))
    assert len(res.t) >= 1
    import re
    assert re.search(match, res.message), res.message
    if cause is not None:
        assert isinstance(res.exception, ms.LoadError)
        assert isinstance(res.exception.__cause__, cause)


@pytest.mark.parametrize("case, text, match", SCENES, ids=[c[0] for c in SCENES])
def test_bad_scenes_are_refused_naming_the_key(case, text, match, tmp_path, no_hang):
    with pytest.raises(SceneError, match=match):
        scene(text, tmp_path)
    # The command line says the same and returns 2, writing nothing.
    with pytest.raises(SceneError, match=match):
        run_cli(tmp_path, text)
    assert not (tmp_path / "out").exists()


def locked_chain():
    """Two links held straight between fixed pivots: instantaneously mobile, finitely not."""
    mech = ms.Mechanism("locked chain")
    a = mech.add(ms.RigidBody.rod("a", (0, 0), (1, 0), 1.0))
    b = mech.add(ms.RigidBody.rod("b", (1, 0), (2, 0), 1.0))
    mech.add(ms.Revolute(mech.ground, a, at=(0, 0), name="O"))
    mech.add(ms.Revolute(a, b, at=(1, 0), name="M"))
    mech.add(ms.Revolute(b, mech.ground, at=(2, 0), name="E"))
    return mech


UNCLEAR = [
    ("locked collinear chain", lambda t: locked_chain().simulate(1.0),
     "'locked chain' is locked where it starts.*joints O, M, E.*no finite one"),
    ("assemble tol negative", lambda t: pendulum().assemble(tol=-1.0),
     "assemble: `tol` must be a positive number, got -1"),
    ("load a text file", lambda t: ms.load_result((t / "hello.txt", (t / "hello.txt").write_text(
        "hello"))[0]), "hello.txt is not a result saved by mechsim"),
    ("steady state period as float32", lambda t: ms.examples.pendulum().steady_state(
        period=np.float32(-0.0419)), "`period` must be positive, got"),
    ("linear system step too small", lambda t: ms.LinearSystem(
        np.eye(2), np.zeros((2, 2)), np.eye(2)).simulate(30.0, h=1e-12),
     "`h` = 1e-12 over 30 s.*GiB.*choose a larger h"),
    ("linear system force nan", lambda t: ms.LinearSystem(
        np.eye(2), np.zeros((2, 2)), np.eye(2), force=lambda t: [math.nan, 0.0]).simulate(
        1.0, h=0.1), "`force\\(t\\)` must be finite"),
    ("linear system x0 nan", lambda t: ms.LinearSystem(
        np.eye(2), np.zeros((2, 2)), np.eye(2)).simulate(1.0, h=0.1, x0=[math.nan, 0.0]),
     "`x0` must be finite"),
]


@pytest.mark.parametrize("case, make, match", UNCLEAR, ids=[c[0] for c in UNCLEAR])
def test_bad_arguments_elsewhere_are_refused_naming_them(case, make, match, tmp_path, no_hang):
    """Each once failed unclearly (a pickle hint, "must be positive" for a positive numpy
    scalar, a MemoryError of terabytes, NaNs returned silently)."""
    with pytest.raises(ValueError, match=match):
        make(tmp_path)


def test_numpy_scalars_are_numbers(no_hang):
    sol = ms.examples.spring_mass(mass=np.float32(2.0), stiffness=np.int64(800),
                                  stretch=0.0, damping=np.float64(6.0))
    assert sol.simulate(np.float32(0.1), rtol=np.float64(1e-8)).status == "success"
    steady = ms.examples.pendulum(angle=-math.pi / 2).steady_state(period=np.float32(0.5))
    assert steady.iterations >= 0


def test_scene_files_that_are_not_scenes(tmp_path, no_hang):
    (tmp_path / "latin1.toml").write_bytes('name = "Gr\xfcn"\n'.encode("latin-1"))
    with pytest.raises(SceneError, match="latin1.toml: not UTF-8"):
        ms.load_scene(tmp_path / "latin1.toml")
    (tmp_path / "dir.toml").mkdir()
    with pytest.raises(SceneError, match="is a directory"):
        ms.load_scene(tmp_path / "dir.toml")
    with pytest.raises(SceneError, match="does not exist"):
        ms.load_scene(tmp_path / "missing.toml")
    (tmp_path / "big.toml").write_text("# " + "x" * (5 * 2 ** 20))
    with pytest.raises(SceneError, match="larger than"):
        ms.load_scene(tmp_path / "big.toml")


def test_scene_outputs_stay_inside_the_output_directory_through_links(tmp_path):
    """A link inside the output directory pointing out of it is refused before the run."""
    out = tmp_path / "out" / "scene"
    out.mkdir(parents=True)
    outside = tmp_path / "elsewhere"
    outside.mkdir()
    (out / "link").symlink_to(outside)
    text = four_bar_with("save = true", 'save = true\nexport = "link/x.vtu"')
    with pytest.raises(SceneError, match="leaves the output directory"):
        run_cli(tmp_path, text)
    assert not list(outside.iterdir())


# --- user text never runs ------------------------------------------------------------------------
PAYLOAD_NAMES = [
    'x"""; __import__("os").system("touch {m}"); """',
    "x'''; __import__('os').system('touch {m}'); '''",
    'a\n__import__("os").system("touch {m}")\n',
    '"); __import__("os").system("touch {m}"); ("',
    "ﬁ", "fi", "x²", "é\u200b", "{m}\\\\",
]


def _build_named(names, marker):
    """A chain of pendulums whose mechanism, bodies and joints carry `names`."""
    mech = ms.Mechanism(names[0].format(m=marker))
    for i, raw in enumerate(names):
        name = raw.format(m=marker)
        b = mech.add(ms.RigidBody.rod(name, (i, 0), (i + 1, 0), mass=1.0 + 0.1 * i))
        mech.add(ms.Revolute(mech.ground, b, at=(i, 0), name=name + " pin"))
    return mech


def test_names_carrying_code_never_run_and_stay_apart(tmp_path):
    """Each pendulum i of mass 1 + i/10 pinned at its end swings as every other one (a rod
    pinned at its end does not depend on its mass): equal motion, so no two names were
    mixed up in the generated code ('ﬁ' and 'fi' are one identifier to Python)."""
    marker = tmp_path / "marker"
    mech = _build_named(PAYLOAD_NAMES, marker)
    res = mech.simulate(0.5, rtol=1e-10, atol=1e-12)
    assert res.status == "success" and not marker.exists()
    angles = res.q[-1, 2::3]
    assert np.ptp(angles) < 1e-8 and abs(angles[0]) > 0.1


_REUSE = textwrap.dedent("""
    import sys
    sys.path.insert(0, {tests!r})
    from test_trust import _build_named, PAYLOAD_NAMES
    mech = _build_named(PAYLOAD_NAMES, {marker!r})
    res = mech.simulate(0.2)
    print(res.status, mech.from_cache)
""")


def test_a_later_run_reusing_the_cache_runs_no_code_either(tmp_path):
    marker = tmp_path / "marker"
    env = {**os.environ, "MECHSIM_CACHE_DIR": str(seeded_cache(tmp_path / "cache"))}
    code = _REUSE.format(tests=str(ROOT / "tests"), marker=str(marker))
    outs = [subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                           text=True, check=True).stdout.split() for _ in range(2)]
    assert outs == [["success", "False"], ["success", "True"]]
    assert not marker.exists()
    for module in (tmp_path / "cache").glob("*.py"):
        text = module.read_text()
        assert "import os" not in text and "system" not in text and "marker" not in text


def test_driver_and_scene_payloads_never_run(tmp_path):
    marker = tmp_path / "marker"
    payloads = [f"__import__('os').system('touch {marker}')",
                f"(lambda: __import__('os').system('touch {marker}'))()",
                "[x for x in ().__class__.__base__.__subclasses__()]",
                f"open('{marker}', 'w').write('x')", "open('/etc/passwd').read()"]
    for payload in payloads:
        with pytest.raises(ms.ModelError) as err:
            driven(payload)
        assert "root:" not in str(err.value)
        text = four_bar_with("[simulation]", f'[[driver]]\njoint = "A"\nexpression = '
                                             f'"{payload}"\n[simulation]')
        with pytest.raises(SceneError):
            scene(text, tmp_path)
        name_text = four_bar_with('name = "A"', f"name = '''{payload}'''")
        name_text = name_text.replace('name = "four-bar', f"name = '''{payload}'''\n#", 1)
        res = scene(name_text, tmp_path).simulate(t_end=0.05)
        assert res.status == "success"
    assert not marker.exists()


# --- the model cache ---------------------------------------------------------------------------
_PROBE = textwrap.dedent("""
    import warnings
    warnings.simplefilter("always")
    import numpy as np
    import mechsim as ms
    m = ms.examples.double_four_bar({n})
    r = m.simulate(0.3, method="lu", rtol=1e-9, atol=1e-11, output_step=0.1)
    th, _ = ms.examples.parallelogram_exact(r.t, np.pi / 2, -1.0, n={n})
    c = m.compilation()
    print(r.status, float(np.abs(r.coordinate("crank1.angle") - th).max()), c.kernels, c.engine)
""")


def seeded_cache(directory):
    """conftest's `seeded_cache`, imported at the call: the processes of
    `test_a_later_run_reusing_the_cache_runs_no_code_either` import this module, and
    conftest on import points MECHSIM_CACHE_DIR at the session's cache."""
    from conftest import seeded_cache
    return seeded_cache(directory)


def _probe(cache, n=1, **env):
    return _probed(_start_probe(cache, n, **env))


def _start_probe(cache, n=1, **env):
    """The probe running in a new process on the cache directory `cache`."""
    return subprocess.Popen([sys.executable, "-c", _PROBE.format(n=n)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True,
                            env={**os.environ, "MECHSIM_CACHE_DIR": str(cache), **env})


def _probed(process):
    """(status, error, kernels compiled, engine compiled, stderr) of a started probe."""
    out, err = process.communicate(timeout=600)
    assert process.returncode == 0, f"the process died ({process.returncode}): {err[-500:]}"
    status, error, kernels, engine = out.split()
    return status, float(error), kernels == "True", engine == "True", err


@functools.cache
def _compiler_serves() -> bool:
    """Whether compiled C serves the four-bar here (asked on first use, not while the
    tests are collected)."""
    return ms.examples.four_bar().compilation().serves


@pytest.fixture
def compiler():
    if not _compiler_serves():
        pytest.skip("no working C compiler")


needs_compiler = pytest.mark.usefixtures("compiler")


class _Pristine(dict):
    """Caches built on first use for the damage cases: {n windows: (directory, probe
    result)}; a case's model and the other model it borrows an entry from built together."""

    def __init__(self, factory):
        super().__init__()
        self.factory = factory

    def built(self, *sizes):
        new = [n for n in sizes if n not in self]
        directories = {n: seeded_cache(self.factory.mktemp(f"cache{n}")) for n in new}
        started = {n: _start_probe(d, n) for n, d in directories.items()}
        self.update({n: (directories[n], _probed(p)) for n, p in started.items()})
        return self


@pytest.fixture(scope="module")
def pristine(tmp_path_factory):
    return _Pristine(tmp_path_factory)


# The kind of entry: (its model's windows, another model's, the entry's file pattern).
_ENTRIES = {"engine library": (1, 2, "*.evaluations-*.so"),
            "kernel library": (10, 11, "*.kernels-*.so"), "module": (1, 2, "*.py")}
# Each damage and each kind of entry once in the default suite (the small models); the
# rest of the matrix, and the larger models' other damages, in the slow one.
_DEFAULT_DAMAGE = {("truncated", "engine library"), ("foreign", "engine library"),
                   ("zero bytes", "module"), ("edited", "module"), ("truncated", "kernel library")}


def _entries(directory, pattern):
    """The cache entries of `pattern` in `directory`, a module's being the mechanism's
    model (not its joint types' kernels, which are modules too)."""
    return [p for p in directory.glob(pattern) if not p.name.endswith(".sha256") and
            not (p.suffix == ".py" and b"A mechsim type kernel" in p.read_bytes())]


@needs_compiler
@pytest.mark.xdist_group("pristine caches")     # one worker builds each model once
@pytest.mark.parametrize("damage, kind", [
    pytest.param(damage, kind, id=f"{damage}-{kind}",
                 marks=() if (damage, kind) in _DEFAULT_DAMAGE else pytest.mark.slow)
    for kind in _ENTRIES for damage in ("truncated", "zero bytes", "foreign", "edited")])
def test_a_damaged_cache_entry_is_rebuilt_with_the_right_answer(tmp_path, pristine, damage,
                                                                 kind):
    """Each kind of entry damaged each way: the next run (a new process: a truncated library
    used to kill it with SIGBUS) rebuilds the entry and gets the same answer."""
    import shutil
    n, other, pattern = _ENTRIES[kind]
    source, first = pristine.built(*((n, other) if damage == "foreign" else (n,)))[n]
    assert first[0] == "success" and first[1] < 1e-6
    cache = tmp_path / "cache"
    shutil.copytree(source, cache)
    (entry,) = _entries(cache, pattern)
    data = entry.read_bytes()
    if damage == "truncated":
        entry.write_bytes(data[:len(data) // 3])
    elif damage == "zero bytes":
        entry.write_bytes(b"")
    elif damage == "foreign":           # another model's entry of the same kind
        (foreign,) = _entries(pristine[other][0], pattern)
        entry.write_bytes(foreign.read_bytes())
    else:
        entry.write_bytes(data.replace(b"1", b"2", 3) if entry.suffix == ".py"
                          else data[:-64] + bytes(64))
    again = _probe(cache, n)
    assert again[:4] == first[:4]
    from mechsim.codegen.cache import verified_file
    assert verified_file(entry)


@needs_compiler
def test_concurrent_builds_of_one_model_are_safe(tmp_path):
    cache = seeded_cache(tmp_path / "cache")
    env = {**os.environ, "MECHSIM_CACHE_DIR": str(cache)}
    procs = [subprocess.Popen([sys.executable, "-c", _PROBE.format(n=3)], env=env,
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
             for _ in range(3)]
    outs = [p.communicate(timeout=600) for p in procs]
    assert all(p.returncode == 0 for p in procs), [o[1][-300:] for o in outs]
    results = [o[0].split() for o in outs]
    assert all(r[0] == "success" and float(r[1]) < 1e-6 for r in results)
    from mechsim.codegen.cache import verified_file
    entries = [p for p in cache.iterdir() if p.suffix in (".py", ".so")]
    assert entries and all(verified_file(p) for p in entries)
    assert not list(cache.glob("*.tmp"))


def test_a_cache_others_can_write_is_not_used(tmp_path):
    cache = tmp_path / "shared"
    cache.mkdir()
    cache.chmod(0o777)
    status, err, _, _, stderr = _probe(cache)
    assert status == "success" and err < 1e-6
    assert "writable by other users" in stderr and not list(cache.iterdir())


@needs_compiler
def test_a_failed_compiler_is_remembered_and_said_once(tmp_path):
    log = tmp_path / "calls"
    cc = tmp_path / "cc"
    cc.write_text(f"#!/bin/sh\necho called >> {log}\necho 'fatal: no licence' >&2\nexit 1\n")
    cc.chmod(0o755)
    cache = seeded_cache(tmp_path / "cache")
    first = _probe(cache, CC=str(cc))
    assert first[0] == "success" and first[1] < 1e-6 and not first[3]
    assert first[4].count("fatal: no licence") == 1          # one warning, naming the error
    assert str(cc) in first[4]
    calls = log.read_text().count("called")
    second = _probe(cache, CC=str(cc))
    assert second[0] == "success" and log.read_text().count("called") == calls
    assert second[4].count("fatal: no licence") == 1
    # A working compiler is tried again.
    third = _probe(cache)
    assert third[3]


def test_a_compile_that_ran_out_of_disk_is_tried_again_and_leftovers_go(tmp_path):
    """A compile that failed for want of disk (the compiler says 'No space left on device')
    is not remembered in *.failed: once space is freed the next process compiles (before,
    the compiled engine stayed off). The working directory of a compile killed mid-way
    (its process gone) is removed by the next compile (before, it stayed forever)."""
    log = tmp_path / "calls"
    cc = tmp_path / "cc"
    cc.write_text(f"#!/bin/sh\necho called >> {log}\n"
                  "echo 'model.so: No space left on device' >&2\nexit 1\n")
    cc.chmod(0o755)
    cache = seeded_cache(tmp_path / "cache")
    first = _probe(cache, CC=str(cc))
    assert first[0] == "success" and not first[3] and "tried again" in first[4]
    assert not list(cache.glob("*.failed"))
    stale = cache / "mechsim-build-999999999-abc"
    stale.mkdir()
    (stale / "model.c").write_text("half")
    calls = log.read_text().count("called")
    _probe(cache, CC=str(cc))
    assert log.read_text().count("called") > calls
    assert not stale.exists()
    if _compiler_serves():
        assert _probe(cache)[3]                       # space back: compiled


@pytest.mark.parametrize("value, on", [("0", False), ("false", False), (" Off ", False),
                                       ("", False), ("1", True), ("yes", True), ("TRUE", True)])
def test_mechsim_no_compile_reads_as_a_switch(monkeypatch, value, on):
    from mechsim.codegen.cache import env_flag
    monkeypatch.setenv("MECHSIM_NO_COMPILE", value)
    assert env_flag("MECHSIM_NO_COMPILE") is on


@pytest.mark.parametrize("value, compiled", [("false", True), ("yes", False)])
def test_a_new_process_compiles_as_mechsim_no_compile_says(tmp_path, value, compiled):
    """The switch end to end, one value each way (how each value reads: above)."""
    if compiled and not _compiler_serves():
        pytest.skip("no working C compiler")
    status, _, _, engine, _ = _probe(seeded_cache(tmp_path / "cache"), MECHSIM_NO_COMPILE=value)
    assert status == "success" and engine is compiled


def test_compilation_says_why_not():
    c = ms.examples.flexible_four_bar().compilation()
    assert not c.serves and "flexible" in c.reason


# --- fuzzing the parsers -----------------------------------------------------------------------
@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.text(max_size=200))
def test_the_expression_parser_refuses_anything_but_arithmetic(text):
    try:
        e = parse(text, {"t"}, "driver 'fuzz'")
    except ExpressionError as exc:
        assert str(exc).startswith("driver 'fuzz'")
        return
    e.to_sympy({"t": __import__("sympy").Symbol("t")})
    try:
        assert isinstance(e.value(t=0.3), float)
    except (ArithmeticError, ValueError):
        pass


@pytest.mark.parametrize("text", [
    "sin(t) + cos(2*t)*tan(t/3)", "asin(t/4) - acos(t/5) + atan(t)",
    "atan2(t, 1 - t) + hypot(t, 2)", "sinh(t)/cosh(t) - tanh(t)",
    "exp(-t)*log(1 + t)*sqrt(t)", "abs(t - 1)**1.5 + radians(30*t) - degrees(t)/100",
    "step(t, 0.5, 0, 2, 3*pi)", "-t**3 + 2**t - e*pi + 7"])
def test_an_expression_over_an_array_has_its_value_at_each_point(text):
    """`Expression.values` (numpy, what a kinematic analysis scans a driver's law with)
    against `value` point by point, every function once; NaN, not an error, where the
    expression is undefined, and a driver's `values_at` there takes `value`'s error."""
    e = parse(text, {"t"}, "driver 'x'")
    ts = np.linspace(0.0, 3.0, 301)
    np.testing.assert_allclose(e.values(t=ts), [e.value(t=t) for t in ts], rtol=1e-14,
                               atol=1e-14)
    assert e.values(t=np.array(1.25)).shape == ()
    undefined = parse("log(t - 1)", {"t"}, "driver 'x'")
    got = undefined.values(t=ts)
    assert np.all(np.isnan(got[ts < 1.0])) and np.isfinite(got[ts > 1.0]).all()
    mech = ms.examples.four_bar()
    driver = mech.add(ms.Driver(mech.joints[0], "log(t - 1)", name="motor"))
    with pytest.raises(ValueError, match="math domain error"):
        driver.values_at(ts)
    assert driver.values_at(ts[ts > 1.0]) == pytest.approx(got[ts > 1.0], rel=1e-14)


ATOMS = st.sampled_from(["t", "pi", "e", "1", "2.5", "1e3", "0", "-", "+", "*", "/", "**", "(",
                         ")", "sin(", "exp(", "log(", "sqrt(", "abs(", "atan2(", ",", " ", "^",
                         "9", "99", "x", "__", ".", "[", "]", "lambda", "'", "%", "1e308"])


@settings(max_examples=400, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(ATOMS, max_size=40).map("".join))
def test_arithmetic_like_expressions_parse_or_are_refused_without_hanging(text):
    """Anything is either refused with an ExpressionError or parsed; a parsed expression
    has the same value at t = 0.3 by its own evaluation as through sympy, where finite."""
    import sympy
    try:
        e = parse(text, {"t"}, "driver 'fuzz'")
    except ExpressionError:
        return
    t = sympy.Symbol("t")
    through_sympy = e.to_sympy({"t": t})
    try:
        own = e.value(t=0.3)
    except (ArithmeticError, ValueError):
        return                         # undefined there (log of a negative, 1/0, overflow)
    try:
        other = complex(sympy.N(through_sympy.subs(t, sympy.Rational(3, 10)), 30))
    except TypeError:
        return                         # sympy's value is complex infinity or undefined there
    if math.isfinite(own) and cmath.isfinite(other) and abs(other.imag) <= 1e-9 * max(1.0, abs(other)):
        assert other.real == pytest.approx(own, rel=1e-9, abs=1e-12), (text, own, other)


def _toml(value):
    """A value as TOML (inline tables and arrays; test data only)."""
    import json
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (int, float)):
        return repr(value) if not isinstance(value, float) or math.isfinite(value) else \
            ("nan" if math.isnan(value) else ("inf" if value > 0 else "-inf"))
    if isinstance(value, str):
        return json.dumps(value)
    if isinstance(value, list):
        return "[" + ", ".join(_toml(v) for v in value) + "]"
    return "{" + ", ".join(f"{json.dumps(k)} = {_toml(v)}" for k, v in value.items()) + "}"


VALUES = st.recursive(
    st.none().map(lambda _: 0) | st.booleans() | st.integers(-10**6, 10**6)
    | st.floats(allow_nan=True, allow_infinity=True) | st.text(max_size=20)
    | st.sampled_from(["ground", "crank", "A", "t", "2*L", "revolute", "prismatic", "energy"]),
    lambda children: st.lists(children, max_size=4)
    | st.dictionaries(st.sampled_from(["name", "mass", "rod", "at", "bodies", "type", "joint",
                                       "expression", "t_end", "plots"]), children, max_size=4),
    max_leaves=12)
KEYS = st.sampled_from(["name", "gravity", "parameters", "simulation", "output", "body", "joint",
                        "driver", "spring", "force", "torque", "bodies", "x"])


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow,
                                                                  HealthCheck.function_scoped_fixture])
@given(st.dictionaries(KEYS, VALUES, max_size=6))
def test_any_scene_is_loaded_or_refused_by_a_scene_error(tmp_path, data):
    text = "\n".join(f"{k} = {_toml(v)}" for k, v in data.items())
    path = tmp_path / "fuzz.toml"
    path.write_text(text)
    try:
        ms.load_scene(path)
    except SceneError as exc:
        assert str(exc).startswith("fuzz.toml") or "fuzz.toml" in str(exc)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow,
                                                                  HealthCheck.function_scoped_fixture])
@given(st.integers(0, 10**6), VALUES)
def test_a_valid_scene_with_one_value_changed_is_loaded_or_refused_naming_where(tmp_path, k,
                                                                                 value):
    import tomllib
    data = tomllib.loads(FOUR_BAR)
    slots = [(data, key) for key in data]
    for key in ("body", "joint"):
        slots += [(t, kk) for t in data[key] for kk in t]
    for key in ("simulation", "output", "parameters"):
        slots += [(data[key], kk) for kk in data[key]]
    table, key = slots[k % len(slots)]
    table[key] = value
    text = "\n".join(f"{kk} = {_toml(v)}" for kk, v in data.items())
    path = tmp_path / "fuzz.toml"
    path.write_text(text)
    try:
        ms.load_scene(path)
    except SceneError as exc:
        assert "fuzz.toml" in str(exc)
