"""Results as tables: columns named with their SI units, as CSV files and DataFrames."""

import csv

import numpy as np
import pytest

import mechsim as ms
from mechsim.examples import slider_crank_position


@pytest.fixture(scope="module")
def engine():
    """The driven slider-crank (crank 0.15 m at 100 rad/s) over one turn."""
    mech = ms.examples.slider_crank(driven=True, crank_speed=100.0)
    return mech.simulate(2 * np.pi / 100.0, rtol=1e-10, atol=1e-12, output_step=1e-4)


def read_csv(path):
    with open(path, newline="", encoding="utf-8") as f:
        rows = list(csv.reader(f))
    return {name: np.array([float(r[k]) for r in rows[1:]]) for k, name in enumerate(rows[0])}


def test_a_driven_slider_crank_to_csv_holds_its_motion_torque_and_pin_forces(engine, tmp_path):
    """The CSV read back: time, crank angle and slider position with their units (the
    crank at 100 t, the slider on its exact kinematics), the motor torque and the pin
    forces as the result gives them, to the last digit; and the motor's power balancing
    the rate of the kinetic energy (no gravity work in the horizontal slider-crank's
    sliding direction, no dampers: dT/dt + dV/dt = P)."""
    path = engine.to_csv(tmp_path / "engine.csv", joints=["O", "B"], drivers=True)
    table = read_csv(path)
    t = table["t [s]"]
    np.testing.assert_array_equal(t, engine.t)
    np.testing.assert_allclose(table["crank.angle [rad]"], 100.0 * t, rtol=0, atol=1e-9)
    np.testing.assert_allclose(table["slider.x [m]"], slider_crank_position(100.0 * t),
                               rtol=0, atol=1e-9)
    torque = table["driver(O) effort [N·m]"]
    np.testing.assert_array_equal(torque, engine.driver_effort("driver(O)"))
    np.testing.assert_array_equal(table["B force x [N]"], engine.joint_force("B")[:, 0])
    np.testing.assert_array_equal(table["O force y [N]"], engine.joint_force("O")[:, 1])
    assert "B couple [N·m]" not in table and "slide force x [N]" not in table
    energy = engine.energy.kinetic + engine.energy.potential
    rate = np.gradient(energy, t, edge_order=2)
    power = table["driver(O) power [W]"]
    # The second-order difference at h = 1e-4 s of a motion at 100 rad/s and its harmonics
    # errs by about (2 ω h)² ≈ 4e-4 of the power's scale (measured 1.2e-4).
    np.testing.assert_allclose(power[5:-5], rate[5:-5], rtol=0, atol=1e-3 * np.abs(power).max())
    assert np.abs(torque).max() > 10.0                     # a real load, not zeros


def test_columns_carry_their_units(engine):
    table = engine.table(points=[("rod", (0.15, 0.0))], joints=["slide"], drivers=True)
    names = list(table)
    assert names[:4] == ["t [s]", "crank.x [m]", "crank.y [m]", "crank.angle [rad]"]
    assert "crank.angle rate [rad/s]" in names and "slider.x rate [m/s]" in names
    assert "rod(0.15, 0).x [m]" in names and "slide couple [N·m]" in names
    assert "slide coordinate [m]" in names and "slide rate [m/s]" in names
    np.testing.assert_allclose(table["rod(0.15, 0).x [m]"], engine.point("rod", (0.15, 0.0))[:, 0])
    assert all("[" in name and name.endswith("]") for name in names)
    assert set(engine.table(velocities=False)) == {"t [s]", *(f"{n} [{'rad' if n.endswith('angle') else 'm'}]"
                                                             for n in engine.coordinate_names)}


def test_to_pandas_holds_the_same_columns(engine):
    pytest.importorskip("pandas")
    frame = engine.to_pandas(drivers=True)
    table = engine.table(drivers=True)
    assert list(frame.columns) == list(table)
    for name in table:
        np.testing.assert_array_equal(frame[name].to_numpy(), table[name])


def test_a_saved_result_gives_the_same_table(engine, tmp_path):
    """Saved with its reactions and loaded (no model): the same columns and numbers, the
    joints' and drivers' units kept."""
    wanted = dict(joints=True, drivers=True)
    before = engine.table(**wanted)
    back = ms.load_result(engine.save(tmp_path / "engine", reactions=True))
    after = back.table(**wanted)
    assert list(after) == list(before)
    for name in before:
        np.testing.assert_array_equal(after[name], before[name])


def test_a_study_to_csv_round_trips(tmp_path):
    study = ms.sweep(lambda w: ms.examples.slider_crank(driven=True, crank_speed=w),
                     {"w": [50.0, 80.0]}, simulate=dict(t_end=0.01, output_step=0.005),
                     measure=lambda res: {"peak": float(np.abs(res.driver_effort("driver(O)")).max())},
                     workers=1)
    table = read_csv_mixed(study.to_csv(tmp_path / "study.csv"))
    np.testing.assert_array_equal(table["w"], study.table["w"])
    np.testing.assert_array_equal(table["peak"], study.table["peak"])
    assert table["status"] == ["success", "success"]


def read_csv_mixed(path):
    with open(path, newline="", encoding="utf-8") as f:
        rows = list(csv.reader(f))
    out = {}
    for k, name in enumerate(rows[0]):
        column = [r[k] for r in rows[1:]]
        try:
            out[name] = np.array([float(x) for x in column])
        except ValueError:
            out[name] = column
    return out


