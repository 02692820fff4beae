"""Synthesis on exact gradients (`ms.optimize`, `ms.PathPoints`): a four-bar's coupler
path through twelve timed points recovered from a design 7–8 % off, the objective's
gradient against central differences, and bad arguments refused before any evaluation."""

import importlib.util
import pathlib

import numpy as np
import pytest

import mechsim as ms

ROOT = pathlib.Path(__file__).resolve().parents[1]
spec = importlib.util.spec_from_file_location("path_synthesis",
                                              ROOT / "examples" / "path_synthesis.py")
synthesis = importlib.util.module_from_spec(spec)
spec.loader.exec_module(synthesis)


def test_path_synthesis_recovers_the_linkage_that_drew_the_points():
    design, _ = synthesis.synthesize("exact")
    assert design.success
    assert np.sqrt(design.value) < 1e-6                    # rms distance [m]
    for name, value in synthesis.TRUE.items():
        assert design.parameters[name] == pytest.approx(value, rel=1e-4), name


def test_the_path_objective_s_gradient_is_exact():
    """∂(mean squared distance)/∂k of PathPoints against central differences of rebuilt
    mechanisms, extrapolated (Richardson: (4 D(h/2) − D(h))/3, error O(h⁴)), at a design
    away from the optimum (every component non-zero)."""
    values = synthesis.start()
    targets = synthesis.targets()
    objective = ms.PathPoints("coupler", (0.0, 0.0), targets, "motor", synthesis.ANGLES)
    mech = synthesis.path_four_bar(**{k: ms.Parameter(k, v) for k, v in values.items()})
    names = list(values)
    value, grad = objective(mech, names)
    assert value == pytest.approx(objective(synthesis.path_four_bar(**values), [])[0],
                                  rel=1e-12)
    def central(name, h):
        up = objective(synthesis.path_four_bar(**{**values, name: values[name] + h}), [])[0]
        down = objective(synthesis.path_four_bar(**{**values, name: values[name] - h}), [])[0]
        return (up - down) / (2 * h)

    for j, name in enumerate(names):
        h = 1e-4 * max(1.0, abs(values[name]))
        fd = (4 * central(name, h / 2) - central(name, h)) / 3
        assert grad[j] == pytest.approx(fd, rel=1e-6, abs=1e-9 * value), name


def test_optimize_refuses_bad_arguments_before_any_evaluation():
    mech = synthesis.path_four_bar(**{k: ms.Parameter(k, v) for k, v in synthesis.TRUE.items()})

    def never(mech, names):
        raise AssertionError("evaluated")

    with pytest.raises(ValueError, match="names 'e', which is no Parameter"):
        ms.optimize(mech, never, ["a", "e"])
    with pytest.raises(ValueError, match="the bounds of 'a' must have low < high"):
        ms.optimize(mech, never, ["a"], bounds={"a": (0.2, 0.1)})
    with pytest.raises(ValueError, match="one \\(low, high\\) per parameter"):
        ms.optimize(mech, never, ["a", "b"], bounds=[(0.0, 1.0)])
    with pytest.raises(ValueError, match="`gradient` must be"):
        ms.optimize(mech, never, ["a"], gradient="adjoint")
    with pytest.raises(ValueError, match="PathPoints: `targets` must be 3 points"):
        ms.PathPoints("coupler", (0.0, 0.0), np.zeros((2, 2)), "motor", [0.0, 1.0, 2.0])


def test_designs_that_cannot_be_evaluated_are_counted_not_fatal():
    """An objective that cannot be evaluated beyond a crank of 0.2 m (as a linkage that
    no longer assembles) while its minimum lies at 0.3 m: those trial designs are given a
    value above every one seen and counted with their messages, and the search ends on a
    design that was evaluated, the mechanism set to it."""
    mech = synthesis.path_four_bar(**{k: ms.Parameter(k, v) for k, v in synthesis.TRUE.items()})

    def objective(mech, names):
        a = mech.parameter_values()["a"]
        if a > 0.2:
            raise ms.design.DesignError(f"no assembly at a = {a:.3f}")
        return (a - 0.3) ** 2, np.array([2 * (a - 0.3)] if names else [])

    design = ms.optimize(mech, objective, ["a"], bounds={"a": (0.05, 0.5)})
    assert design.failures > 0
    assert design.failure_messages[0].startswith("no assembly at a = ")
    assert design.parameters["a"] <= 0.2
    assert design.value == pytest.approx((design.parameters["a"] - 0.3) ** 2, rel=1e-12)
    assert mech.parameter_values()["a"] == design.parameters["a"]


