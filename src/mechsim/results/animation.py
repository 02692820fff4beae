"""Pictures of a result's motion: snapshots with traced paths (`plot_motion`) and animations
(`animate`, GIF through Pillow, MP4 through ffmpeg where it is installed).

A body is drawn as the polyline `SimulationResult.export` draws (a rigid body through its
joints, load points and centre of mass; a beam along its axis, deformed by its modes times
`exaggeration`), a revolute joint as a pin, a prismatic joint as a pin on a guide line over
the slide it covers, a slot as its centre line, a stop as a mark where it stops its joint
(fixed in the joint's body_a), a spring as a zig-zag, a traced point as the path it has covered. Under
the mechanism a time bar shades the singular passages and marks the present time.
"""

from __future__ import annotations

import math
import numbers

from pathlib import Path

import numpy as np

from ..files import save_figure, written
from ..kinematics import drawn_points, frame_point
from .plots import literal_text

# An animation plays at most this many seconds: longer results are decimated.
MAX_SECONDS = 12.0
COILS = 8                       # zig-zags of a drawn spring


class Scene:
    """The drawing of `result` at the sample indices `frames` (geometry only, no artists)."""

    def __init__(self, result, frames, trace=(), exaggeration=1.0):
        p = result.problem
        if p is None:
            why = f" ({result.model_note})" if getattr(result, "model_note", "") else ""
            raise RuntimeError("drawing the motion needs the mechanism's geometry, and this "
                               f"result was loaded without its mechanism{why}")
        self.result, self.problem, self.frames = result, p, np.asarray(frames)
        q = result.q[self.frames]
        self.bodies = [(name, drawn_points(q, start, local, modal, exaggeration))
                       for name, start, local, modal in p.drawing]
        from ..problem.geometry import joint_coordinates, joint_point
        self.pins = {name: joint_point(g, q) for name, g in p.joints.items()}
        self.guides = []                  # (K, P, 2) polylines fixed in a joint's body_a
        for name, g in p.joints.items():
            if g.joint.kind == "prismatic":
                s = joint_coordinates(g, result.q, result.v)[0]
                self.guides.append(self._guide(g, q, s.min(), s.max()))
            elif g.joint.kind == "curve" and g.joint.form in ("line", "circle"):
                self.guides.append(self._slot(g, q, result.q))
        stops = [e for e in (p.friction.elements if p.friction is not None else ())
                 if e.kind == "stop"]
        for e in stops:
            for _, limit in e.friction.limits():
                self.guides.append(self._stop(e.geometry, q, limit))
        self.springs = [self._spring(q, sp) for sp in p.springs]
        self.traces = [(self._label(body, local), result.point(body, local))
                       for body, local in trace]

    @staticmethod
    def _label(body, local):
        return f"{getattr(body, 'name', body)} ({float(local[0]):g}, {float(local[1]):g})"

    @staticmethod
    def _guide(g, q, lowest, highest):
        """(K, 2, 2) ends of a prismatic joint's guide line: along its axis (turning with
        body_a) through the slides the whole result covers, with a margin."""
        from ..problem.geometry import NumericContext, value
        ctx = NumericContext(g.starts, q)
        p = g.parameters
        ax, ay = (value(c) * np.ones(q.shape[0]) for c in ctx.point(
            g.joint.body_a, g.local_a[0], g.local_a[1], p, "a"))
        ux, uy = (value(c) * np.ones(q.shape[0]) for c in ctx.direction(
            g.joint.body_a, p["ux"], p["uy"], p, "a"))
        margin = 0.15 * max(highest - lowest, 1e-3)
        ends = [lowest - margin, highest + margin]
        return np.stack([np.column_stack([ax + e * ux, ay + e * uy]) for e in ends], axis=1)

    @staticmethod
    def _in_body_a(g, q, local):
        """(K, P, 2): the points `local` (P, 2) of joint g's body_a frame at the states q."""
        from ..problem.geometry import NumericContext, value
        ctx = NumericContext(g.starts, q)
        x, y = (value(c) * np.ones(q.shape[0]) for c in ctx.point(g.joint.body_a, 0.0, 0.0))
        ux, uy = (value(c) * np.ones(q.shape[0]) for c in ctx.direction(g.joint.body_a,
                                                                          1.0, 0.0))
        lx, ly = local[:, 0], local[:, 1]
        return np.stack([x[:, None] + ux[:, None] * lx - uy[:, None] * ly,
                         y[:, None] + uy[:, None] * lx + ux[:, None] * ly], axis=-1)

    @classmethod
    def _slot(cls, g, q, every):
        """A slot's centre line in body_a: a straight one over the stretch its pin covers
        in the whole result (with a margin), a circular one whole."""
        from ..problem.geometry import NumericContext, value
        joint, (cx, cy) = g.joint, g.local_a
        if joint.form == "circle":
            a = np.linspace(0.0, 2.0 * np.pi, 65)
            local = np.column_stack([cx + joint.shape * np.cos(a), cy + joint.shape * np.sin(a)])
            return cls._in_body_a(g, q, local)
        u = np.asarray(joint.body_a.local_direction(joint.shape), float)
        ctx = NumericContext(g.starts, every)
        ax, ay = (value(c) for c in ctx.point(joint.body_a, cx, cy, g.parameters, "a"))
        bx, by = (value(c) for c in ctx.point(joint.body_b, *g.local_b, g.parameters, "b"))
        ex, ey = (value(c) for c in ctx.direction(joint.body_a, u[0], u[1]))
        s = (np.asarray(bx - ax) * ex + np.asarray(by - ay) * ey).reshape(-1)
        margin = 0.15 * max(np.ptp(s), 1e-3)
        ends = np.array([s.min() - margin, s.max() + margin])
        return cls._in_body_a(g, q, np.column_stack([cx + ends * u[0], cy + ends * u[1]]))

    @classmethod
    def _stop(cls, g, q, limit):
        """A stop's mark in body_a at `limit`: a revolute's, a stroke from the pin out
        where body_b's centre line reaches at the limit; a prismatic's, a bar across the
        guide where body_b's point reaches it."""
        joint = g.joint
        (ax, ay), (bx, by) = g.local_a, g.local_b
        if joint.kind == "prismatic":
            u = np.array([g.parameters["ux"], g.parameters["uy"]])
            n = np.array([-u[1], u[0]])
            body = joint.body_b               # as tall as its block is drawn (√(6 I/m))
            size = math.sqrt(6.0 * getattr(body, "inertia", 0.0) / body.mass) or 0.05
            at = np.array([ax, ay]) + limit * u
            return cls._in_body_a(g, q, np.array([at - size * n, at + size * n]))
        # a revolute: body_b's arm, the pin to its centre, turned to the limit in body_a
        arm = np.hypot(bx, by) or 0.1
        direction = np.arctan2(-by, -bx) + joint.body_b.angle - joint.body_a.angle + \
            limit - joint.initial_coordinate()
        ray = np.array([0.6, 1.2])[:, None] * arm * np.array([np.cos(direction),
                                                            np.sin(direction)])
        return cls._in_body_a(g, q, np.array([ax, ay]) + ray)

    @staticmethod
    def _spring(q, sp):
        """(K, 2 COILS + 2, 2) zig-zag of a spring between its attachment points."""
        a = frame_point(q, sp.a, sp.sa, sp.modal_a)
        b = frame_point(q, sp.b, sp.sb, sp.modal_b)
        d = b - a
        length = np.linalg.norm(d, axis=1, keepdims=True)
        normal = np.column_stack([-d[:, 1], d[:, 0]]) / np.where(length > 0, length, 1.0)
        u = np.linspace(0.0, 1.0, 2 * COILS + 2)
        side = np.zeros_like(u)
        side[1:-1] = np.where(np.arange(1, u.size - 1) % 2, 1.0, -1.0)
        width = 0.06 * np.median(length)
        return a[:, None] + u[None, :, None] * d[:, None] + \
            width * side[None, :, None] * normal[:, None]

    def limits(self):
        """(x range, y range) holding every drawn point with a 5 % margin, equal aspect."""
        pts = [pl.reshape(-1, 2) for _, pl in self.bodies]
        pts += [p for p in self.pins.values()] + [t for _, t in self.traces]
        pts += [g.reshape(-1, 2) for g in self.guides]
        allp = np.vstack(pts)
        lo, hi = allp.min(axis=0), allp.max(axis=0)
        size = max(np.max(hi - lo), 1e-6)
        mid = (lo + hi) / 2
        half = 0.55 * size
        return (mid[0] - half, mid[0] + half), (mid[1] - half, mid[1] + half)