def test_what_a_loaded_result_cannot_answer_is_said_plainly(tmp_path):
    res = ms.examples.slider_crank(driven=True, crank_speed=100.0).simulate(
        0.01, output_step=1e-3)
    res.mechanism = None            # a result without its model (as from solver.simulate)
    back = ms.load_result(res.save(tmp_path / "plain"))            # no reactions kept
    with pytest.raises(RuntimeError, match="computing the reactions and joint coordinates "
                                           "needs the mechanism's model.*reactions=True"):
        back.joint_force("O")
    with pytest.raises(RuntimeError, match="extending the run needs the mechanism's model"):
        back.extend(1.0)


def test_cycle_figures_give_their_units(engine):
    text = str(engine.cycle_figures())
    assert "driver 'driver(O)': peak effort" in text and " N·m, RMS " in text
    assert engine.cycle_figures().drivers["driver(O)"]["unit"] == "N·m"


def test_set_speed_after_set_state_starts_from_that_state():
    """An equilibrium set as the state, then a joint speed: the run starts at the
    equilibrium turning at that speed (before, set_speed threw the state away and the run
    started from the angle as built)."""
    mech = ms.examples.pendulum(length=0.6, angle=-0.3)
    mech.add(ms.RotationalSpring(mech.ground, mech.body("rod"), stiffness=20.0))
    eq = mech.equilibrium()
    assert eq.converged and abs(eq.q[2] + 0.3) > 0.1
    mech.set_state(eq.q)
    mech.set_speed(mech.joints[0], 0.5)
    res = mech.simulate(0.01)
    np.testing.assert_allclose(res.q[0], eq.q, atol=1e-12)
    assert res.coordinate("rod.angle")[0] == pytest.approx(eq.q[2], abs=1e-12)
    assert res.v[0][2] == pytest.approx(0.5, abs=1e-12)


def test_point_acceleration_and_angular_velocity(engine):
    """The crank of the driven slider-crank turns at 100 rad/s: its tip accelerates
    centripetally, ω² r towards the pivot; the connecting rod's angular velocity and its
    points' accelerations match finite differences of the velocities (second order,
    h = 1e-4 s)."""
    tip = engine.point_acceleration("crank", (0.075, 0.0))
    r = engine.point("crank", (0.075, 0.0))
    np.testing.assert_allclose(tip, -100.0 ** 2 * r, rtol=0, atol=1e-8 * 750)
    np.testing.assert_allclose(engine.angular_velocity("crank"), 100.0, rtol=1e-12)
    assert np.all(engine.angular_velocity("ground") == 0.0)
    t = engine.t
    rod = engine.angular_velocity("rod")
    np.testing.assert_allclose(rod, np.gradient(engine.coordinate("rod.angle"), t,
                                                edge_order=2), rtol=0, atol=1e-3 * 50)
    end = engine.point_acceleration("rod", (0.15, 0.0))
    by_difference = np.gradient(engine.point_velocity("rod", (0.15, 0.0)), t, axis=0,
                                edge_order=2)
    scale = np.abs(end).max()
    np.testing.assert_allclose(end[2:-2], by_difference[2:-2], rtol=0, atol=3e-4 * scale)


def test_point_acceleration_on_a_flexible_beam_follows_its_velocity():
    res = ms.examples.flexible_four_bar().simulate(0.05, integrator="adams", max_step=5e-4,
                                                   output_step=1e-4)
    mid = res.point_acceleration("coupler", (0.5, 0.0))
    by_difference = np.gradient(res.point_velocity("coupler", (0.5, 0.0)), res.t, axis=0,
                                edge_order=2)
    # (measured 6e-6 of the largest; leaving out the modal terms puts it 0.29 off)
    np.testing.assert_allclose(mid[3:-3], by_difference[3:-3], rtol=0,
                               atol=1e-4 * np.abs(mid).max())


def test_a_result_shows_itself_in_jupyter_as_a_table():
    mech = ms.Mechanism("<b>rig</b> & co")
    rod = mech.add(ms.RigidBody.rod("rod<1>", (0, 0), (1, 0), 1.0))
    mech.add(ms.Revolute(mech.ground, rod, at=(0, 0)))
    res = mech.simulate(0.1, output_step=0.01)
    page = res._repr_html_()
    assert page.startswith("<table>") and "success: reached t_end" in page
    assert "&lt;b&gt;rig&lt;/b&gt; &amp; co" in page and "rod&lt;1&gt;.angle" in page
    assert "11, t = 0 … 0.1 s" in page and "<b>" not in page


def test_user_channels_join_the_table(engine):
    """A user's own quantities, as functions of the result, become columns under the names
    given (the crank tip's speed, which is ω r = 15 m/s); a channel of the wrong length or
    not a function is refused naming it."""
    speed = engine.table(velocities=False, channels={
        "crank tip speed [m/s]": lambda r: np.hypot(*r.point_velocity("crank", (0.075, 0)).T)})
    assert list(speed)[-1] == "crank tip speed [m/s]"
    np.testing.assert_allclose(speed["crank tip speed [m/s]"], 100.0 * 0.15, rtol=1e-9)
    with pytest.raises(ValueError, match="channel 'bad \\[m\\]' gave shape \\(3,\\)"):
        engine.table(channels={"bad [m]": lambda r: np.zeros(3)})
    with pytest.raises(ValueError, match="channel 'x' must be a function"):
        engine.table(channels={"x": 3.0})