spec_cw = importlib.util.spec_from_file_location("counterweight",
                                                 ROOT / "examples" / "counterweight.py")
counterweight = importlib.util.module_from_spec(spec_cw)
spec_cw.loader.exec_module(counterweight)


def _richardson(f, x, h):
    """(4 D(h/2) − D(h))/3 of the central difference D of f at x: error O(h⁴)."""
    def central(step):
        return (f(x + step) - f(x - step)) / (2 * step)
    return (4 * central(h / 2) - central(h)) / 3


def test_the_torque_norm_s_gradient_is_exact():
    """EffortNorm's gradient (the motor torque's sensitivities to a counterweight's mass
    and radius and the guide's offset) against extrapolated central differences."""
    objective = counterweight.objective()
    values = {"m_cw": 1.0, "r_cw": 0.05, "e": 0.01}
    mech = counterweight.pump(**{k: ms.Parameter(k, v) for k, v in values.items()})
    value, grad = objective(mech, list(values))
    for j, name in enumerate(values):
        fd = _richardson(lambda x: objective(counterweight.pump(**{**values, name: x}), [])[0],
                         values[name], 1e-3)
        assert grad[j] == pytest.approx(fd, rel=1e-6, abs=1e-9 * value), name


@pytest.fixture(scope="module")
def sized():
    """The example's counterweight sized on exact gradients (design, history, mechanism),
    once for the tests that compare with it."""
    return counterweight.size("exact")


# (one worker sizes the counterweight for all of them)
@pytest.mark.xdist_group("counterweight")
def test_a_counterweight_sized_on_exact_gradients_flattens_the_torque(sized):
    """From a 1 kg counterweight at 5 cm, the search ends where the objective's slope in
    each parameter off its bound vanishes (checked by differences, independently of the
    gradients it used), and the peak torque over a turn falls from 9.0 to under 1.5 N·m."""
    design, _, mech = sized
    assert design.success
    objective = counterweight.objective()
    for name, (low, high) in counterweight.BOUNDS.items():
        x = design.parameters[name]
        if low + 1e-6 < x < high - 1e-6:
            slope = _richardson(lambda y: objective(counterweight.pump(
                **{**design.parameters, name: y}), [])[0], x, 1e-4)
            assert abs(slope) * max(abs(x), 0.05) < 1e-5 * design.value, name
    assert counterweight.peak(counterweight.pump(**counterweight.START)) > 9.0
    assert counterweight.peak(mech) < 1.5


# --- design files and `mechsim optimize` ----------------------------------------------------
def _design_file(tmp_path, **changes):
    """The pump's design file, copied beside a copy of its scene, with `changes` to its
    tables (None removes one)."""
    import shutil
    import tomllib
    scene = tmp_path / "pump.toml"
    shutil.copy(ROOT / "mechanisms" / "pump.toml", scene)
    with open(ROOT / "mechanisms" / "studies" / "pump_counterweight.toml", "rb") as fh:
        data = tomllib.load(fh)
    data["scene"] = "pump.toml"
    data.update(changes)
    data = {k: v for k, v in data.items() if v is not None}

    def text(value):
        if isinstance(value, dict):
            return "{ " + ", ".join(f"{k} = {text(v)}" for k, v in value.items()) + " }"
        if isinstance(value, list):
            return "[" + ", ".join(text(v) for v in value) + "]"
        return repr(value) if not isinstance(value, str) else f'"{value}"'

    lines = [f"{k} = {text(v)}" for k, v in data.items()
             if not isinstance(v, (dict, list))]
    for key, table in data.items():
        if isinstance(table, dict):
            lines += [f"[{key}]"] + [f"{k} = {text(v)}" for k, v in table.items()]
        elif isinstance(table, list):
            for entry in table:
                lines += [f"[[{key}]]"] + [f"{k} = {text(v)}" for k, v in entry.items()]
    path = tmp_path / "design.toml"
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.mark.xdist_group("counterweight")
def test_mechsim_optimize_finds_the_design_the_python_interface_finds(tmp_path, monkeypatch,
                                                                      sized):
    """`mechsim optimize` on the pump scene (its numbers written as scene parameters and
    expressions) and `ms.optimize` on the example's Python model (the same pump) reach
    the same counterweight, and the design file written holds it."""
    import tomllib
    from mechsim.app.cli import main
    monkeypatch.chdir(tmp_path)
    assert main(["optimize", str(_design_file(tmp_path)), "--quiet"]) == 0
    with open(tmp_path / "out" / "pump_counterweight.toml", "rb") as fh:
        written = tomllib.load(fh)
    design, _, _ = sized
    assert written["parameters"]["m_cw"] == pytest.approx(design.parameters["m_cw"], rel=1e-5)
    assert written["parameters"]["r_cw"] == pytest.approx(design.parameters["r_cw"], rel=1e-5)
    assert abs(written["parameters"]["offset"] - design.parameters["e"]) < 1e-7
    assert written["value"] == pytest.approx(design.value, rel=1e-8)


