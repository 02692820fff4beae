"""What a joint writes its equations against: the geometry of body frames and their points.

`JointContext` holds the formulas (a point's global position, a body-fixed direction, a
node's angle on a flexible beam); a subclass supplies the frames (`frame`, `modal`) and the
trigonometry (`cos`, `sin`) in its own kind of number: sympy symbols for the generated
constraint equations (`mechsim.symbolic.constraints.SymbolicContext`), or dual numbers over
many states for joint coordinates and reactions (`mechsim.problem.geometry`). A joint
only does arithmetic on what the context hands it, so the same `equations` serve both.
"""

from __future__ import annotations


class JointContext:
    """Base of the contexts joints see. Subclasses implement `frame(body)` -> (x, y, θ),
    `modal(body)` -> the modal amplitudes η (empty for a rigid body), and `cos`, `sin`."""

    def frame(self, body):
        raise NotImplementedError

    def modal(self, body):
        raise NotImplementedError

    def cos(self, x):
        raise NotImplementedError

    def sin(self, x):
        raise NotImplementedError

    def angle(self, body, p=None, role=None):
        """Angle of the body's frame; at an attachment (`p`, `role`, see `point`) of a
        flexible body it includes the modal rotation of that node."""
        th = self.frame(body)[2]
        for k, eta in enumerate(self.modal(body) if p is not None else (), start=1):
            th = th + eta * p[f"{role}_r{k}"]
        return th

    def direction(self, body, ux, uy, p=None, role=None):
        """A body-fixed direction (ux, uy) in global components."""
        th = self.angle(body, p, role)
        c, s = self.cos(th), self.sin(th)
        return [c * ux - s * uy, s * ux + c * uy]

    def point(self, body, sx, sy, p=None, role=None):
        """Global position of the body-fixed point (sx, sy). On a flexible body the point
        moves with the modes: pass the joint's parameters `p` and the side `role` ("a" or
        "b") whose mode-shape parameters `<role>_u<k>`, `<role>_v<k>` belong to the point."""
        x, y, th = self.frame(body)
        for k, eta in enumerate(self.modal(body) if p is not None else (), start=1):
            sx = sx + eta * p[f"{role}_u{k}"]
            sy = sy + eta * p[f"{role}_v{k}"]
        c, s = self.cos(th), self.sin(th)
        return [x + c * sx - s * sy, y + s * sx + c * sy]
