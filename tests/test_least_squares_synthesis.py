"""Precision-point synthesis as least squares: the objectives' residuals and their exact
Jacobians, `optimize(method="least_squares")`, and Alt's nine-point problem
(`examples/nine_point_synthesis.py`)."""

from __future__ import annotations

import importlib.util
import pathlib

import numpy as np
import pytest

import mechsim as ms

HERE = pathlib.Path(__file__).resolve().parent.parent / "examples"


def _example(name):
    spec = importlib.util.spec_from_file_location(name, HERE / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


synthesis = _example("path_synthesis")
nine = _example("nine_point_synthesis")


def test_the_path_residuals_jacobian_is_exact_column_by_column():
    """PathPoints with the body's angles and free timing: each column of J against central
    differences of the residuals (the linkage's numbers and the advances), and r·r is
    the objective's value."""
    angles = synthesis.ANGLES[:5]
    known = synthesis.path_four_bar(**synthesis.TRUE).kinematics(over=("motor", angles))
    poses = known.q[:, known.coordinate_names.index("coupler.angle")] + 0.02
    values = synthesis.start()
    objective = ms.PathPoints("coupler", (0.0, 0.0), synthesis.targets()[:5] + 0.003,
                              "motor", angles * 1.05, free_timing=True, angles=poses,
                              length=0.2)
    mech = synthesis.path_four_bar(**{k: ms.Parameter(k, v) for k, v in values.items()})
    names = list(values)
    r, jac = objective.residuals(mech, names)
    assert jac.shape == (3 * 5, len(names) + 4)
    assert r @ r == pytest.approx(objective(mech, [])[0], rel=1e-14)
    advances = objective.variable_values()

    def residuals(name=None, h=0.0, advance=None):
        if advance is not None:
            x = advances.copy()
            x[advance] += h
            objective.set_variables(x)
            out = objective.residuals(mech, [])[0]
            objective.set_variables(advances)
            return out
        return objective.residuals(
            synthesis.path_four_bar(**{**values, name: values[name] + h}), [])[0]

    for j, name in enumerate(names):
        h = 1e-6 * max(1.0, abs(values[name]))
        fd = (residuals(name, h) - residuals(name, -h)) / (2 * h)
        assert np.allclose(jac[:, j], fd, rtol=1e-6, atol=1e-8 * np.abs(fd).max()), name
    for j in range(4):
        fd = (residuals(h=1e-6, advance=j) - residuals(h=-1e-6, advance=j)) / 2e-6
        column = jac[:, len(names) + j]
        assert np.allclose(column, fd, rtol=1e-6, atol=1e-8 * np.abs(fd).max()), j
        # An advance moves the later points only (rows: the points' x, y, then the angles).
        assert np.all(column[:2 * (j + 1)] == 0.0) and np.all(column[10:11 + j] == 0.0)


def test_the_function_residuals_jacobian_is_exact():
    angles = synthesis.ANGLES[:6]
    kin = synthesis.path_four_bar(**synthesis.TRUE).kinematics(over=("motor", angles))
    psi = kin.q[:, kin.coordinate_names.index("rocker.angle")]
    objective = ms.FunctionPoints("ground", "rocker", psi - psi[0] + 0.01 * angles, "motor",
                                  angles)
    values = {**synthesis.TRUE, "a": 0.106, "c": 0.27}
    mech = synthesis.path_four_bar(**{k: ms.Parameter(k, v) for k, v in values.items()})
    r, jac = objective.residuals(mech, ["a", "c"])
    assert r @ r == pytest.approx(objective(mech, [])[0], rel=1e-14)
    for j, name in enumerate(["a", "c"]):
        up, down = ({**values, name: values[name] + s * 1e-6} for s in (1.0, -1.0))
        fd = (objective.residuals(synthesis.path_four_bar(**up), [])[0] -
              objective.residuals(synthesis.path_four_bar(**down), [])[0]) / 2e-6
        assert np.allclose(jac[:, j], fd, rtol=1e-6, atol=1e-9), name


def test_the_nine_point_linkage_passes_through_the_nine_points():
    """The crank-rocker of the example, analysed by mechsim at its crank's advances,
    passes through Alt's nine points in order: the problem's optimum is exact."""
    mech = nine.linkage(**nine.KNOWN)
    values = np.concatenate([[0.0], np.cumsum(nine.ADVANCES)])
    kin = mech.kinematics(over=("motor", values))
    assert kin.success
    assert np.max(np.abs(kin.point("coupler", (0.0, 0.0)) - nine.POINTS)) < 1e-12
    assert values[-1] < 2 * np.pi                       # all within one turn of the crank


def test_nine_point_synthesis_on_exact_jacobians_reaches_the_exact_linkage():
    """Eighteen unknowns (the linkage's ten numbers and the eight advances), each 5 % off:
    the trust-region search on the exact Jacobian ends on the linkage through the nine
    points, to round-off."""
    design, _ = nine.synthesize("exact", "least_squares")
    assert design.success, design.message
    assert np.sqrt(design.value) < 1e-12                          # m, on a 1.5 m figure
    for name, value in nine.KNOWN.items():
        assert design.parameters[name] == pytest.approx(value, rel=1e-9, abs=1e-12), name
    found = np.array([design.variables[f"advance {i}"] for i in range(1, 9)])
    assert np.allclose(found, nine.ADVANCES, rtol=1e-9)


def test_least_squares_refuses_what_it_cannot_search_before_any_evaluation():
    values = synthesis.start()
    mech = synthesis.path_four_bar(**{k: ms.Parameter(k, v) for k, v in values.items()})
    effort = ms.EffortNorm("motor", over=("motor", synthesis.ANGLES))
    with pytest.raises(ValueError, match="needs an objective with residuals"):
        ms.optimize(mech, effort, ["a"], method="least_squares")
    path = ms.PathPoints("coupler", (0.0, 0.0), synthesis.targets(), "motor",
                         synthesis.ANGLES)
    with pytest.raises(ValueError, match="takes no constraints"):
        ms.optimize(mech, path, ["a"], method="least_squares",
                    constraints=[ms.GrashofCrank("a", "b", "c", "d")])
