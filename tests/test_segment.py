"""Plain LU and projection steps taken in the compiled engine (`mechsim.run.segment`) give
the Python loop's numbers to the bit."""

import math

import numpy as np
import pytest
from conftest import needs_compiler

import mechsim as ms
from mechsim.app.bench import PROBLEMS
from mechsim.run import segment


def _both(mech, monkeypatch, kinds=None, **run):
    """The run with segments and without, and the steps the segments took (`kinds`, where
    given, gets them by the formulation: 0 projection, 1 partition)."""
    taken = []
    advance = segment.Segment.advance

    def counted(self):
        done = advance(self)
        if done:
            taken.append((self.steps.s.kind, self.steps.s.count))
            if self.pending is not None:
                taken.append(("observe" if self.pending.observe else "pending", 0))
        return done
    monkeypatch.setattr(segment.Segment, "advance", counted)
    fast = mech.simulate(**run)
    monkeypatch.setattr(segment, "enabled", False)
    slow = mech.simulate(**run)
    monkeypatch.setattr(segment, "enabled", True)
    if kinds is not None:
        for kind, count in taken:
            kinds[kind] = kinds.get(kind, 0) + (count if kind in (0, 1) else 1)
    return fast, slow, sum(count for _, count in taken)


def _same(fast, slow):
    for a, b in ((fast.t, slow.t), (fast.q, slow.q), (fast.v, slow.v)):
        assert a.shape == b.shape and a.tobytes() == b.tobytes()
    for key in ("steps", "rhs_evaluations", "factorizations", "corrections_in_place",
                "partitions", "switches", "bridges"):
        assert fast.stats[key] == slow.stats[key], key
    assert fast.status == slow.status and fast.message == slow.message
    assert [(p.t_start, p.t_end, p.min_sigma, p.t_min, p.joints, p.bridged)
            for p in fast.singular_passages] == \
        [(p.t_start, p.t_end, p.min_sigma, p.t_min, p.joints, p.bridged)
         for p in slow.singular_passages]


@needs_compiler
@pytest.mark.parametrize("name, method, rtol", [
    ("crank-rocker", "hybrid", 1e-4),        # long steps: the path followed, re-references
    ("crank-rocker", "lu", 1e-8),
    ("parallelogram", "hybrid", 1e-6),       # LU phases between passages
    ("double-four-bar", "hybrid", 1e-8),
])
def test_segments_give_the_python_loop_s_numbers_to_the_bit(name, method, rtol, monkeypatch):
    """The same samples, steps, counts, passages and message with segments as without:
    the segments make the loop's decisions on the same doubles, so every sample of the
    run is bitwise the Python loop's, not merely close; and they take part."""
    p = PROBLEMS[name]
    fast, slow, taken = _both(p.build(), monkeypatch, t_end=p.t_end, method=method,
                              rtol=rtol, atol=1e-2 * rtol, output_step=p.t_end / 1000,
                              max_step=p.max_step)
    assert fast.success
    _same(fast, slow)
    assert taken >= 0.2 * fast.stats["steps"]


@needs_compiler
@pytest.mark.parametrize("name, method, rtol, every_step", [
    ("double-four-bar", "hybrid", 1e-4, False),   # between passages, landings of the bridge
    ("double-four-bar", "projection", 1e-6, False),
    ("crank-rocker", "projection", 1e-6, True),   # far from the band; a sample every step
])
def test_projection_segments_give_the_python_loop_s_numbers_to_the_bit(name, method, rtol,
                                                                     every_step,
                                                                     monkeypatch):
    """The projection method's steps in the engine (the hybrid's projection phase after
    and between passages, the bridge's approach, the projected state's rate evaluated
    again, the hybrid's stable steps towards LU counted with the compiled condition test),
    the steps after which the hybrid switches or the bridge crosses taken there up to
    their observation (pending: the loop finishes them), the passages observed there
    too where the bridge crosses them (a passage open at the start, the band, the dips a
    search finds, refined, with their joints): the same samples, counts, switches,
    bridges and passages as the loop's own steps, most of the projection steps taken
    there, and no step of these bridged runs handed to the loop for its observation."""
    p = PROBLEMS[name]
    kinds = {}
    grid = {} if every_step else {"output_step": p.t_end / 1000}
    fast, slow, _ = _both(p.build(), monkeypatch, kinds, t_end=p.t_end, method=method,
                          rtol=rtol, atol=1e-2 * rtol, max_step=p.max_step, **grid)
    assert fast.success
    _same(fast, slow)
    assert fast.stats["projections"] == slow.stats["projections"]
    projection_steps = fast.stats["steps"] - kinds.get(1, 0)
    assert kinds.get(0, 0) >= 0.4 * projection_steps
    if method == "hybrid":                 # its switches, most of them pending
        assert fast.stats["switches"] >= 2
        assert kinds.get("pending", 0) >= fast.stats["switches"] // 2
    if name == "double-four-bar":          # its passages observed in the segments
        assert fast.stats["bridges"] == len(fast.singular_passages) == 10
        assert kinds.get("observe", 0) == 0


