"""Point kinematics of a body frame in absolute coordinates: where a body-fixed point is, how
fast it moves, and the generalized force of a point force on it.

A body's coordinates start at index `start` of q as (x, y, θ) of its frame, followed on a
flexible body by its modal amplitudes η₁ … η_k; a point's local position s moves with the
modes by `modal` (2, k) · η. `start` None is the ground (the point is fixed).

Two forms of the same formulas: vectorized ones over leading dimensions of q (results,
exports, energies over a whole run) and scalar ones on plain floats for one state (the
forces inside a right-hand side, where numpy's per-call cost exceeds the arithmetic).
"""

from __future__ import annotations

import math

import numpy as np


# --- vectorized: q of shape (..., n), results (..., 2) ---------------------------------------
def _local(q, start, s, modal):
    """Body-frame position of attachment point `s`, moved by the modal displacement
    `modal` (2, k) · η for a point of a flexible body."""
    s = np.asarray(s, float)
    if modal is None:
        return np.broadcast_to(s, q.shape[:-1] + (2,))
    k = modal.shape[1]
    return s + q[..., start + 3:start + 3 + k] @ modal.T


def frame_point(q: np.ndarray, start: int | None, s, modal=None) -> np.ndarray:
    """Global position of body-fixed point `s` of the body whose (x, y, angle) start at
    index `start` of `q` (None: the ground); on a flexible body `modal` (2, k) adds the
    point's modal displacement. `q` has shape (..., n); result (..., 2)."""
    if start is None:
        return np.broadcast_to(np.asarray(s, float), q.shape[:-1] + (2,)).copy()
    u = _local(q, start, s, modal)
    th = q[..., start + 2]
    c, sn = np.cos(th), np.sin(th)
    return np.stack([q[..., start] + c * u[..., 0] - sn * u[..., 1],
                     q[..., start + 1] + sn * u[..., 0] + c * u[..., 1]], axis=-1)


def frame_point_velocity(q: np.ndarray, v: np.ndarray, start: int | None, s,
                         modal=None) -> np.ndarray:
    """Velocity of body-fixed point `s`: Ṙ + ω × (A ū) + A (modal · η̇). Shapes as in
    `frame_point`."""
    if start is None:
        return np.zeros(q.shape[:-1] + (2,))
    u = _local(q, start, s, modal)
    th, w = q[..., start + 2], v[..., start + 2]
    c, sn = np.cos(th), np.sin(th)
    dx = -w * (sn * u[..., 0] + c * u[..., 1])
    dy = w * (c * u[..., 0] - sn * u[..., 1])
    if modal is not None:
        du = v[..., start + 3:start + 3 + modal.shape[1]] @ modal.T
        dx = dx + c * du[..., 0] - sn * du[..., 1]
        dy = dy + sn * du[..., 0] + c * du[..., 1]
    return np.stack([v[..., start] + dx, v[..., start + 1] + dy], axis=-1)


def frame_point_acceleration(q: np.ndarray, v: np.ndarray, a: np.ndarray, start: int | None,
                             s, modal=None) -> np.ndarray:
    """Acceleration of body-fixed point `s`: R̈ + α × (A u) − ω² A u + 2 ω × (A u̇) + A ü,
    u the point in the body's frame (modal · η added on a flexible body, u̇ and ü its
    rates). Shapes as in `frame_point`; `a` the accelerations q̈ like v."""
    if start is None:
        return np.zeros(q.shape[:-1] + (2,))
    u = _local(q, start, s, modal)
    th, w, alpha = q[..., start + 2], v[..., start + 2], a[..., start + 2]
    c, sn = np.cos(th), np.sin(th)

    def turned(x, y):                 # A (x, y) and A S (x, y), S a quarter turn
        return (c * x - sn * y, sn * x + c * y), (-sn * x - c * y, c * x - sn * y)

    (ax_, ay_), (sx, sy) = turned(u[..., 0], u[..., 1])
    out_x = a[..., start] + alpha * sx - w * w * ax_
    out_y = a[..., start + 1] + alpha * sy - w * w * ay_
    if modal is not None:
        k = modal.shape[1]
        du = v[..., start + 3:start + 3 + k] @ modal.T
        ddu = a[..., start + 3:start + 3 + k] @ modal.T
        _, (dsx, dsy) = turned(du[..., 0], du[..., 1])
        (ddx, ddy), _ = turned(ddu[..., 0], ddu[..., 1])
        out_x = out_x + 2.0 * w * dsx + ddx
        out_y = out_y + 2.0 * w * dsy + ddy
    return np.stack([out_x, out_y], axis=-1)


def drawn_points(q: np.ndarray, start: int | None, local, modal=None,
                 scale: float = 1.0) -> np.ndarray:
    """(K, p, 2) global positions of a body's drawing points `local` (p, 2) at the states
    q (K, n); `modal` (p, 2, k) their mode shapes (None: rigid), scaled by `scale` (a
    drawing's exaggeration of the elastic displacement)."""
    out = np.empty((q.shape[0], len(local), 2))
    for i, s in enumerate(local):
        out[:, i] = frame_point(q, start, s, None if modal is None else scale * modal[i])
    return out


# --- scalar: one state q of shape (n,), results as tuples of floats ----------------------------
def _moved(q, start, s, modal):
    if modal is None:
        return s
    d = modal @ q[start + 3:start + 3 + modal.shape[1]]
    return (s[0] + d[0], s[1] + d[1])


def point(q, start, s, modal=None) -> tuple[float, float]:
    """`frame_point` of one state, as a pair of floats."""
    if start is None:
        return s
    s = _moved(q, start, s, modal)
    c, sn = math.cos(q[start + 2]), math.sin(q[start + 2])
    return (q[start] + c * s[0] - sn * s[1], q[start + 1] + sn * s[0] + c * s[1])


def point_velocity(q, v, start, s, modal=None) -> tuple[float, float]:
    """`frame_point_velocity` of one state, as a pair of floats."""
    if start is None:
        return (0.0, 0.0)
    s = _moved(q, start, s, modal)
    c, sn = math.cos(q[start + 2]), math.sin(q[start + 2])
    w = v[start + 2]
    vx, vy = v[start] - w * (sn * s[0] + c * s[1]), v[start + 1] + w * (c * s[0] - sn * s[1])
    if modal is not None:
        du = modal @ v[start + 3:start + 3 + modal.shape[1]]
        vx, vy = vx + c * du[0] - sn * du[1], vy + sn * du[0] + c * du[1]
    return (vx, vy)


def add_point_force(Q, q, start, s, fx, fy, modal=None) -> None:
    """Add to Q (n,) the generalized force of a point force (fx, fy) at body point `s`: on
    the frame's position the force, on its angle the moment about the frame origin, on the
    modal amplitudes its work through the point's mode shapes."""
    if start is None:
        return
    s = _moved(q, start, s, modal)
    c, sn = math.cos(q[start + 2]), math.sin(q[start + 2])
    rx, ry = c * s[0] - sn * s[1], sn * s[0] + c * s[1]
    Q[start] += fx
    Q[start + 1] += fy
    Q[start + 2] += rx * fy - ry * fx
    if modal is not None:
        k = modal.shape[1]
        Q[start + 3:start + 3 + k] += modal.T @ (c * fx + sn * fy, -sn * fx + c * fy)