@pytest.mark.parametrize("changes, message", [
    (dict(parameters={"mass": [0.0, 1.0]}), "'mass' is not one of the scene's"),
    (dict(parameters={"m_cw": [2.0, 1.0]}), "expected \\[low, high\\] with low < high"),
    (dict(parameters={"m_arm": [0.0, 9.0]}), "a varied parameter must be a number there"),
    (dict(objective={"peak_effort": "pump"}), "no driver 'pump'"),
    (dict(objective={"fastest": "motor"}), "\\[objective\\] must give one of"),
    (dict(analysis={"over": {"driver": "motor", "degrees": [0, 360, 0]}}), "a step > 0"),
    (dict(analysis=None), "\\[analysis\\] must give"),
    (dict(gradient="adjoint"), "`gradient` must be"),
    (dict(method="newton"), "`method` must be one of"),
    (dict(method="least_squares"), "'least_squares' takes a path objective"),
    (dict(constraint=[{"transmission_angle": {"bodies": ["rod", "arm"], "minimum": 60.0}}]),
     "`bodies` must name two of the scene's bodies"),
    (dict(constraint=[{"transmission_angle": {"bodies": ["rod", "plunger"], "minimum": 95}}]),
     "`minimum` must be degrees between 0 and 90"),
    (dict(constraint=[{"pressure_angle": 30.0}]), "expected transmission_angle"),
    (dict(objective={"peak_joint_force": "bearing"}), "no joint 'bearing'; joints: main"),
    (dict(constraint=[{"grashof_crank": {"links": ["r_cw", 0.3, 0.2]}}]),
     "expected grashof_crank = { links"),
    (dict(constraint=[{"grashof_crank": {"links": ["crank", 0.3, 0.2, 0.4]}}]),
     "'crank' is not one of the scene's \\[parameters\\]"),
    (dict(constraint=[{"grashof_crank": {"links": [0.1, 0.3, 0.2, 0.4], "margin": -1}}]),
     "`margin` must be a length"),
])
def test_a_design_file_s_mistakes_are_named_before_any_evaluation(tmp_path, monkeypatch,
                                                                   capsys, changes, message):
    import re
    from mechsim.app.cli import main
    monkeypatch.chdir(tmp_path)
    assert main(["optimize", str(_design_file(tmp_path, **changes))]) == 2
    assert re.search(message, capsys.readouterr().err)
    assert not (tmp_path / "out").exists()


TURN = ("motor", np.radians(np.arange(0.0, 361.0, 5.0)))


def test_the_transmission_angle_s_jacobian_is_exact():
    values = synthesis.start()
    constraint = ms.TransmissionAngle("coupler", "rocker", 45.0, over=TURN)
    mech = synthesis.path_four_bar(**{k: ms.Parameter(k, v) for k, v in values.items()})
    names = list(values)
    g, jac = constraint(mech, names)
    assert jac.shape == (len(TURN[1]), len(names))
    for j, name in enumerate(names):
        fd = _richardson(lambda x: constraint(synthesis.path_four_bar(**{**values, name: x}),
                                              [])[0], values[name], 1e-4)
        np.testing.assert_allclose(jac[:, j], fd, rtol=1e-6, atol=1e-8, err_msg=name)


