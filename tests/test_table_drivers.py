"""Drives from measured data: a driver given as a table of (t, value), a C² cubic spline."""

import numpy as np
import pytest

import mechsim as ms
from mechsim.examples import slider_crank_position

W, A, OMEGA = 40.0, 0.3, 25.0           # crank angle θ(t) = W t + A sin(Ω t)


def theta(t):
    return W * t + A * np.sin(OMEGA * t)


def engine(table=None):
    """The driven slider-crank, its crank on θ(t) as a law, or as `table`."""
    mech = ms.examples.slider_crank(driven=True, crank_speed=W + A * OMEGA)   # θ̇(0)
    pivot = mech.joint("O")
    mech.drivers.clear()
    if table is None:
        mech.add(ms.Driver(pivot, f"{W}*t + {A}*sin({OMEGA}*t)", name="motor"))
    else:
        mech.add(ms.Driver(pivot, table=table, name="motor"))
    return mech


def test_a_table_drives_the_slider_crank_as_its_law_does():
    """θ sampled every 2 ms over 0.3 s. The crank follows the spline through the table
    (scipy's, computed here) to the solver's tolerance, and the slider the exact
    kinematics of that angle; the spline itself is within O(h⁴) of θ (1e-7 rad), its
    rate O(h³), and the motor torque equals the analytic law's to 1e-3 of its peak (the
    acceleration's O(h²) interpolation error)."""
    from scipy.interpolate import CubicSpline
    t = np.linspace(0.0, 0.3, 151)
    spline = CubicSpline(t, theta(t))
    table = engine(table=(t, theta(t)))
    law = engine()
    a = table.kinematics(0.3, 1e-3)
    b = law.kinematics(0.3, 1e-3)
    assert a.success and b.success
    angle = a.coordinate("crank.angle")
    np.testing.assert_allclose(angle, spline(a.t), rtol=0, atol=1e-11)
    np.testing.assert_allclose(a.v[:, 2], spline(a.t, 1), rtol=0, atol=1e-9)
    np.testing.assert_allclose(angle, theta(a.t), rtol=0, atol=1e-7)
    np.testing.assert_allclose(a.coordinate("slider.x"), slider_crank_position(angle),
                               rtol=0, atol=1e-11)
    rate = W + A * OMEGA * np.cos(OMEGA * a.t)         # O(h³), larger in the end pieces
    np.testing.assert_allclose(a.v[:, 2], rate, rtol=0, atol=5e-4)
    torque_a, torque_b = a.driver_effort("motor"), b.driver_effort("motor")
    peak = np.abs(torque_b).max()
    assert peak > 1.0
    np.testing.assert_allclose(torque_a, torque_b, rtol=0, atol=1e-3 * peak)


def test_a_table_driven_simulation_follows_the_table():
    """Simulated (projection) on the generated model (the table's spline in it): the
    crank on the table's spline to the constraint tolerance, and within the spline's O(h⁴)
    of θ."""
    from scipy.interpolate import CubicSpline
    t = np.linspace(0.0, 0.2, 101)
    mech = engine(table=np.column_stack([t, theta(t)]))          # rows (t, value)
    res = mech.simulate(0.2, method="projection", rtol=1e-9, atol=1e-11, output_step=1e-3)
    assert res.success, res.message
    assert not getattr(mech.problem().model, "ASSEMBLED", False)   # the table is generated
    angle = res.coordinate("crank.angle")
    np.testing.assert_allclose(angle, CubicSpline(t, theta(t))(res.t), rtol=0, atol=1e-9)
    np.testing.assert_allclose(angle, theta(res.t), rtol=0, atol=1e-7)


def test_a_table_s_law_is_scipy_s_spline_and_the_generated_model_s():
    """The law's value, rate and acceleration equal scipy's not-a-knot spline's and its
    derivatives' to round-off (its piece's cubic summed in Horner's order), between the
    points, at each point and just past either end (the end pieces go on); and bitwise
    what the generated model evaluates (`splines.evaluate_table` on the law's constants),
    so the assembled and generated builds read the same law."""
    from scipy.interpolate import CubicSpline
    from mechsim.model.splines import evaluate_table
    rng = np.random.default_rng(5)
    t = np.cumsum(rng.uniform(0.005, 0.05, 40))
    values = theta(t) + rng.normal(scale=0.01, size=t.size)
    driver = ms.Driver(engine().joint("O"), table=(t, values), name="m")
    law, constants = driver.law, tuple(driver.law_constants)
    spline = CubicSpline(t, values, bc_type="not-a-knot")
    span = t[-1] - t[0]
    at = np.concatenate([rng.uniform(t[0], t[-1], 100), t,
                         [t[0] - 0.5e-6 * span, t[-1] + 0.5e-6 * span]])
    scale = [np.max(np.abs(spline(at, k))) for k in range(3)]
    for x in at:
        jet = law.jet("t", x)
        for k in range(3):
            assert abs(jet[k] - float(spline(x, k))) <= 1e-14 * scale[k], (x, k)
            assert jet[k] == evaluate_table(k, x, t.size - 1, constants)
        assert law.value(x) == jet[0]
    with pytest.raises(ValueError, match="outside the table"):
        law.value(t[-1] + 1e-3 * span)


