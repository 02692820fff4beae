"""Reading a file `SimulationResult.save` wrote."""

from __future__ import annotations

import json
import zipfile
from pathlib import Path

import numpy as np

from ..records import SingularPassage, Switch
from .result import EnergyLog, SimulationResult


def read_saved(path) -> tuple[SimulationResult, dict]:
    """The result in a file `SimulationResult.save` wrote, and its metadata; a file that is
    not one is a ValueError saying so."""
    if Path(path).is_file() and not zipfile.is_zipfile(path):
        raise ValueError(f"{path} is not a result saved by mechsim (SimulationResult.save "
                         "writes .npz files) nor the directory of a streamed run")
    with np.load(path, allow_pickle=False) as data:
        try:
            meta = json.loads(str(data["meta"]))
            names = meta["coordinate_names"]
            shapes = {key: data[key].shape for key in ("t", "q", "v")}
        except (KeyError, ValueError, TypeError) as exc:
            raise ValueError(f"{path} is not a result saved by mechsim ({exc})") from None
        rows = shapes["t"][0] if len(shapes["t"]) == 1 else -1
        if rows < 0 or shapes["q"] != (rows, len(names)) or shapes["v"] != (rows, len(names)):
            raise ValueError(f"{path}: its arrays do not fit together: t {shapes['t']}, "
                             f"q {shapes['q']}, v {shapes['v']} for {len(names)} coordinates")
        energy = None
        if "kinetic" in data:
            if "work_by" in data:
                energy = EnergyLog(data["kinetic"], data["potential"], data["strain"],
                                   work_by=data["work_by"],
                                   channels=tuple(meta["work_channels"]),
                                   includes=meta["work_includes"])
            else:
                energy = EnergyLog(data["kinetic"], data["potential"], data["strain"],
                                   data["work"] if "work" in data else None)
        violation = data["constraint_violation"] if "constraint_violation" in data else None
        saved = None
        if "reactions" in meta:
            r = meta["reactions"]
            saved = {key: data[f"reaction_{k}"] for k, key in enumerate(r["keys"])}
            saved.update(joints=r["joints"], drivers=r["drivers"], kinds=r.get("kinds", {}),
                         driver_kinds=r.get("driver_kinds", {}))
        sensitivities = None
        if "sensitivities" in meta:
            from ..problem.sensitivity import StoredSensitivities
            spec = meta["sensitivities"]
            sensitivities = StoredSensitivities(
                spec["names"], {k: data[f"sensitivity_{k}"] for k in spec["keys"]})
        res = SimulationResult(
            data["t"], data["q"], data["v"], meta["coordinate_names"], status=meta["status"],
            message=meta["message"], stats=meta["stats"],
            singular_passages=[SingularPassage(**{**s, "joints": tuple(s.get("joints", ()))})
                               for s in meta["singular_passages"]],
            switches=[Switch(**s) for s in meta["switches"]], energy=energy,
            constraint_violation=violation, saved_reactions=saved)
    res.settings = meta.get("settings", {})
    res.sensitivities = sensitivities
    return res, meta
