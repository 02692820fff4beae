"""What a result records about itself as JSON (`SimulationResult.save`, a stream's
meta.json)."""

from __future__ import annotations

from dataclasses import asdict


def metadata(result) -> dict:
    """The JSON-able description of a result (names, status, statistics, passages,
    switches, the settings `extend` goes on with, and the mechanism as a scene where the
    result knows it and a scene can hold it) that `save` and a stream's meta.json keep."""
    meta = {"coordinate_names": result.coordinate_names, "status": result.status,
            "message": result.message, "stats": result.stats,
            "singular_passages": [asdict(s) for s in result.singular_passages],
            "switches": [asdict(s) for s in result.switches],
            "settings": result.settings}
    if result.impacts or result.friction_switches:
        meta["impacts"] = [asdict(i) for i in result.impacts]
        meta["friction_switches"] = [asdict(s) for s in result.friction_switches]
    friction = getattr(result.problem, "friction", None)
    if friction is not None and friction.schedule:
        meta["friction_schedule"] = [[float(t), [int(m) for m in modes]]
                                     for t, modes in friction.schedule]
    if result.mechanism is not None:
        from ..model import ModelError
        from ..model.scene_save import scene_data
        try:
            meta["mechanism"] = scene_data(result.mechanism)
        except ModelError as exc:
            meta["mechanism_left_out"] = str(exc)
    return meta