def frame_indices(t, fps, max_frames=None) -> np.ndarray:
    """Sample indices to draw: every sample, or evenly spaced ones where there are more than
    fps × MAX_SECONDS (or `max_frames`)."""
    limit = int(max_frames if max_frames is not None else fps * MAX_SECONDS)
    if len(t) <= limit:
        return np.arange(len(t))
    return np.unique(np.round(np.linspace(0, len(t) - 1, max(limit, 2))).astype(int))


def pace_note(t, frames, fps) -> str:
    """"   (0.2 × real time)" where the frames shown at `fps` show simulated time slower or
    faster than it passed ("" where at its pace)."""
    pace = (t[frames[-1]] - t[frames[0]]) / max(len(frames) - 1, 1) * fps
    return "" if not pace > 0 or abs(pace - 1.0) < 0.01 else f"   ({pace:.3g} × real time)"


def _figure():
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    fig = Figure(figsize=(6.4, 6.0), layout="constrained")
    FigureCanvasAgg(fig)                       # the writers read its pixels
    grid = fig.add_gridspec(2, 1, height_ratios=(12, 1))
    return fig, fig.add_subplot(grid[0]), fig.add_subplot(grid[1])


def _time_bar(ax, result):
    t0, t1 = result.t[0], result.t[-1]
    for k, sp in enumerate(result.singular_passages):
        ax.axvspan(sp.t_start, max(sp.t_end, sp.t_start + 1e-3 * (t1 - t0)), color="C3",
                   alpha=0.35, lw=0, label="singular passage" if k == 0 else None)
    ax.set_xlim(t0, t1 if t1 > t0 else t0 + 1.0)
    ax.set_yticks([])
    ax.set_xlabel("time [s]")
    return ax.axvline(t0, color="k", lw=2)