def test_path_synthesis_kept_off_poor_transmission():
    """The linkage that drew the points transmits at 41.4° at worst; asked for 45°, the
    search ends on a feasible design (every sample at 45° or more) that misses the points
    by a few millimetres, the same design whether the gradients are exact or scipy's
    differences (an independent check of where it ends)."""
    def run(gradient):
        parameters = {k: ms.Parameter(k, v) for k, v in synthesis.start().items()}
        mech = synthesis.path_four_bar(**parameters)
        objective = ms.PathPoints("coupler", (0.0, 0.0), synthesis.targets(), "motor",
                                  synthesis.ANGLES)
        constraint = ms.TransmissionAngle("coupler", "rocker", 45.0, over=TURN)
        design = ms.optimize(mech, objective, list(parameters), constraints=[constraint],
                             gradient=gradient)
        return design, constraint(mech, [])[0]

    known = synthesis.path_four_bar(**synthesis.TRUE)
    mu = np.diff(known.kinematics(over=TURN).q[:, [known.coordinate_names.index(
        f"{b}.angle") for b in ("coupler", "rocker")]], axis=1)[:, 0]
    assert np.degrees(np.arcsin(np.abs(np.sin(mu)))).min() < 42.0
    exact, margins = run("exact")
    assert exact.success and margins.min() > -1e-8
    assert 1e-4 < np.sqrt(exact.value) < 1e-2
    differences, _ = run("2-point")
    assert exact.value == pytest.approx(differences.value, rel=1e-5)


def test_a_multistart_spreads_its_searches_and_keeps_the_best():
    """Two starts over ±20 % of the drawing linkage (a Latin hypercube), searched in two
    processes: a row per start, every search converged, the best one the linkage that drew
    the points, and no row better than the best."""
    objective = ms.PathPoints("coupler", (0.0, 0.0), synthesis.targets(), "motor",
                              synthesis.ANGLES)
    bounds = {k: (0.8 * v, 1.2 * v) for k, v in synthesis.TRUE.items()}
    found = ms.multistart(synthesis.path_four_bar, objective, bounds, starts=2, seed=1,
                          workers=2, tol=1e-14)
    table = found.study.table
    assert len(found.study) == 2 and list(table["status"]) == ["success"] * 2
    starts = np.column_stack([table[k] for k in bounds])
    assert len({tuple(row) for row in starts.round(12)}) == 2
    for j, (low, high) in enumerate(bounds.values()):
        assert np.all((low <= starts[:, j]) & (starts[:, j] <= high))
    assert found.best.value == table["value"].min() < 1e-12
    for name, value in synthesis.TRUE.items():
        assert found.best.parameters[name] == pytest.approx(value, rel=1e-4)
    with pytest.raises(ValueError, match="every parameter needs finite bounds"):
        ms.multistart(synthesis.path_four_bar, objective, {"a": (None, 1.0)})
    with pytest.raises(ValueError, match="`starts` must be a count"):
        ms.multistart(synthesis.path_four_bar, objective, bounds, starts=0)


@pytest.mark.xdist_group("counterweight")
def test_a_design_file_s_constraint_holds_at_the_design(tmp_path, monkeypatch, sized):
    """[[constraint]] transmission_angle between the pump's rod and plunger (at least 65°:
    the offset may not tilt the rod far): the design found keeps it at every sample of
    the analysis, and reaches the unconstrained design's torque (the constraint does not
    bind there)."""
    import tomllib
    from mechsim.app.cli import main
    monkeypatch.chdir(tmp_path)
    path = _design_file(tmp_path, constraint=[
        {"transmission_angle": {"bodies": ["rod", "plunger"], "minimum": 65.0}}])
    assert main(["optimize", str(path), "--quiet"]) == 0
    with open(tmp_path / "out" / "pump_counterweight.toml", "rb") as fh:
        written = tomllib.load(fh)
    mech = ms.load_scene(tmp_path / "pump.toml", parameters=written["parameters"]).mechanism
    kin = mech.kinematics(over=("motor", np.radians(np.arange(0.0, 361.0, 2.0))))
    mu = kin.coordinate("plunger.angle") - kin.coordinate("rod.angle")
    assert np.degrees(np.arcsin(np.abs(np.sin(mu)))).min() >= 65.0 - 1e-6
    design, _, _ = sized
    assert written["value"] == pytest.approx(design.value, rel=1e-6)


