"""Results joined end to end: the runs between a mechanism's events as one result."""

from __future__ import annotations

import numpy as np

from ..records import WorkRecord
from .result import SimulationResult


def join(first: SimulationResult, rest: SimulationResult) -> SimulationResult:
    """`rest`, which starts at `first`'s last sample, appended to `first`."""
    stats = dict(rest.stats)
    for key, value in first.stats.items():
        if isinstance(value, (int, float)) and not isinstance(value, bool) and \
                isinstance(rest.stats.get(key), (int, float)):
            stats[key] = value + rest.stats[key]
    work = None
    a, b = first.work_record, rest.work_record
    if a is not None and b is not None and a.channels == b.channels and \
            len(a.values) == len(first.t) and len(b.values):
        work = WorkRecord(a.channels, np.vstack([a.values, b.values[1:] + a.values[-1]]),
                          "; ".join(n for n in (a.note, b.note) if n))
    out = SimulationResult(
        np.concatenate([first.t, rest.t[1:]]), np.vstack([first.q, rest.q[1:]]),
        np.vstack([first.v, rest.v[1:]]), first.coordinate_names, problem=first.problem,
        status=rest.status, message=rest.message, stats=stats,
        singular_passages=first.singular_passages + rest.singular_passages,
        switches=first.switches + rest.switches, exception=rest.exception, work=work)
    out.settings = dict(rest.settings)
    out.continuation = rest.continuation
    out.mechanism = first.mechanism
    if hasattr(first.sensitivities, "joined") and rest.sensitivities is not None:
        out.sensitivities = first.sensitivities.joined(rest.sensitivities, out)
    return out