class Artists:
    """The lines of one drawn state, updated in place from frame to frame."""

    def __init__(self, ax, scene, faded=False):
        self.scene = scene
        alpha = 0.25 if faded else 1.0
        self.bodies = [ax.plot([], [], "-", lw=3, color=f"C{k % 10}", alpha=alpha,
                               solid_capstyle="round", label=None if faded else name)[0]
                       for k, (name, _) in enumerate(scene.bodies)]
        self.guides = [ax.plot([], [], "-", lw=1, color="0.5", alpha=alpha)[0]
                       for _ in scene.guides]
        self.springs = [ax.plot([], [], "-", lw=1, color="0.3", alpha=alpha)[0]
                        for _ in scene.springs]
        self.pins = ax.plot([], [], "o", ms=6, mfc="white", mec="k", alpha=alpha)[0]

    def show(self, i):
        """Draw the state of frame i (an index into `scene.frames`)."""
        s = self.scene
        for line, (_, pl) in zip(self.bodies, s.bodies):
            line.set_data(pl[i, :, 0], pl[i, :, 1])
        for line, g in zip(self.guides, s.guides):
            line.set_data(g[i, :, 0], g[i, :, 1])
        for line, z in zip(self.springs, s.springs):
            line.set_data(z[i, :, 0], z[i, :, 1])
        pins = np.array([p[i] for p in s.pins.values()]) if s.pins else np.zeros((0, 2))
        self.pins.set_data(pins[:, 0], pins[:, 1])


def _exaggerated(scene, exaggeration) -> str:
    """", elastic deflection × k" where beams are drawn with their deflection exaggerated."""
    flexible = any(modal is not None for *_, modal in scene.problem.drawing)
    return f" (elastic deflection × {exaggeration:g})" if flexible and exaggeration != 1.0 \
        else ""


