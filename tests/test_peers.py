"""The peer models of `mechsim bench peers` (MuJoCo and Exudyn) describe the same
mechanism: the MJCF's tree and loop closures from the pins, and, where the peers are
installed (the `peers` extra), their initial state and short motion against mechsim's."""

import math

import numpy as np
import pytest

import mechsim as ms
from mechsim.app import peers


def test_the_mujoco_model_is_a_tree_of_hinges_closed_by_connects():
    """The double four-bar's 7 pins: 5 hinges of a spanning tree from the ground (one per
    body), the 2 that close its loops as connect equalities."""
    mech = ms.examples.double_four_bar(2)
    parent, order, closing = peers.spanning_tree(mech)
    assert len(order) == len(mech.bodies) == 5 and len(closing) == 2
    xml = peers.mujoco_xml(mech, 1e-3, "RK4", ("crank1", (0.5, 0.0)))
    assert xml.count("<connect ") == 2 and xml.count('type="hinge"') == 5
    assert xml.count('<site name="trace"') == 1 and 'solref="0.002 1"' in xml


@pytest.mark.parametrize("tool", ["mujoco", "exudyn"])
def test_a_peer_swings_the_pendulum_as_mechsim_does(tool):
    """A rod pinned at its end, released horizontal, 0.5 s: each peer's tip within its
    step's accuracy of mechsim's (a first check that the models mean the same)."""
    pytest.importorskip(tool)
    mech = ms.examples.pendulum()
    res = mech.simulate(0.5, rtol=1e-10, atol=1e-12, output_step=0.05)
    tip = res.point("rod", (0.5, 0.0))
    run = peers.mujoco_run if tool == "mujoco" else peers.exudyn_run
    _, t, xy = run(mech, 0.5, 1e-4, 0.05, ("rod", (0.5, 0.0)))
    np.testing.assert_allclose(t, res.t, atol=1e-9)
    assert np.max(np.hypot(*(xy - tip).T)) < 1e-3
    assert math.isclose(float(xy[0, 0]), 1.0, abs_tol=1e-9)


def test_the_exact_equation_s_runs_converge_to_the_bench_s_exact_motion():
    """scipy's DOP853 on the double four-bar's exact 1-DOF equation, the floor beside the
    peers: its crank tip converges to the bench's exact path (itself DOP853 at 1e-13) as
    its rtol falls, to 1e-9 m at rtol 1e-12 (its own error ~300 rtol over the ten passages,
    as mechsim's bench records it), and errs by a fifth of the crank at rtol 1e-3."""
    from mechsim.app.bench import PROBLEMS
    problem = PROBLEMS["double-four-bar"]
    errors = []
    for rtol in (1e-3, 1e-6, 1e-12):
        _, t, xy = peers.exact_run(problem, rtol, problem.t_end / 1000)
        assert t.size == 1001 and np.allclose(np.hypot(*xy.T), 1.0)
        errors.append(problem.point_error(t, xy))
    assert errors[2] < 1e-9 and 1e-5 < errors[1] < 1e-3 and errors[0] > 0.1


def test_the_reference_time_at_an_error_follows_its_work_precision_curve():
    """The reference's time at an error between two of its runs is their log-log
    interpolation (at 3.16e-4 between runs at 1e-3 in 1 ms and 1e-4 in 4 ms: 2 ms), a
    run slower than a more accurate one counts at that one's time (the reference's best),
    and outside the runs' errors there is none; each successful mechsim run is set beside
    it."""
    from mechsim.app.bench import Row
    name, tool = "double-four-bar", "exact 1-DOF DOP853"
    rows = [peers.PeerRow(name, tool, 1e-4, 1e-3, 1e-3),
            peers.PeerRow(name, tool, 1e-5, 1e-4, 5e-3),      # slower than a better run
            peers.PeerRow(name, tool, 1e-6, 1e-5, 4e-3),
            peers.PeerRow(name, "mujoco RK4", 1e-3, 1e-4, 1e-6)]
    assert math.isclose(peers.reference_time(rows, name, 10 ** -3.5), 2e-3, rel_tol=1e-12)
    assert math.isclose(peers.reference_time(rows, name, 1e-4), 4e-3, rel_tol=1e-12)
    assert math.isclose(peers.reference_time(rows, name, 3e-5), 4e-3, rel_tol=1e-12)
    assert peers.reference_time(rows, name, 1e-6) is None
    assert peers.reference_time(rows, name, 1e-2) is None
    assert peers.reference_time(rows, "crank-rocker", 1e-4) is None
    mine = [Row(name, "lu", "DOP853", 1e-4, "success", 10 ** -3.5, 0.0, 4e-3, 10, 100, 1),
            Row(name, "lu", "DOP853", 1e-6, "failed", 1e-7, 0.0, 4e-3, 10, 100, 1)]
    lines = peers.against_reference(mine, rows)
    assert len(lines) == 1 and lines[0].endswith("→ 2.00×")


def test_the_floor_is_timed_in_the_rounds_of_mechsim_s_runs(monkeypatch):
    """`mechsim bench peers` times the exact 1-DOF floor after each round of mechsim's
    runs of a problem (`bench.run`'s `beside`), at least `MIN_FLOOR_RUNS` times at each
    rtol, keeping each rtol's shortest time with that run's error; a problem without an
    exact 1-DOF equation (the driven slider-crank, 0 DOF) has no floor."""
    from mechsim.app import bench
    walls = iter(np.linspace(0.9, 0.1, 1000))
    calls = []

    def timed(problem, rtol, output_step):
        calls.append((problem.name, rtol))
        t = np.linspace(0.0, problem.t_end, 3)
        return next(walls), t, np.column_stack([np.cos(t), np.sin(t)])
    monkeypatch.setattr(peers, "exact_run", timed)
    monkeypatch.setattr(peers, "EXACT_RTOLS", (1e-3, 1e-6))
    rounds = []
    floor = peers.Floor()

    def beside(name, round_, count):
        rounds.append((name, round_, count, len(calls)))
        floor(name, round_, count)
    names = ["parallelogram", "driven-slider-crank"]
    rows = bench.run(names, ["lu"], [1e-3], progress=None, repeat=2, beside=beside)
    assert [r.problem for r in rows] == names
    assert [r[:3] for r in rounds] == [(name, k, 2) for name in names for k in (0, 1)]
    assert rounds[1][3] == 2           # the floor ran in the first round, each rtol once
    assert {name for name, _ in calls} == {"parallelogram"}
    assert all(calls.count(("parallelogram", r)) >= peers.MIN_FLOOR_RUNS for r in (1e-3, 1e-6))
    got = floor.rows("parallelogram")
    assert [r.step for r in got] == [1e-3, 1e-6] and floor.rows("driven-slider-crank") == []
    # times fall run after run: each rtol keeps its last run's
    w = np.linspace(0.9, 0.1, 1000)
    last = [max(i for i, call in enumerate(calls) if call[1] == r) for r in (1e-3, 1e-6)]
    assert [r.wall_time for r in got] == [w[i] for i in last]
    problem = bench.PROBLEMS["parallelogram"]
    t = np.linspace(0.0, problem.t_end, 3)
    error = problem.point_error(t, np.column_stack([np.cos(t), np.sin(t)]))
    assert all(r.error == error and r.tool == "exact 1-DOF DOP853" for r in got)
