"""A run continued where it stopped (`SimulationResult.extend`) equals the uninterrupted run
to the integration tolerance, its energy balance and passages carried on."""

import numpy as np
import pytest

import mechsim as ms


def damped_engine():
    mech = ms.examples.slider_crank(driven=True)
    mech.add(ms.Spring(mech.ground, mech.body("slider"), at_a=(0.6, 0.0), at_b=(0.45, 0.0),
                       stiffness=200.0, damping=3.0, name="buffer"))
    return mech


def test_an_extended_run_equals_the_uninterrupted_one():
    mech = damped_engine()
    run = dict(rtol=1e-9, atol=1e-11, output_step=1e-3)
    full = mech.simulate(0.2, **run)
    joined = mech.simulate(0.1, **run).extend(0.2)
    np.testing.assert_allclose(joined.t, full.t, rtol=0, atol=1e-15)
    assert np.max(np.abs(joined.q - full.q)) < 1e-9
    # The work of the damper and the motor carried on: the balance keeps its baseline.
    assert joined.energy.channels == full.energy.channels
    assert np.max(np.abs(joined.energy.work - full.energy.work)) < \
        1e-8 * np.max(np.abs(full.energy.work))
    assert np.max(np.abs(joined.energy_drift)) < 100 * 1e-9
    assert joined.stats["steps"] > 0 and joined.settings["rtol"] == 1e-9


def test_extending_through_singular_passages_keeps_them():
    mech = ms.examples.four_bar()
    run = dict(rtol=1e-9, atol=1e-11, output_step=1e-3)
    full = mech.simulate(2.0, **run)
    joined = mech.simulate(0.5, **run).extend(1.2).extend(2.0)
    assert [round(p.t_min, 3) for p in joined.singular_passages] == \
        [round(p.t_min, 3) for p in full.singular_passages]
    assert np.max(np.abs(joined.q - full.q)) < 1e-8
    # Overrides of the settings apply to the part they extend.
    coarse = mech.simulate(0.5, **run).extend(1.0, output_step=0.01)
    assert np.allclose(np.diff(coarse.t[coarse.t > 0.5]), 0.01)


def test_extend_checks_its_arguments(tmp_path):
    res = ms.examples.pendulum().simulate(0.2, output_step=0.05)
    with pytest.raises(ValueError, match="after the last sample"):
        res.extend(0.1)
    res.mechanism = None            # a result without its model (as from solver.simulate)
    loaded = ms.load_result(res.save(tmp_path / "p.npz"))
    with pytest.raises(RuntimeError, match="extending the run"):
        loaded.extend(1.0)


def test_a_long_run_holds_little_more_than_its_samples():
    """Peak memory (numpy's allocations, traced) of a run with 50 000 samples within 1.5
    times its arrays plus 0.25 MB: the samples are written into one array sized by the
    output grid and handed to the result without a copy, and a step over thousands of
    samples solves them a chunk at a time."""
    import tracemalloc
    mech = ms.examples.pendulum()
    mech.simulate(0.01)                                 # model built, imports done
    tracemalloc.start()
    try:
        base = tracemalloc.get_traced_memory()[0]
        res = mech.simulate(1.0, rtol=1e-9, atol=1e-11, output_step=2e-5)
        peak = tracemalloc.get_traced_memory()[1] - base
    finally:
        tracemalloc.stop()
    arrays = res.t.nbytes + res.q.nbytes + res.v.nbytes
    assert len(res.t) == 50001
    assert peak < 1.5 * arrays + 0.25e6, (peak, arrays)


# A streamed run's traced peak, measured in a fresh process: tracemalloc counts every
# thread's allocations, and a test worker may hold threads of earlier tests (5.2 MB traced
# once in the suite against 2.4 MB alone).
_STREAM_PEAK = """
import sys, tracemalloc
sys.path.insert(0, {tests!r})
from test_extend import damped_engine
mech = damped_engine()
mech.simulate(0.01)
tracemalloc.start()
base = tracemalloc.get_traced_memory()[0]
res = mech.simulate(0.5, stream={where!r}, rtol=1e-8, atol=1e-10, output_step=1e-5)
print(tracemalloc.get_traced_memory()[1] - base, res.t.nbytes + res.q.nbytes + res.v.nbytes)
"""


def test_a_streamed_run_writes_its_samples_to_disk_and_reloads_them(tmp_path):
    """Streamed to a directory, a 50 001-sample run (a damped driven slider-crank) holds at
    its peak less than a third of what its samples take; its arrays, work and energy
    balance are those of the same run in memory, and the directory loads back to them."""
    import subprocess
    import sys
    from pathlib import Path
    code = _STREAM_PEAK.format(tests=str(Path(__file__).parent), where=str(tmp_path / "alone"))
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    peak, arrays = map(int, done.stdout.split())
    assert arrays > 7e6 and peak < arrays / 3, (peak, arrays)
    mech = damped_engine()
    run = dict(rtol=1e-8, atol=1e-10, output_step=1e-5)
    plain = mech.simulate(0.5, **run)
    res = mech.simulate(0.5, stream=tmp_path / "run", **run)
    np.testing.assert_array_equal(res.q, plain.q)
    np.testing.assert_array_equal(res.energy.work, plain.energy.work)
    back = ms.load_result(tmp_path / "run")
    assert back.status == "success" and back.stream_path == tmp_path / "run"
    np.testing.assert_array_equal(back.t, plain.t)
    np.testing.assert_array_equal(back.v, plain.v)
    np.testing.assert_array_equal(back.work_record.values, plain.work_record.values)
    # The same directory takes a new stream; a directory of other files is refused.
    mech.simulate(0.01, stream=tmp_path / "run")
    (tmp_path / "other").mkdir()
    (tmp_path / "other" / "notes.txt").write_text("mine")
    with pytest.raises(ValueError, match="holds other files"):
        mech.simulate(0.01, stream=tmp_path / "other")
