"""A run's samples streamed to a directory (`simulate(stream=...)`) and read back.

The directory holds samples.bin and work.bin (raw float64 rows, `mechsim.run.samples.DiskRows`)
and meta.json, which says how to read them: written with status "partial" before the first
sample and replaced, atomically, when the run ends (`mechsim.files`).
"""

from __future__ import annotations

import json

import numpy as np

from ..records import SingularPassage, Status, Switch, WorkRecord
from .meta import metadata
from .result import SimulationResult

# The files a streamed run writes into its directory (`simulate(stream=...)`).
STREAM_FILES = ("samples.bin", "work.bin", "meta.json")


def begin_stream(directory, coordinate_names, channels) -> None:
    """meta.json of a stream whose run has begun: what reading its samples needs, with
    status "partial" until `finish_stream` replaces it (a run killed on the way loads as
    partial, its samples those whole on disk)."""
    meta = {"coordinate_names": list(coordinate_names), "status": Status.PARTIAL,
            "message": "the run writing this stream did not finish (killed, or still "
                       "running): its samples up to the last written", "stats": {},
            "singular_passages": [], "switches": [],
            "width": 1 + 2 * len(coordinate_names), "samples": None,
            "work": {"channels": list(channels), "rows": None, "note": ""}}
    directory.write_text("meta.json", json.dumps(meta))


def finish_stream(result: SimulationResult, directory) -> None:
    """Write beside a streamed run's samples what reading them back needs (meta.json,
    atomically). Where that fails (a full disk) the result says so; its samples stand."""
    meta = metadata(result)
    meta["width"] = 1 + 2 * len(result.coordinate_names)
    meta["samples"] = len(result.t)
    work = result.work_record
    if work is not None:
        meta["work"] = {"channels": list(work.channels), "rows": len(work.values),
                        "note": work.note}
    try:
        directory.write_text("meta.json", json.dumps(meta, default=float))
    except OSError as exc:
        result.message += (f"; the stream's meta.json could not be written ({exc}): "
                           f"{directory.path} loads as a partial run")
    result.stream_path = directory.path


def read_stream(path) -> tuple[SimulationResult, dict]:
    """A streamed run read back (its samples as read-only memory maps), checked against
    its files, and its meta.json: a stream whose run did not finish loads with status
    "partial" and the samples whole on disk; anything inconsistent is a ValueError saying
    what."""
    from ..files import OutputDirectory
    directory = OutputDirectory(path, create=False)
    where = f"stream {directory.path}"
    try:
        with directory.open_read("meta.json") as f:
            meta = json.loads(f.read().decode("utf-8"))
        names, width = meta["coordinate_names"], int(meta["width"])
    except FileNotFoundError:
        raise ValueError(f"{where}: no meta.json: not a stream's directory, or its run was "
                         "killed before it began") from None
    except (ValueError, KeyError, TypeError, UnicodeDecodeError) as exc:
        raise ValueError(f"{where}: meta.json is damaged ({exc})") from None
    n = len(names)
    if width != 1 + 2 * n:
        raise ValueError(f"{where}: meta.json gives rows of {width} numbers for {n} "
                         f"coordinates (expected {1 + 2 * n})")
    rows = _whole_rows(directory, "samples.bin", width, where)
    partial = meta["status"] == Status.PARTIAL
    count = rows if partial else meta["samples"]
    if not isinstance(count, int) or count < 0 or count > rows or (not partial and count != rows):
        raise ValueError(f"{where}: meta.json says {count} samples, samples.bin holds {rows}")
    samples = directory.map("samples.bin", (count, width)) if count else np.zeros((0, width))
    work = None
    w = meta.get("work")
    if w and w.get("channels"):
        work_rows = _whole_rows(directory, "work.bin", len(w["channels"]), where)
        used = min(work_rows, count) if partial else w["rows"]
        if not isinstance(used, int) or used > work_rows:
            raise ValueError(f"{where}: meta.json says {used} work rows, work.bin holds "
                             f"{work_rows}")
        if used:
            work = WorkRecord(tuple(w["channels"]),
                              directory.map("work.bin", (used, len(w["channels"]))),
                              w.get("note", ""))
    message = meta["message"]
    if partial:
        last = f"t = {samples[-1, 0]:.9g}" if count else "no sample"
        message = f"{message} ({count} samples, up to {last})"
    res = SimulationResult(
        samples[:, 0], samples[:, 1:1 + n], samples[:, 1 + n:], names,
        status=meta["status"], message=message, stats=meta["stats"],
        singular_passages=[SingularPassage(**{**s, "joints": tuple(s.get("joints", ()))})
                           for s in meta["singular_passages"]],
        switches=[Switch(**s) for s in meta["switches"]], work=work)
    res.settings = meta.get("settings", {})
    res.stream_path = directory.path
    return res, meta


def _whole_rows(directory, name, width, where) -> int:
    """How many whole rows of `width` float64 numbers the file `name` holds."""
    try:
        size = directory.size(name)
    except FileNotFoundError:
        raise ValueError(f"{where}: {name} is missing") from None
    return size // (8 * width) if width else 0
