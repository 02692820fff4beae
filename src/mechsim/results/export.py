"""Export a result's motion as a meshio time series (ParaView, VisIt, …).

Every body is drawn as a polyline: a rigid body through its attachment points (joints,
springs, forces) and its centre of mass, a flexible beam through points along its axis (the
nodes and points between them, moved by the modes with the element shape functions). The
mesh holds the positions at the first output time; each time step carries point data

    displacement           position(t) − position(t₀)  (ParaView: "Warp By Vector")
    velocity               of the material point
    elastic_displacement   the modal part of the displacement, in global components
    eta<k>                 modal amplitude k of the point's beam (0 on rigid bodies)

and the cell data `body`, an index into the body names listed in `<stem>_body_names.txt`
beside the file. The positions are (x, y, 0): ParaView expects three components.

An `.xdmf` file keeps its heavy data in `<stem>.h5` beside it (HDF5, where h5py is
installed: the `hdf5` extra), else inline as XML text (several times larger and slower); a
`.vtu` series is one compressed binary file per time with a `<stem>.pvd` collection that
ParaView opens as one time series. `every=k` writes every k-th sample (and the last). The
point data are single precision (a drawing's, to 1e-7 of their size).
"""

from __future__ import annotations

import contextlib
import warnings
from pathlib import Path

import numpy as np

from ..files import written
from ..kinematics import drawn_points, frame_point_velocity

# The formats written: ones whose meshio writers take line cells and point data per time.
FORMATS = (".xdmf", ".vtu", ".vtk")


def check_format(path) -> None:
    """ValueError unless `path` ends in one of `FORMATS`."""
    suffix = Path(path).suffix.lower()
    if suffix not in FORMATS:
        raise ValueError(f"cannot export to {str(path)!r}: the file must end in one of "
                         f"{', '.join(FORMATS)}, got {suffix or 'no suffix'!r}")


def export(result, path, drawing, every: int = 1) -> Path:
    """Write `result` to `path` (.xdmf: one time series file; any other meshio format: one
    file per output time, `<stem>_<i><suffix>`, and for .vtu a `<stem>.pvd` collection).
    `drawing` is the problem's list of `(body name, start index, local points (p, 2),
    modal shapes (p, 2, k) or None)`; `every`: write every k-th sample (and the last)."""
    check_format(path)
    if isinstance(every, bool) or not isinstance(every, (int, np.integer)) or every < 1:
        raise ValueError(f"export: `every` must be a whole number ≥ 1, got {every!r}")
    import meshio

    path = Path(path)
    keep = np.unique(np.append(np.arange(0, len(result.t), every), len(result.t) - 1))
    t = result.t[keep]
    n = len(t)
    pos, vel, el, etas, cells, body_index = _fields(result.q[keep], result.v[keep], drawing)

    def xyz(a):
        return np.concatenate([a, np.zeros(a.shape[:-1] + (1,))], axis=-1)

    points0 = xyz(pos[0])
    cell_blocks = [("line", np.concatenate(cells).astype(np.int64))]
    cell_data = {"body": [np.concatenate(body_index).astype(np.int64)]}
    names = [d[0] for d in drawing]

    def point_data(i):
        # Single precision: a drawing's fields to 1e-7 of their size, at half the bytes.
        data = {"displacement": xyz(pos[i] - pos[0]), "velocity": xyz(vel[i]),
                "elastic_displacement": xyz(el[i])}
        data.update({f"eta{k + 1}": etas[k][i] for k in etas})
        return {key: value.astype(np.float32) for key, value in data.items()}

    def write(staged):
        # Every file of the export is written in a staging directory and renamed into
        # place together once all are done (`mechsim.files.written`).
        staged.with_name(staged.stem + "_body_names.txt").write_text(
            "".join(f"{i} {name}\n" for i, name in enumerate(names)))
        if staged.suffix.lower() == ".xdmf":
            fmt = _xdmf_format()
            # meshio's writer puts its heavy-data file in the working directory (its reader
            # looks beside the .xdmf file): write from the file's own directory.
            with contextlib.chdir(staged.parent), \
                    meshio.xdmf.TimeSeriesWriter(staged.name, data_format=fmt) as writer:
                writer.write_points_cells(points0, cell_blocks)
                for i in range(n):
                    writer.write_data(float(t[i]), point_data=point_data(i),
                                      cell_data=cell_data)
            return
        width = len(str(n - 1))
        files = []
        for i in range(n):
            mesh = meshio.Mesh(xyz(pos[i]), cell_blocks, point_data=point_data(i),
                               cell_data=cell_data)
            files.append(staged.with_name(f"{staged.stem}_{i:0{width}d}{staged.suffix}"))
            meshio.write(files[-1], mesh)
        if staged.suffix.lower() == ".vtu":
            _collection(staged.with_suffix(".pvd"), t, files)

    return written(path, write)


def _fields(q, v, drawing):
    """(positions, velocities, elastic displacements (n, points, 2), modal amplitudes per
    point {k: (n, points)}, line cells, body index per cell) of the drawn points."""
    n = len(q)
    positions, velocities, elastic, cells, body_index = [], [], [], [], []
    eta_fields: dict[int, list] = {}
    max_modes = max((d[3].shape[2] for d in drawing if d[3] is not None), default=0)
    offset = 0
    for b, (name, start, local, modal) in enumerate(drawing):
        p = len(local)
        pos = drawn_points(q, start, local, modal)                          # (n, p, 2)
        vel = np.stack([frame_point_velocity(q, v, start, s,
                                             None if modal is None else modal[i])
                        for i, s in enumerate(local)], axis=1)
        if modal is None:
            el = np.zeros((n, p, 2))
        else:                     # the deformed points less the same points of the frame
            el = pos - drawn_points(q, start, local)
        for k in range(max_modes):
            value = q[:, start + 3 + k] if modal is not None and k < modal.shape[2] \
                else np.zeros(n)
            eta_fields.setdefault(k, []).append(np.repeat(value[:, None], p, axis=1))
        positions.append(pos)
        velocities.append(vel)
        elastic.append(el)
        cells.append(np.column_stack([offset + np.arange(p - 1), offset + np.arange(1, p)]))
        body_index.append(np.full(p - 1, b))
        offset += p
    etas = {k: np.concatenate(f, axis=1) for k, f in eta_fields.items()}
    return (np.concatenate(positions, axis=1), np.concatenate(velocities, axis=1),
            np.concatenate(elastic, axis=1), etas, cells, body_index)


def _xdmf_format() -> str:
    """"HDF" where h5py is installed, else "XML" (with a warning: several times larger)."""
    try:
        import h5py  # noqa: F401
        return "HDF"
    except ImportError:
        warnings.warn("mechsim: writing XDMF with its data inline as XML text, several times "
                      "larger and slower than HDF5; install h5py (pip install h5py; from "
                      "a checkout, pip install '.[hdf5]') for compact files", stacklevel=4)
        return "XML"


def _collection(path, times, files) -> None:
    """A ParaView data collection (.pvd): the time series of `files` at `times`."""
    from xml.sax.saxutils import quoteattr
    rows = "".join(f'    <DataSet timestep="{float(tk)!r}" part="0" '
                   f"file={quoteattr(f.name)}/>\n" for tk, f in zip(times, files))
    path.write_text('<?xml version="1.0"?>\n<VTKFile type="Collection" version="0.1">\n'
                    f"  <Collection>\n{rows}  </Collection>\n</VTKFile>\n")
