"""The run's configuration objects: `RunConfig` (the user's keywords checked once),
`Tolerances` (every tolerance derived from rtol and atol in one place) and the hybrid
method's `SwitchPolicy` (seed 001's switching rules, decided apart from the switching)."""

from types import SimpleNamespace

import numpy as np
import pytest

import mechsim as ms
from mechsim.formulations.hybrid import SwitchPolicy
from mechsim.integrators import integrator_name
from mechsim.run.solver import RunConfig
from mechsim.tolerances import Tolerances


def test_tolerances_derive_every_other_tolerance():
    tol = Tolerances(1e-6, 1e-8)
    assert tol.newton == pytest.approx(1e-10)
    assert tol.manifold == pytest.approx(1e-5)            # max(10 rtol, 100 atol)
    assert Tolerances(1e-8, 1e-8).manifold == pytest.approx(1e-6)
    assert tol.tight_manifold == pytest.approx(1e-11)
    assert Tolerances(1e-12, 1e-14).tight_manifold == 1e-13   # not below round-off
    assert (tol.inner().rtol, tol.inner().atol) == pytest.approx((1e-8, 1e-10))
    assert Tolerances(1e-12, 1e-14).inner().rtol == 1e-13
    assert tol.work == pytest.approx(1e-7)
    for bad in (0.0, -1e-6, float("nan"), float("inf"), True, "1e-6"):
        with pytest.raises(ValueError, match="`rtol` must be a positive number"):
            Tolerances(bad, 1e-8)


def test_a_run_config_is_checked_once_and_is_what_the_result_keeps():
    mech = ms.examples.double_four_bar()
    n = len(mech.coordinate_names)
    config = RunConfig.from_keywords(n, 0.3, "projection", rtol=1e-7, atol=1e-9,
                                     output_step=0.01, rcond=1e-3)
    assert config.method.name == "projection" and integrator_name(config.integrator) == "DOP853"
    assert (config.rtol, config.atol, config.t_start, config.t_end) == (1e-7, 1e-9, 0.0, 0.3)
    assert config.options == {"rcond": 1e-3}
    res = mech.simulate(0.3, method="projection", rtol=1e-7, atol=1e-9, output_step=0.01,
                        rcond=1e-3)
    assert res.success, res.message
    assert res.settings == config.settings()
    with pytest.raises(ValueError, match="'rcnd'.*rcond"):
        RunConfig.from_keywords(n, 1.0, "projection", rcnd=1e-3)
    with pytest.raises(ValueError, match="`rtol`"):
        RunConfig.from_keywords(n, 1.0, rtol=-1.0)
    with pytest.raises(ValueError, match="'alpha' is an option of method"):
        RunConfig.from_keywords(n, 1.0, "lu", alpha=5.0)
    with pytest.raises(ValueError, match="`t_end` must be after t_start = 2.0"):
        RunConfig.from_keywords(n, 1.0, t_start=2.0)


def monitor(last, rate=0.0, ahead=False, inside=False):
    """The singularity monitor's readings a switching rule looks at."""
    return SimpleNamespace(last=last, rate=rate, enter=0.07, leave=0.14, inside=inside,
                           predicted_within=lambda step: ahead,
                           open_passage=SimpleNamespace(joints=("C", "D")))


def test_lu_may_only_reach_half_the_predicted_entry_into_the_band():
    policy = SwitchPolicy()
    assert policy.lu_limit(monitor(0.5, rate=-2.0)) == pytest.approx(0.5 * 0.43 / 2.0)
    assert policy.lu_limit(monitor(0.5, rate=+2.0)) is None         # rising: no limit
    assert policy.lu_limit(monitor(0.05, rate=-2.0)) is None        # inside the band
    assert policy.lu_limit(monitor(0.0701, rate=-1e9)) == 1e-6      # the floor
    assert policy.lu_limit(None) is None


def test_lu_leaves_when_a_passage_is_ahead_or_after_two_steps_held_by_its_limit():
    policy = SwitchPolicy()
    assert policy.leave_lu(monitor(0.1, ahead=True), 0.01, None).startswith(
        "σ_min/σ_max at 0.1 of its peak, falling")
    policy = SwitchPolicy()
    inside = policy.leave_lu(monitor(0.05, ahead=True, inside=True), 0.01, None)
    assert "near a singular configuration (joints C, D)" in inside
    policy = SwitchPolicy()
    quiet = monitor(0.5, rate=-1.0)
    reasons = [policy.leave_lu(quiet, step, 0.1) for step in (0.1, 0.1, 0.1)]
    assert reasons[:2] == [None, None] and reasons[2] is not None      # held, held: switch
    policy = SwitchPolicy()
    assert [policy.leave_lu(quiet, step, 0.1) for step in (0.1, 0.05, 0.1, 0.05)] == \
        [None] * 4                                                    # never held twice


def test_a_burst_of_repartitions_sends_lu_to_projection():
    policy = SwitchPolicy(repartition_burst=3, burst_steps=10)
    verdicts = []
    for step in (1, 12, 13, 14):
        policy.steps = step
        verdicts.append(policy.repartitioned())
    assert verdicts[:3] == [None, None, None]                # 1 fell out of the window
    assert verdicts[3] == "independent set changed 3 times in 10 steps"


def test_projection_hands_back_after_stable_growing_steps_with_lu_ready():
    policy = SwitchPolicy(stable_steps=5)
    clear = monitor(0.5)
    steps = np.array([0.01, 0.01, 0.012, 0.012, 0.013])
    out = [policy.back_to_lu(clear, h, lambda: True) for h in steps]
    assert out[:4] == [None] * 4 and out[4].startswith("5 stable steps")
    policy = SwitchPolicy(stable_steps=5)
    out = [policy.back_to_lu(clear, h, lambda: True) for h in (0.01, 0.01, 0.005, 0.01)]
    assert policy.stable == 1 and out == [None] * 4           # the shrinking step reset it
    policy = SwitchPolicy(stable_steps=2)
    assert [policy.back_to_lu(monitor(0.1), 0.01, lambda: True) for _ in range(3)] == \
        [None] * 3                                            # below `leave`: never clear
    assert [policy.back_to_lu(clear, 0.01, lambda: False) for _ in range(3)] == [None] * 3