def test_free_timing_s_gradient_is_exact():
    """With free timing the driver's advances between the points are the objective's own
    variables: their derivatives (the point's velocity over the driver's rate, summed
    over the later points) against central differences of the objective."""
    values = synthesis.start()
    targets = synthesis.targets()[:6]
    angles = synthesis.ANGLES[:6] * 1.1
    mech = synthesis.path_four_bar(**{k: ms.Parameter(k, v) for k, v in values.items()})
    names = list(values)
    objective = ms.PathPoints("coupler", (0.0, 0.0), targets, "motor", angles,
                              free_timing=True)
    assert objective.variables == [f"advance {i}" for i in range(1, 6)]
    advances = objective.variable_values()
    value, grad = objective(mech, names)
    assert len(grad) == len(names) + 5

    def at(x):
        objective.set_variables(x)
        return objective(mech, [])[0]

    for j in range(5):
        h = 1e-5
        up, down = advances.copy(), advances.copy()
        up[j] += h
        down[j] -= h
        fd = (at(up) - at(down)) / (2 * h)
        assert grad[len(names) + j] == pytest.approx(fd, rel=1e-6, abs=1e-9 * value), j
    objective.set_variables(advances)
    with pytest.raises(ValueError, match="increasing or decreasing"):
        ms.PathPoints("coupler", (0.0, 0.0), targets[:3], "motor", [0.0, 0.5, 0.2],
                      free_timing=True)


def test_path_synthesis_without_prescribed_timing_finds_the_points():
    """Six points of the known linkage's path, the timing not given (the search starts
    from equal advances 10 % longer than the known ones, and the coupler's numbers 7–8 %
    off): the design found passes through them, and `Design.variables` holds the
    advances."""
    targets = synthesis.targets()[:6]
    known = np.diff(synthesis.ANGLES[:6])
    guess = np.concatenate([[0.0], np.cumsum(known * 1.1)])
    start = {**synthesis.TRUE, **{k: v for k, v in synthesis.start().items()
                                  if k in ("b", "px", "py")}}
    mech = synthesis.path_four_bar(**{k: ms.Parameter(k, v) for k, v in start.items()})
    objective = ms.PathPoints("coupler", (0.0, 0.0), targets, "motor", guess,
                              free_timing=True)
    design = ms.optimize(mech, objective, ["b", "px", "py"], tol=1e-16)
    assert np.sqrt(design.value) < 1e-6, design.message
    assert sorted(design.variables) == [f"advance {i}" for i in range(1, 6)]
    got = mech.kinematics(over=("motor", objective.values)).point("coupler", (0.0, 0.0))
    assert np.max(np.hypot(*(got - targets).T)) < 1e-5


def rocker_turns(values, angles):
    """The rocker's turns from the first point at the crank's `angles`."""
    kin = synthesis.path_four_bar(**values).kinematics(over=("motor", angles))
    psi = kin.q[:, kin.coordinate_names.index("rocker.angle")]
    return psi - psi[0]


def test_function_generation_s_gradient_is_exact_and_it_finds_the_linkage():
    """FunctionPoints: the rocker's turns against the crank's. Its gradient against
    Richardson-extrapolated central differences, and the crank-rocker whose turns they
    are found again from links 5–8 % off (the ground link fixed: angles do not scale)."""
    angles = synthesis.ANGLES[:7]
    targets = rocker_turns(synthesis.TRUE, angles)
    objective = ms.FunctionPoints("ground", "rocker", targets, "motor", angles)
    values = {**synthesis.TRUE, "a": 0.106, "b": 0.28, "c": 0.27}
    mech = synthesis.path_four_bar(**{k: ms.Parameter(k, v) for k, v in values.items()})
    names = ["a", "b", "c"]
    value, grad = objective(mech, names)
    assert value > 1e-4

    def central(name, h):
        up = objective(synthesis.path_four_bar(**{**values, name: values[name] + h}), [])[0]
        down = objective(synthesis.path_four_bar(**{**values, name: values[name] - h}), [])[0]
        return (up - down) / (2 * h)

    for j, name in enumerate(names):
        fd = (4 * central(name, 5e-5) - central(name, 1e-4)) / 3
        assert grad[j] == pytest.approx(fd, rel=1e-6), name
    design = ms.optimize(mech, objective, names, tol=1e-16)
    assert np.sqrt(design.value) < 1e-7                     # rad
    for name in names:
        assert design.parameters[name] == pytest.approx(synthesis.TRUE[name], rel=1e-5)