@needs_compiler
def test_a_segment_stops_where_the_loop_stops(monkeypatch):
    """A step limit reached inside what would be a segment ends the run at the same step
    with the same partial result; a crank-rocker released from its toggle with a fine
    output grid (many samples a step) and one sample every step (a coarse grid) agree."""
    mech = ms.examples.general_four_bar(0.3, 0.9, 0.7, 1.0, math.radians(60.0),
                                        masses=(1.0, 1.5, 1.0), name="crank-rocker")
    fast, slow, taken = _both(mech, monkeypatch, t_end=3.0, method="lu", rtol=1e-6,
                              atol=1e-8, output_step=1e-3, max_steps=40)
    assert not fast.success and "max_steps = 40" in fast.message and taken > 20
    _same(fast, slow)
    fast, slow, taken = _both(mech, monkeypatch, t_end=3.0, method="hybrid", rtol=1e-9,
                              atol=1e-11, output_step=0.5)
    assert fast.success and taken > 20
    _same(fast, slow)
    np.testing.assert_allclose(fast.t, np.linspace(0.0, 3.0, 7))


@needs_compiler
def test_the_passage_search_and_a_kept_partition_run_in_the_engine(monkeypatch):
    """The crank-rocker at rtol 1e-3 strides ~0.07 s: the monitor's cheap bounds cannot
    clear some steps, which its passage search (`SingularityMonitor._anchored`) clears, and
    after the path was followed the partition's choice keeps its set. With segments, both
    run in the engine (Python searches and chooses no more than at the start), and the
    run is the loop's to the bit."""
    from mechsim.formulations.monitor import SingularityMonitor
    from mechsim.formulations.partitioned import Partitioned
    calls = {"search": 0, "choose": 0}
    anchored, choose = SingularityMonitor._anchored, Partitioned.choose

    def counted_search(self, *args, **kw):
        calls["search"] += 1
        return anchored(self, *args, **kw)

    def counted_choose(self, *args, **kw):
        calls["choose"] += 1
        return choose(self, *args, **kw)
    monkeypatch.setattr(SingularityMonitor, "_anchored", counted_search)
    monkeypatch.setattr(Partitioned, "choose", counted_choose)
    p = PROBLEMS["crank-rocker"]
    run = dict(t_end=p.t_end, method="hybrid", rtol=1e-3, atol=1e-5,
               output_step=p.t_end / 1000)
    mech = p.build()
    fast = mech.simulate(**run)
    in_engine = dict(calls)
    monkeypatch.setattr(segment, "enabled", False)
    calls.update(search=0, choose=0)
    slow = mech.simulate(**run)
    assert slow.success and calls["search"] >= 2 and calls["choose"] >= 2
    assert in_engine["search"] == 0 and in_engine["choose"] <= 1      # the first partition
    _same(fast, slow)


@needs_compiler
@pytest.mark.parametrize("method", ["lu", "hybrid"])
def test_segments_through_dead_centres_and_under_drivers(method, monkeypatch):
    """The slider-crank through its dead centres (a thousand steps) and a pendulum hanging
    from a slider-crank driven at 20 rad/s (rheonomic constraints, Φ_t ≠ 0; without the
    drivers' work, which the loop integrates step by step): the loop's numbers to the
    bit, most steps in segments. With the work integral the driven run has no segments
    and is the loop's own."""
    from test_engine import _driven_slider_crank_with_pendulum
    driven = _driven_slider_crank_with_pendulum()
    for mech, rtol, work in ((ms.examples.slider_crank(crank_angle=math.radians(60.0)), 1e-8,
                              True), (driven, 1e-7, False), (driven, 1e-7, True)):
        fast, slow, taken = _both(mech, monkeypatch, t_end=1.0, method=method, rtol=rtol,
                                  atol=1e-2 * rtol, output_step=1e-3, work=work)
        in_segments = not (mech is driven and work)
        assert fast.success and (taken >= 0.5 * fast.stats["steps"]) == in_segments
        _same(fast, slow)