def _axes(ax, scene, title):
    (x0, x1), (y0, y1) = scene.limits()
    ax.set_xlim(x0, x1)
    ax.set_ylim(y0, y1)
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.grid(True, alpha=0.3)
    ax.set_title(title)


def plot_motion(result, path=None, trace=(), snapshots=6, exaggeration=1.0, ax=None):
    """`snapshots` states evenly over the result (the earlier ones faded) with the whole
    paths of the `trace` points [(body, local point), …]. Returns the Figure."""
    k = np.unique(np.round(np.linspace(0, len(result.t) - 1, max(snapshots, 1))).astype(int))
    scene = Scene(result, k, trace, exaggeration)
    if ax is None:
        from .plots import new_figure
        ax = new_figure((6.4, 5.4)).add_subplot()
    fig = ax.figure
    for i in range(len(k)):
        Artists(ax, scene, faded=i < len(k) - 1).show(i)
    for j, (label, xy) in enumerate(scene.traces):
        ax.plot(xy[:, 0], xy[:, 1], "--", lw=1, color=f"C{(j + 5) % 10}", label=f"path of {label}")
    _axes(ax, scene, f"{scene.problem.title}: {len(k)} states, t = {result.t[0]:.3g} … "
                     f"{result.t[-1]:.3g} s" + _exaggerated(scene, exaggeration))
    ax.legend(loc="best", fontsize="x-small")
    literal_text(fig)
    if path is not None:
        save_figure(fig, path)
    return fig


def animate(result, path, trace=(), fps=30, exaggeration=1.0, max_frames=None) -> Path:
    """Write the motion to `path`: a GIF (Pillow) or an MP4 (ffmpeg, where installed), at
    `fps` frames a second, decimated to at most fps × MAX_SECONDS frames (or `max_frames`),
    with the `trace` points' paths drawn as they are covered. Returns the path.

    A GIF's still parts (axes, ticks, legend, time bar) are drawn once and each frame
    redraws only the moving lines over them (blitting); its frames share the first one's
    palette, and each stores only the pixels that changed (`gif_bytes`). An MP4 is drawn
    whole, frame by frame, by matplotlib's ffmpeg writer."""
    from matplotlib import animation
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in (".gif", ".mp4"):
        raise ValueError(f"animate: the file must end in .gif or .mp4, got {str(path)!r}")
    if suffix == ".mp4" and not animation.writers.is_available("ffmpeg"):
        raise ValueError("animate: writing MP4 needs ffmpeg, which is not installed; "
                         "write a .gif instead")
    if suffix == ".gif":
        data = animation_gif(result, trace, fps, exaggeration, max_frames).data
        return written(path, lambda p: Path(p).write_bytes(data))
    fig, show, _, count = _render(result, trace, fps, exaggeration, max_frames)

    def mp4(p):
        writer = animation.FFMpegWriter(fps=fps)
        with writer.saving(fig, p, dpi=fig.dpi):
            for i in range(count):
                show(i)
                writer.grab_frame()
    return written(path, mp4, shared=True)           # ffmpeg writes from its own process


class Animation:
    """A result's motion as a looping GIF held in memory (`SimulationResult.animation`):
    shown inline in Jupyter (`_repr_html_`), written with `save(path)`. `data` is the
    GIF's bytes, `frames` its frame count, `fps` its rate, `pace` the simulated seconds
    it shows per second of playing (1: real time)."""

    def __init__(self, data: bytes, frames: int, fps: float, pace: float, title: str):
        self.data, self.frames, self.fps, self.pace, self.title = data, frames, fps, pace, title

    def save(self, path) -> Path:
        """The GIF at `path` (which must end in .gif); returns the path."""
        path = Path(path)
        if path.suffix.lower() != ".gif":
            raise ValueError(f"Animation.save: the file must end in .gif, got {str(path)!r}")
        return written(path, lambda p: Path(p).write_bytes(self.data))

    def _repr_html_(self) -> str:
        import base64
        import html
        return (f'<img src="data:image/gif;base64,{base64.b64encode(self.data).decode()}" '
                f'alt="{html.escape(self.title)}">')

    def __repr__(self):
        return (f"Animation({self.title!r}: {self.frames} frames at {self.fps:g} fps, "
                f"{self.pace:.3g} × real time, {len(self.data) / 1e6:.2f} MB)")