def test_motion_generation_adds_the_body_s_angle_with_exact_derivatives():
    """PathPoints with `angles`: the coupler's angle errors weigh in (one radian as
    `length` metres); the gradient against central differences, timing free too."""
    angles = synthesis.ANGLES[:5]
    known = synthesis.path_four_bar(**synthesis.TRUE).kinematics(over=("motor", angles))
    poses = known.q[:, known.coordinate_names.index("coupler.angle")]
    values = synthesis.start()
    objective = ms.PathPoints("coupler", (0.0, 0.0), synthesis.targets()[:5], "motor",
                              angles * 1.05, free_timing=True, angles=poses, length=0.2)
    mech = synthesis.path_four_bar(**{k: ms.Parameter(k, v) for k, v in values.items()})
    names = list(values)
    value, grad = objective(mech, names)
    plain = ms.PathPoints("coupler", (0.0, 0.0), synthesis.targets()[:5], "motor",
                          angles * 1.05)(mech, [])[0]
    assert value > plain

    def at(name=None, h=0.0, advance=None):
        if advance is not None:
            x = objective.variable_values().copy()
            x[advance] += h
            objective.set_variables(x)
            out = objective(mech, [])[0]
            x[advance] -= h
            objective.set_variables(x)
            return out
        return objective(synthesis.path_four_bar(**{**values, name: values[name] + h}),
                         [])[0]

    for j, name in enumerate(names):
        h = 1e-5 * max(1.0, abs(values[name]))
        fd = (at(name, h) - at(name, -h)) / (2 * h)
        assert grad[j] == pytest.approx(fd, rel=1e-5, abs=1e-9 * value), name
    for j in range(4):
        fd = (at(h=1e-6, advance=j) - at(h=-1e-6, advance=j)) / 2e-6
        assert grad[len(names) + j] == pytest.approx(fd, rel=1e-5, abs=1e-9 * value), j


@pytest.mark.parametrize("joint, p", [("O", 16.0), ("A", 2.0), ("guide", 16.0)])
def test_the_joint_force_norm_s_gradient_is_exact(joint, p):
    """JointForceNorm's gradient (the pin loads' sensitivities to the counterweight's mass
    and radius and the guide's offset) against extrapolated central differences: the
    crank's bearing, the crank pin and the plunger's guide."""
    objective = ms.JointForceNorm(joint, p=p, over=("motor", np.radians(
        np.arange(0.0, 361.0, 4.0))))
    values = {"m_cw": 1.0, "r_cw": 0.05, "e": 0.01}
    mech = counterweight.pump(**{k: ms.Parameter(k, v) for k, v in values.items()})
    value, grad = objective(mech, list(values))
    force = mech.kinematics(over=objective.over).joint_force(joint)
    size = np.hypot(force[:, 0], force[:, 1])
    assert value == pytest.approx(np.mean(size ** p) ** (1 / p), rel=1e-12)
    for j, name in enumerate(values):
        fd = _richardson(lambda x: objective(counterweight.pump(**{**values, name: x}), [])[0],
                         values[name], 1e-3)
        assert grad[j] == pytest.approx(fd, rel=1e-6, abs=1e-9 * value), name