@needs_compiler
@pytest.mark.parametrize("method", ["lu", "hybrid"])
def test_segments_record_a_sample_at_every_step(method, monkeypatch):
    """Without an output grid (a sample at each step's end, `simulate`'s default) the
    segments record the steps' ends as the loop does, to the bit, also where the partition
    moved its reference (the sample solved again from it, as `Partitioned.state` does)."""
    p = PROBLEMS["crank-rocker"]
    fast, slow, taken = _both(p.build(), monkeypatch, t_end=p.t_end, method=method,
                              rtol=1e-6, atol=1e-8)
    assert fast.success and len(fast.t) == fast.stats["steps"] + 1
    assert taken >= 0.9 * fast.stats["steps"]
    _same(fast, slow)


@needs_compiler
def test_the_loop_takes_the_search_of_a_step_a_segment_declined(monkeypatch):
    """The double four-bar's LU steps across its passages: a segment searches the step
    and finds a passage, which it records itself; where it cannot (here no room for a
    passage: a step ending inside one, a refinement the engine declines, are others), the
    loop observes that step and, rather than search again, takes the segment's search (the
    same request, partition and dense output, compared entry by entry). The run is the
    loop's to the bit."""
    from mechsim.codegen import steps
    from mechsim.codegen.search import StepSearch
    monkeypatch.setattr(steps, "PASSAGES", 0)
    taken = []
    anchored = StepSearch.anchored

    def counted(self, *args):
        got = anchored(self, *args)
        taken.append(bool(self.search.kept))
        return got
    monkeypatch.setattr(StepSearch, "anchored", counted)
    p = PROBLEMS["double-four-bar"]
    fast, slow, in_segments = _both(p.build(), monkeypatch, t_end=p.t_end, method="lu",
                                    rtol=1e-3, atol=1e-5, output_step=p.t_end / 1000)
    assert fast.success and len(fast.singular_passages) == 10 and in_segments > 0
    assert sum(taken) >= 10          # the fast run's passage steps (the slow run's: none)
    _same(fast, slow)


@needs_compiler
def test_lu_segments_record_the_passages_inside_their_steps(monkeypatch):
    """The double four-bar in LU at rtol 1e-3 strides across each of its ten passages in
    one step: the segment finds the dip by its search, refines its minimum, names its
    joints and records it, as the loop's monitor would, and goes on; no step is handed to
    the loop for its observation (the segments take every step, the one that ends the run
    up to its observation: the loop finishes it), and the run is the loop's to the bit
    (passages, joints and all)."""
    p = PROBLEMS["double-four-bar"]
    kinds = {}
    fast, slow, taken = _both(p.build(), monkeypatch, kinds, t_end=p.t_end, method="lu",
                              rtol=1e-3, atol=1e-5, output_step=p.t_end / 1000)
    assert fast.success and len(fast.singular_passages) == 10
    assert all(p.joints for p in fast.singular_passages)
    assert kinds.get("observe", 0) == 0 and taken == fast.stats["steps"]
    assert kinds.get("pending", 0) >= 1                 # the run's last step
    _same(fast, slow)


@needs_compiler
@pytest.mark.parametrize("rtol, through", [(1e-6, True), (1e-8, False)])
def test_lu_segments_step_through_a_passage_where_the_tolerances_stay(rtol, through,
                                                                     monkeypatch):
    """The double four-bar in LU at rtol 1e-6 ends steps inside its passages' band: the
    run's local tolerances (1e-8) are above `PASSAGE_FLOOR`, so LU keeps them inside a
    passage and the segment observes the band, the open passage going on and closing, as
    the loop's monitor would: no step is handed to the loop. At rtol 1e-8 (local 6.3e-10)
    the tolerances change inside a passage: a step that ends there is the loop's. Either
    way the run is the loop's to the bit."""
    from mechsim.tolerances import PASSAGE_FLOOR, Tolerances
    p = PROBLEMS["double-four-bar"]
    kinds = {}
    fast, slow, taken = _both(p.build(), monkeypatch, kinds, t_end=p.t_end, method="lu",
                              rtol=rtol, atol=1e-2 * rtol, output_step=p.t_end / 1000)
    assert fast.success and len(fast.singular_passages) == 10
    assert all(p.joints for p in fast.singular_passages)
    local = Tolerances(rtol, 1e-2 * rtol).local()
    assert (local.rtol >= PASSAGE_FLOOR) == through
    if through:
        assert kinds.get("observe", 0) == 0 and taken == fast.stats["steps"]
    else:
        assert kinds.get("observe", 0) >= 1
    _same(fast, slow)