def animation_gif(result, trace=(), fps=30, exaggeration=1.0, max_frames=None) -> Animation:
    """The motion as an `Animation` (a GIF in memory), drawn as `animate` draws it."""
    _, _, frame, count = _render(result, trace, fps, exaggeration, max_frames)
    images = [frame(i) for i in range(count)]
    frames = frame_indices(result.t, fps, max_frames)
    pace = (result.t[frames[-1]] - result.t[frames[0]]) / max(len(frames) - 1, 1) * fps
    title = getattr(result.problem, "title", None) or getattr(result.mechanism, "name", "motion")
    return Animation(gif_bytes(images, fps), count, fps, pace, title)


def _render(result, trace, fps, exaggeration, max_frames):
    """(figure, show(i), frame(i) -> RGB array, number of frames) of the motion."""
    if not (isinstance(fps, numbers.Real) and 1 <= fps <= 120):
        raise ValueError(f"animate: `fps` must be between 1 and 120, got {fps!r}")
    frames = frame_indices(result.t, fps, max_frames)
    scene = Scene(result, frames, trace, exaggeration)
    speed = pace_note(result.t, frames, fps)
    fig, ax, bar = _figure()
    artists = Artists(ax, scene)
    paths = [ax.plot([], [], "--", lw=1, color=f"C{(j + 5) % 10}", label=f"path of {label}")[0]
             for j, (label, _) in enumerate(scene.traces)]
    _axes(ax, scene, " ")
    ax.legend(loc="upper right", fontsize="x-small")
    now = _time_bar(bar, result)
    clock = ax.text(0.02, 0.97, "", transform=ax.transAxes, va="top", fontsize="small")
    moving = [*artists.bodies, *artists.guides, *artists.springs, artists.pins, *paths,
              clock]
    ax.set_title(scene.problem.title + _exaggerated(scene, exaggeration))
    literal_text(fig)
    canvas = fig.canvas
    canvas.draw()                                # the layout, found once
    fig.set_layout_engine("none")
    for a in moving + [now]:
        a.set_visible(False)
    canvas.draw()
    still = canvas.copy_from_bbox(fig.bbox)
    for a in moving + [now]:
        a.set_visible(True)

    def show(i):
        artists.show(i)
        k = frames[i]
        for line, (_, xy) in zip(paths, scene.traces):
            line.set_data(xy[:k + 1, 0], xy[:k + 1, 1])
        now.set_xdata([result.t[k]])
        clock.set_text(f"t = {result.t[k]:.4f} s{speed}")

    def frame(i):
        show(i)
        canvas.restore_region(still)
        for a in moving:
            ax.draw_artist(a)
        bar.draw_artist(now)
        return np.asarray(canvas.buffer_rgba())[..., :3].copy()

    return fig, show, frame, len(frames)


def gif_bytes(images, fps) -> bytes:
    """A looping GIF of the RGB arrays `images` through Pillow (which matplotlib requires),
    every frame mapped onto the first one's adaptive palette (255 colours), saved with
    Pillow's optimization, which stores of each frame only the pixels that changed (the
    four-bar scene's 360 frames: 3.1 MB without it, 1.0 MB with it)."""
    import io

    from PIL import Image
    palette = Image.fromarray(images[0]).quantize(colors=255,
                                                  method=Image.Quantize.MEDIANCUT)
    frames = [Image.fromarray(image).quantize(palette=palette, dither=Image.Dither.NONE)
              for image in images]
    out = io.BytesIO()
    frames[0].save(out, format="GIF", save_all=True, append_images=frames[1:],
                   duration=round(1000 / fps), loop=0, optimize=True)
    return out.getvalue()
