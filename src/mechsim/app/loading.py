"""`load_result`: a saved or streamed result read back with the mechanism that ran it.

It stands above the results (which read the samples) and the scenes (which build the
mechanism saved beside them as a scene), so neither needs the other.
"""

from __future__ import annotations

from pathlib import Path

from ..results.result import SimulationResult
from ..results.saved import read_saved
from ..results.stream import read_stream
from .scene import scene_from


def load_result(path) -> SimulationResult:
    """Read a result written by `SimulationResult.save`, or the directory a run streamed
    to (`simulate(stream=...)`), with its mechanism where one was saved."""
    res, meta = read_stream(path) if Path(path).is_dir() else read_saved(path)
    attach_mechanism(res, meta, Path(path).name)
    return res


def attach_mechanism(result, meta, where) -> None:
    """Give a loaded result the mechanism saved with it (built again from its scene), and
    with it the model: it then plots, animates, extends and computes reactions as the run
    did. Nothing where none was saved."""
    data = meta.get("mechanism")
    if data is None:
        result.model_note = meta.get("mechanism_left_out", "")
        return
    mech = scene_from(data, where, run=False).mechanism
    if list(mech.coordinate_names) != list(result.coordinate_names):
        raise ValueError(f"{where}: the mechanism saved with it has coordinates "
                         f"{mech.coordinate_names[:4]}…, the samples "
                         f"{result.coordinate_names[:4]}…")
    result.mechanism = mech
    result.problem = mech.problem()
    if result.settings:                  # `extend` goes on as the run that made it would
        from ..engineering.impacts import extend_piecewise
        from ..run.solver import continue_run
        result.continuation = extend_piecewise if "contacts" in result.settings else \
            continue_run
    schedule = meta.get("friction_schedule")
    if schedule and result.problem.friction is not None:      # each piece's stick and slip
        result.problem = result.problem.with_friction(
            result.problem.friction.with_schedule((t, tuple(m)) for t, m in schedule))
    from ..engineering.friction import FrictionSwitch
    from ..engineering.impacts import Impact
    result.impacts = [Impact(**i) for i in meta.get("impacts", ())]
    result.friction_switches = [FrictionSwitch(**s) for s in meta.get("friction_switches", ())]
