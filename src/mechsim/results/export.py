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
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..kinematics import frame_point, frame_point_velocity

# The formats written: ones whose meshio writers take line cells and point data per time.
FORMATS = (".xdmf", ".vtu", ".vtk")


def check_format(path) -> None:
    """ValueError unless `path` ends in one of `FORMATS`."""
    suffix = Path(path).suffix.lower()
    if suffix not in FORMATS:
        raise ValueError(f"cannot export to {str(path)!r}: the file must end in one of "
                         f"{', '.join(FORMATS)}, got {suffix or 'no suffix'!r}")


def export(result, path, drawing) -> Path:
    """Write `result` to `path` (.xdmf: one time series file; any other meshio format: one
    file per output time, `<stem>_<i><suffix>`). `drawing` is the problem's list of
    `(body name, start index, local points (p, 2), modal shapes (p, 2, k) or None)`."""
    check_format(path)
    import meshio

    path = Path(path)
    q, v, t = result.q, result.v, result.t
    n = len(t)
    positions, velocities, elastic, cells, body_index = [], [], [], [], []
    eta_fields: dict[int, list] = {}
    max_modes = max((d[3].shape[2] for d in drawing if d[3] is not None), default=0)
    offset = 0
    for b, (name, start, local, modal) in enumerate(drawing):
        p = len(local)
        pos = np.stack([frame_point(q, start, s, None if modal is None else modal[i])
                        for i, s in enumerate(local)], axis=1)             # (n, p, 2)
        vel = np.stack([frame_point_velocity(q, v, start, s,
                                             None if modal is None else modal[i])
                        for i, s in enumerate(local)], axis=1)
        if modal is None:
            el = np.zeros((n, p, 2))
        else:                     # the deformed points less the same points of the frame
            el = pos - np.stack([frame_point(q, start, s) for s in local], axis=1)
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
    pos = np.concatenate(positions, axis=1)
    vel = np.concatenate(velocities, axis=1)
    el = np.concatenate(elastic, axis=1)
    etas = {k: np.concatenate(f, axis=1) for k, f in eta_fields.items()}

    def xyz(a):
        return np.concatenate([a, np.zeros(a.shape[:-1] + (1,))], axis=-1)

    points0 = xyz(pos[0])
    cell_blocks = [("line", np.concatenate(cells).astype(np.int64))]
    cell_data = {"body": [np.concatenate(body_index).astype(np.int64)]}
    names = [d[0] for d in drawing]

    def point_data(i):
        data = {"displacement": xyz(pos[i] - pos[0]), "velocity": xyz(vel[i]),
                "elastic_displacement": xyz(el[i])}
        data.update({f"eta{k + 1}": etas[k][i] for k in etas})
        return data

    path.parent.mkdir(parents=True, exist_ok=True)
    path.with_name(path.stem + "_body_names.txt").write_text(
        "".join(f"{i} {name}\n" for i, name in enumerate(names)))
    if path.suffix.lower() == ".xdmf":
        # Inline XML data: HDF5 would need h5py, and meshio's "Binary" format writes its
        # .bin files into the working directory rather than beside the .xdmf file.
        with meshio.xdmf.TimeSeriesWriter(path, data_format="XML") as writer:
            writer.write_points_cells(points0, cell_blocks)
            for i in range(n):
                writer.write_data(float(t[i]), point_data=point_data(i), cell_data=cell_data)
        return path
    width = len(str(n - 1))
    for i in range(n):
        mesh = meshio.Mesh(xyz(pos[i]), cell_blocks, point_data=point_data(i),
                           cell_data=cell_data)
        meshio.write(path.with_name(f"{path.stem}_{i:0{width}d}{path.suffix}"), mesh)
    return path
