"""A run holds the BLAS libraries to one thread while it works, unless the user chose.

The suite's workers hold BLAS to one thread (conftest.py): each test here raises it to
`MANY` first, so that what a run does with more threads is seen on any machine."""

import pytest
from threadpoolctl import threadpool_info, threadpool_limits

import mechsim as ms
from mechsim.threads import USER_VARIABLES


MANY = 3


@pytest.fixture(autouse=True)
def many_threads():
    """BLAS with `MANY` threads around each test (the suite's one restored after)."""
    with threadpool_limits(limits=MANY, user_api="blas"):
        assert all(n == MANY for n in blas_threads())
        yield


def blas_threads():
    return [pool["num_threads"] for pool in threadpool_info() if pool["user_api"] == "blas"]


def probed_pendulum(seen):
    """A pendulum with a force that records the BLAS thread counts when first called."""
    mech = ms.examples.pendulum()

    def push(t):
        if not seen:
            seen.append(blas_threads())
        return (0.0, 0.0)
    mech.add(ms.Force(mech.body("rod"), push, at=(0.5, 0.0)))
    return mech


def test_a_run_uses_one_blas_thread_and_gives_them_back(monkeypatch):
    for name in USER_VARIABLES:
        monkeypatch.delenv(name, raising=False)
    before = blas_threads()
    assert before, "numpy's BLAS is not visible to threadpoolctl"
    seen = []
    res = probed_pendulum(seen).simulate(0.05)
    assert res.success and seen and all(n == 1 for n in seen[0])
    after = blas_threads()          # scipy's BLAS may have been loaded during the run
    assert after[:len(before)] == before and max(after) == max(before)


def test_a_users_thread_count_is_left_alone(monkeypatch):
    monkeypatch.setenv("OMP_NUM_THREADS", "2")
    before = blas_threads()
    seen = []
    probed_pendulum(seen).simulate(0.05)
    assert seen and seen[0][:len(before)] == before


def test_equilibrium_uses_one_blas_thread(monkeypatch):
    for name in USER_VARIABLES:
        monkeypatch.delenv(name, raising=False)
    seen = []
    probed_pendulum(seen).equilibrium()
    assert seen and all(n == 1 for n in seen[0])


def test_nested_runs_hold_one_thread_and_the_outermost_gives_them_back(monkeypatch):
    """A run made of runs (stops, friction, shooting) sets the limit once: inside an inner
    block BLAS still has one thread, after the inner block too, and after the outer one
    the threads it found."""
    from mechsim.threads import run_threads
    for name in USER_VARIABLES:
        monkeypatch.delenv(name, raising=False)
    before = blas_threads()
    with run_threads():
        with run_threads():
            assert all(n == 1 for n in blas_threads())
        assert all(n == 1 for n in blas_threads())
    assert blas_threads()[:len(before)] == before


def test_a_design_search_uses_one_blas_thread_and_gives_them_back(monkeypatch):
    """`ms.optimize` evaluates its objective with one BLAS thread (its objectives' runs and
    scipy's own arithmetic between them), and the threads come back after it."""
    for name in USER_VARIABLES:
        monkeypatch.delenv(name, raising=False)
    mech = ms.Mechanism("rod")
    rod = mech.add(ms.RigidBody.rod("rod", (0, 0), (1, 0), ms.Parameter("m", 1.0)))
    mech.add(ms.Revolute(mech.ground, rod, at=(0, 0)))
    seen = []

    def objective(mech, names):
        seen.append(blas_threads())
        m = mech.parameter_values()["m"]
        return (m - 2.0) ** 2, [2.0 * (m - 2.0)]

    design = ms.optimize(mech, objective, ["m"], bounds={"m": (0.5, 3.0)})
    assert design.parameters["m"] == pytest.approx(2.0, abs=1e-6)
    assert seen and all(n == 1 for counts in seen for n in counts)
    assert all(n == MANY for n in blas_threads())
