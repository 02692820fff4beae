"""A new formulation needs nothing but the base class's contract: the index-1 formulation
written in `Formulation`'s docstring (no stabilization), taken from there as it stands and
registered, runs through the registry's analytic tests."""

import re
import textwrap

import numpy as np
import pytest

from mechsim.formulations import METHODS, Formulation
from test_accuracy import CASES
from test_driven import four_bar_angles


def docstring_formulation():
    """The class of the example in `Formulation.__doc__`."""
    block = re.search(r"::\n\n(.*?)\n\n    Declared", Formulation.__doc__, re.S).group(1)
    namespace = {"np": np, "Formulation": Formulation}
    exec(textwrap.dedent(block), namespace)            # mechsim's own docstring
    return namespace["Index1"]


@pytest.fixture
def index1(monkeypatch):
    cls = docstring_formulation()
    monkeypatch.setitem(METHODS, cls.name, cls)
    return cls.name


def test_the_example_is_short_and_uses_only_the_contract():
    cls = docstring_formulation()
    assert cls.__mro__[1] is Formulation
    assert set(vars(cls)) - {"__module__", "__doc__", "__qualname__", "__firstlineno__",
                             "__static_attributes__"} == {"name", "initial_state", "rhs",
                                                          "state"}


@pytest.mark.parametrize("case", CASES)
def test_the_index1_error_follows_rtol(case, index1):
    """The error against the minimal-coordinate Lagrange models, as for the registry's
    methods (test_accuracy): within 50 rtol and falling 3 times per 100 times rtol. Without
    stabilization the constraints drift, slowly enough over these 2–3 s."""
    build, t_end, exact, names = CASES[case]
    mech = build()
    errors = []
    for rtol in (1e-6, 1e-8, 1e-10):
        res = mech.simulate(t_end, method=index1, rtol=rtol, atol=1e-2 * rtol, output_step=0.05)
        assert res.success, res.message
        assert res.stats["method"] == index1 and res.stats["rhs_evaluations"] > 0
        ref = exact(res.t)
        errors.append(max(np.max(np.abs(res.coordinate(names[k]) - ref[k])) for k in range(2)))
    assert all(err < 50 * rtol for err, rtol in zip(errors, (1e-6, 1e-8, 1e-10))), errors
    assert errors[1] < errors[0] / 3 and errors[2] < errors[1] / 3, errors


def test_the_index1_formulation_runs_a_driven_mechanism(index1):
    """A fully driven crank-rocker (0 DOF) by the new formulation: it does not declare
    `needs_freedom`, so it runs itself, and follows the exact kinematics."""
    from test_driven import crank_rocker
    res = crank_rocker().simulate(1.0, method=index1, rtol=1e-10, atol=1e-12,
                                  output_step=0.01)
    assert res.success, res.message
    th3, th4 = four_bar_angles(0.3 + 10.0 * res.t, 0.2, 0.6, 0.5, 0.7, 1)
    err = np.unwrap(res.coordinate("rocker.angle")) - np.unwrap(th4)
    assert np.max(np.abs(err)) < 1e-7