def test_a_long_table_is_evaluated_by_the_assembled_build():
    """A table of more than `GENERATED_POINTS` stays out of the generated model (its
    numbers would make every generated function's call and the module grow with it): the
    assembled build evaluates it, and the crank follows its spline as a short one's does."""
    from scipy.interpolate import CubicSpline
    from mechsim.model.drivers import GENERATED_POINTS
    t = np.linspace(0.0, 0.05, GENERATED_POINTS + 1)
    mech = engine(table=(t, theta(t)))
    assert mech.drivers[0].evaluated and mech.drivers[0].law_constants == []
    assert getattr(mech.problem().model, "ASSEMBLED", False)
    res = mech.kinematics(0.05, 1e-3)
    assert res.success, res.message
    np.testing.assert_allclose(res.coordinate("crank.angle"), CubicSpline(t, theta(t))(res.t),
                               rtol=0, atol=1e-11)
    short = engine(table=(t[::10], theta(t[::10])))
    assert not short.drivers[0].evaluated and len(short.drivers[0].law_constants) == 5 * 100 + 1


def test_a_table_round_trips_through_a_scene(tmp_path):
    t = np.linspace(0.0, 0.2, 21)
    mech = engine(table=(t, theta(t)))
    back = ms.load_mechanism(mech.save(tmp_path / "engine.toml"))
    law = back.drivers[0].law
    np.testing.assert_array_equal(law.times, t)
    np.testing.assert_array_equal(law.values, theta(t))
    assert back.drivers[0].tabulated


@pytest.mark.parametrize("table, message", [
    (([0.0, 0.1, 0.1, 0.2], [0, 1, 2, 3]), r"times must increase strictly; t = 0.1 \(point 2\)"),
    (([0.0, 0.1, 0.2], [0, 1, 2]), "at least 4 points"),
    (([0.0, 0.1, 0.2, 0.3], [0, 1, np.nan, 3]), r"point 2 .* is not finite"),
    ("0.1", "expected"),
    (([[0, 1, 2, 3], [0, 1, 2, 3], [0, 1, 2, 3]]), "shape"),
])
def test_a_bad_table_is_refused_naming_the_driver(table, message):
    with pytest.raises(ms.ModelError, match=r"driver 'motor' `table`: .*" + message):
        engine(table=table)


def test_a_run_beyond_the_table_is_refused_before_any_work():
    t = np.linspace(0.0, 0.1, 11)
    mech = engine(table=(t, theta(t)))
    with pytest.raises(ms.ModelError, match=r"driver 'motor' is given by a table of 11 points "
                                            r"over \[0, 0.1\] s; the run asks for \[0, 0.2\] s"):
        mech.simulate(0.2)
    with pytest.raises(ms.ModelError, match=r"the run asks for \[0, 0.3\] s"):
        mech.kinematics(0.3, 0.01)
    with pytest.raises(ms.ModelError, match="an `expression` or a `table`, or a `function`"):
        ms.Driver(mech.joint("O"), "t", table=(t, t))


def test_a_python_function_drives_the_crank():
    """A function giving (θ, θ̇, θ̈) drives as the same law written as an expression does
    (1e-12); one giving θ alone within its central differences (torque 1e-5 of its peak)."""
    def exact(t):
        return (W * t + A * np.sin(OMEGA * t), W + A * OMEGA * np.cos(OMEGA * t),
                -A * OMEGA**2 * np.sin(OMEGA * t))

    def angle(t):
        return W * t + A * np.sin(OMEGA * t)
    law = engine().kinematics(0.2, 1e-3)
    for function, tol in ((exact, 1e-9), (angle, 1e-5)):
        mech = ms.examples.slider_crank(driven=True, crank_speed=W + A * OMEGA)
        mech.drivers.clear()
        mech.add(ms.Driver(mech.joint("O"), function=function, name="motor"))
        res = mech.kinematics(0.2, 1e-3)
        np.testing.assert_allclose(res.q, law.q, rtol=0, atol=1e-12)
        peak = np.abs(law.driver_effort("motor")).max()
        np.testing.assert_allclose(res.driver_effort("motor"), law.driver_effort("motor"),
                                   rtol=0, atol=tol * peak)


def test_a_failing_function_ends_the_run_naming_the_driver(tmp_path):
    def broken(t):
        if t > 0.05:
            raise ZeroDivisionError("no motor data here")
        return W * t
    mech = ms.examples.slider_crank(driven=True, crank_speed=W)
    mech.drivers.clear()
    mech.add(ms.Driver(mech.joint("O"), function=broken, name="motor"))
    res = mech.simulate(0.1, method="projection", output_step=0.01)
    assert res.status == "failed" and "driver 'motor'" in res.message
    assert "ZeroDivisionError: no motor data here" in res.message and res.t[-1] >= 0.03
    with pytest.raises(ms.ModelError, match=r"driver 'motor' is a Python function"):
        mech.save(tmp_path / "m.toml")


@pytest.mark.parametrize("build", ["assembled", "fused"])
def test_a_smooth_step_drives_the_crank_in_both_builds(build):
    """step(t, 0, 0, 0.5, 2) (MSC Adams' STEP): the crank turns 2 rad along the cubic
    40 t² (3 − 4 t) / 10, its rate and acceleration the cubic's, then stays."""
    mech = ms.examples.slider_crank(driven=True, crank_speed=0.0)
    mech.drivers.clear()
    mech.add(ms.Driver(mech.joint("O"), "step(t, 0, 0, 0.5, 2)", name="motor"))
    mech.problem(build=build)
    res = mech.kinematics(0.8, 0.1)           # a sample every 0.1 s, from rest at t = 0
    assert res.success, res.message
    t = res.t
    u = np.clip(t / 0.5, 0.0, 1.0)
    np.testing.assert_allclose(res.coordinate("crank.angle"), 2 * u**2 * (3 - 2 * u),
                               atol=1e-10)
    rate = np.where(t < 0.5, 2 * 6 * u * (1 - u) / 0.5, 0.0)
    np.testing.assert_allclose(res.v[:, 2], rate, atol=1e-9)
    with pytest.raises(ms.ModelError, match=r"unknown function|takes 5 argument"):
        ms.Driver(mech.joint("O"), "step(t, 0, 1)")