def test_the_grashof_crank_constraint_is_the_grashof_class_and_exact():
    """Feasible exactly where `grashof_class` calls the four-bar a crank-rocker (600
    random sets of lengths, an independent classification), linear in the lengths with
    the jacobian on the named Parameters; a name that is no Parameter is refused by
    optimize before any evaluation."""
    class Lengths:                 # what the constraint reads of a mechanism (most of
        name = "lengths"           # these lengths assemble no four-bar)
        parameters = ["a", "b", "d"]

        def parameter_values(self):
            return self.values

    rng = np.random.default_rng(7)
    lengths = Lengths()
    for a, b, c, d in rng.uniform(0.05, 1.0, size=(600, 4)):
        lengths.values = {"a": a, "b": b, "d": d}
        values, jac = ms.GrashofCrank("a", "b", c, "d")(lengths, ["d", "a"])
        assert bool(np.all(values >= 0.0)) == \
            (ms.examples.grashof_class(a, b, c, d) == "crank-rocker")
        np.testing.assert_array_equal(jac, [[-1.0, -1.0], [1.0, -1.0], [1.0, -1.0]])
    mech = ms.examples.coupler_four_bar(ms.Parameter("a", 0.1), ms.Parameter("b", 0.3),
                                        0.25, ms.Parameter("d", 0.3), 0.1, 0.05, 0.4)
    constraint = ms.GrashofCrank("a", "b", 0.25, "d")
    values, _ = ms.GrashofCrank("a", "b", 0.25, "d", margin=0.01)(mech, [])
    np.testing.assert_allclose(values, [0.14, 0.24, 0.14], atol=1e-15)
    objective = ms.PathPoints("coupler", (0.0, 0.0), synthesis.targets(), "motor",
                              synthesis.ANGLES)
    with pytest.raises(ValueError, match="GrashofCrank: 'c' is no Parameter"):
        ms.optimize(mech, objective, ["a"], constraints=[ms.GrashofCrank("a", "b", "c", "d")])
    with pytest.raises(ValueError, match="the rocker must be a Parameter's name or a length"):
        ms.GrashofCrank("a", "b", None, "d")
    assert constraint(mech, ["a"])[1].shape == (3, 1)


def test_a_design_file_s_pin_load_objective_is_the_python_one(tmp_path, monkeypatch):
    """[objective] peak_joint_force on the pump's main bearing (its 16-norm mean over a
    turn) through `mechsim optimize` and `ms.JointForceNorm` on the example's Python model
    reach the same counterweight; the bearing's peak load falls from the start's."""
    import tomllib
    from mechsim.app.cli import main
    monkeypatch.chdir(tmp_path)
    path = _design_file(tmp_path, objective={"peak_joint_force": "main bearing"})
    assert main(["optimize", str(path), "--quiet"]) == 0
    with open(tmp_path / "out" / "pump_counterweight.toml", "rb") as fh:
        written = tomllib.load(fh)
    objective = ms.JointForceNorm("O", p=16.0, over=("motor", np.radians(
        np.arange(0.0, 361.0, 2.0))))
    start = counterweight.START
    mech = counterweight.pump(**{k: ms.Parameter(k, v) for k, v in start.items()})
    before = objective(mech, [])[0]
    design = ms.optimize(mech, objective, list(start), bounds=counterweight.BOUNDS)
    assert written["value"] == pytest.approx(design.value, rel=1e-6)
    assert written["parameters"]["m_cw"] == pytest.approx(design.parameters["m_cw"], rel=1e-4)
    assert design.value < 0.9 * before


def test_a_design_file_s_path_is_searched_by_least_squares(tmp_path, monkeypatch):
    """`method = "least_squares"` with a path objective: the plunger's positions over a
    turn drawn with the guide 20 mm off the crank's pivot, the search from the scene's
    offset 0 finds it again."""
    import tomllib
    from mechsim.app.cli import main
    from mechsim.app.scene import load_scene
    monkeypatch.chdir(tmp_path)
    path = _design_file(tmp_path, parameters={"offset": [-0.06, 0.06]},
                        analysis={"over": {"driver": "motor", "degrees": [0, 360, 30]}},
                        method="least_squares", objective=None)
    drawn = load_scene(tmp_path / "pump.toml", {"offset": ms.Parameter("offset", 0.02)})
    targets = drawn.mechanism.kinematics(over=("motor", np.radians(np.arange(0, 361, 30)))) \
        .point("plunger", (0.0, 0.0))
    rows = ", ".join(f"[{float(x)!r}, {float(y)!r}]" for x, y in targets)
    path.write_text(path.read_text() + "[objective]\npath = { body = \"plunger\", "
                    f"point = [0.0, 0.0], targets = [{rows}] }}\n")
    assert main(["optimize", str(path), "--quiet"]) == 0
    with open(tmp_path / "out" / "pump_counterweight.toml", "rb") as fh:
        written = tomllib.load(fh)
    # (scipy's default tolerances: steps of 1e-8 relative)
    assert written["parameters"]["offset"] == pytest.approx(0.02, abs=1e-8)
    assert written["value"] < 1e-14                     # m²: the plunger within 0.1 µm
