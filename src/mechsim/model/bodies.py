"""Bodies: the ground and planar rigid bodies with their frame at the centre of mass."""

from __future__ import annotations

import math

import numpy as np

from . import parameters as dual
from .checks import ModelError, rotation, scalar, scalar_exact, vector2, vector2_exact


class Body:
    """Base of everything joints and forces attach to.

    A body owns `coordinate_names` (suffixes of its generalized coordinates, in order) and an
    initial state given by the user: a guess that `Mechanism.assemble` makes consistent.
    """

    coordinate_names: tuple[str, ...] = ()

    def __init__(self, name: str):
        if not isinstance(name, str) or not name.strip():
            raise ModelError(f"a body needs a non-empty name, got {name!r}")
        self.name = name
        # Every body exposes its initial frame (position of the frame origin and its angle)
        # so that joints can turn global attachment points into body-fixed ones.
        self.position = np.zeros(2)
        self.angle = 0.0

    # The frame as given, Parameters and numbers computed from them kept
    # (`mechsim.model.parameters`): what the joints' geometry is computed from. A body
    # whose arguments take no parameters has its plain numbers there.
    _given_position = _given_angle = None

    @property
    def exact_position(self):
        return self.position if self._given_position is None else self._given_position

    @property
    def exact_angle(self):
        return self.angle if self._given_angle is None else self._given_angle

    def local_point(self, global_point) -> np.ndarray:
        """Body-fixed coordinates of a point given globally in the initial configuration."""
        return rotation(self.angle).T @ (np.asarray(global_point, float) - self.position)

    def local_direction(self, global_direction) -> np.ndarray:
        return rotation(self.angle).T @ np.asarray(global_direction, float)

    def exact_local_point(self, global_point) -> np.ndarray:
        """`local_point` carrying the derivatives of a point or a body frame that depends
        on Parameters (an object array of Duals then; the float array otherwise)."""
        if not (dual.is_exact(global_point) or self._exact_frame):
            return self.local_point(global_point)
        d = np.asarray(global_point, dtype=object) - np.asarray(self.exact_position, dtype=object)
        return dual.rotation(dual.lift(self.exact_angle)).T @ d

    def exact_local_direction(self, global_direction) -> np.ndarray:
        """`local_direction` carrying derivatives (see `exact_local_point`)."""
        if not (dual.is_exact(global_direction) or self._exact_frame):
            return self.local_direction(global_direction)
        return dual.rotation(dual.lift(self.exact_angle)).T @ \
            np.asarray(global_direction, dtype=object)

    @property
    def _exact_frame(self) -> bool:
        return dual.is_exact(self.exact_position) or dual.is_exact(self.exact_angle)

    def exact_numbers(self) -> list:
        """The numbers as given that may be Parameters or computed from them."""
        return [self._given_position, self._given_angle]

    def exact_initial_state(self) -> tuple[list, list]:
        """(initial coordinates, initial velocities) as given, as lists whose entries are
        Duals where they depend on Parameters (floats here; a rigid body's take them)."""
        return list(self.initial_coordinates), list(self.initial_velocities)

    def refresh_numbers(self) -> None:
        """Take the numbers computed from Parameters again (after
        `mechsim.model.parameters.refresh`), checked as when built."""
        owner = f"body '{self.name}'"
        if self._given_position is not None:
            self.position = vector2(dual.values(self._given_position), "position", owner)
        if self._given_angle is not None:
            self.angle = scalar(dual.value_of(self._given_angle), "angle", owner)

    # Hooks for bodies whose points move relative to their frame (flexible beams); a rigid
    # body's points do not.
    def attachment_parameter_names(self, role: str) -> tuple[str, ...]:
        """Names of the extra joint parameters of a point on this body (side `role`)."""
        return ()

    def attachment_values(self, local, who: str) -> tuple[float, ...]:
        """Values of those parameters at body point `local`; raises if it cannot attach."""
        return ()

    def point_modes(self, local, who: str = "") -> np.ndarray | None:
        """(2, k) modal displacement of body point `local` per unit η (None: rigid)."""
        return None

    def initial_node_rotation(self, local) -> float:
        """Rotation of the material at `local` relative to the frame, initially."""
        return 0.0

    def __repr__(self):
        return f"{type(self).__name__}({self.name!r})"


class Ground(Body):
    """The fixed body: no coordinates, frame at the origin."""

    def __init__(self, name: str = "ground"):
        super().__init__(name)
        self.position = np.zeros(2)
        self.angle = 0.0


class RigidBody(Body):
    """A planar rigid body with coordinates (x, y, angle) of its centre of mass.

    Parameters
    ----------
    name : str
    mass : float, kg, > 0
    inertia : float, kg·m², about the centre of mass; > 0, or 0 for a point mass that cannot
        turn (held by prismatic joints to the ground: a slider block; `point_mass`)
    position, velocity : 2-vectors, initial state of the centre of mass
    angle, angular_velocity : float, rad and rad/s
    """

    coordinate_names = ("x", "y", "angle")

    def __init__(self, name: str, mass: float, inertia: float, position=(0.0, 0.0),
                 angle: float = 0.0, velocity=(0.0, 0.0), angular_velocity: float = 0.0):
        super().__init__(name)
        owner = f"body '{name}'"
        self.mass, exact_mass = scalar_exact(mass, "mass", owner, positive=True)
        self.inertia, exact_inertia = scalar_exact(inertia, "inertia", owner, nonnegative=True)
        self.position, self._given_position = vector2_exact(position, "position", owner)
        self.angle, self._given_angle = scalar_exact(angle, "angle", owner)
        # The initial velocities take Parameters too (a scene's speeds written from its
        # lengths); a run starts from their values.
        self.velocity, self._given_velocity = vector2_exact(velocity, "velocity", owner)
        self.angular_velocity, self._given_rate = scalar_exact(angular_velocity,
                                                               "angular_velocity", owner)
        self.exact_mass, self.exact_inertia = exact_mass, exact_inertia
        # The body's boundary in its frame, closed, where a shape constructor knows it
        # (rectangle, disc, polygon): what drawings and exports show of it.
        self.outline: np.ndarray | None = None

    @classmethod
    def rod(cls, name: str, start, end, mass: float, velocity=(0.0, 0.0),
            angular_velocity: float = 0.0) -> "RigidBody":
        """A uniform slender rod from `start` to `end` (inertia m L²/12 about its middle)."""
        owner = f"body '{name}'"
        (a, ea), (b, eb) = vector2_exact(start, "start", owner), vector2_exact(end, "end", owner)
        length = float(np.hypot(*(b - a)))
        if not length > 0.0:
            raise ModelError(f"{owner}: rod `start` and `end` coincide at {a.tolist()}")
        m, em = scalar_exact(mass, "mass", owner, positive=True)
        if dual.is_exact([ea, eb, em]):          # a rod sized by Parameters
            d = eb - ea
            long = dual.hypot(d[0], d[1])
            return cls(name, mass=em, inertia=em * long * long / 12.0,
                       position=(ea + eb) / 2.0, angle=dual.atan2(d[1], d[0]),
                       velocity=velocity, angular_velocity=angular_velocity)
        return cls(name, mass=m, inertia=m * length * length / 12.0, position=(a + b) / 2.0,
                   angle=math.atan2(b[1] - a[1], b[0] - a[0]), velocity=velocity,
                   angular_velocity=angular_velocity)

    @classmethod
    def point_mass(cls, name: str, position, mass: float, velocity=(0.0, 0.0)) -> "RigidBody":
        """A mass without rotational inertia at `position` (a slider, a piston, a block whose
        size does not matter). Its rotation must be held by the joints: it slides on a
        prismatic joint to the ground, or to a body so held (the mechanism's build refuses
        it otherwise, naming it); since it then never turns, the motion is exact."""
        return cls(name, mass=mass, inertia=0.0, position=position, velocity=velocity)

    @classmethod
    def rectangle(cls, name: str, center, width: float, height: float, mass: float,
                  angle: float = 0.0, velocity=(0.0, 0.0),
                  angular_velocity: float = 0.0) -> "RigidBody":
        """A uniform rectangular plate (a slider block, a link of some width) centred at
        `center`, `width` along its x axis turned by `angle`: inertia m (w² + h²)/12."""
        owner = f"body '{name}'"
        w = scalar(width, "width", owner, positive=True)
        h = scalar(height, "height", owner, positive=True)
        m = scalar(mass, "mass", owner, positive=True)
        body = cls(name, mass=m, inertia=m * (w * w + h * h) / 12.0,
                   position=vector2(center, "center", owner), angle=angle,
                   velocity=velocity, angular_velocity=angular_velocity)
        body.outline = np.array([[-w, -h], [w, -h], [w, h], [-w, h], [-w, -h]]) / 2.0
        return body

    @classmethod
    def disc(cls, name: str, center, radius: float, mass: float, velocity=(0.0, 0.0),
             angular_velocity: float = 0.0) -> "RigidBody":
        """A uniform disc (a flywheel, a crank disc) centred at `center`: inertia m r²/2."""
        owner = f"body '{name}'"
        r = scalar(radius, "radius", owner, positive=True)
        m = scalar(mass, "mass", owner, positive=True)
        body = cls(name, mass=m, inertia=m * r * r / 2.0,
                   position=vector2(center, "center", owner), velocity=velocity,
                   angular_velocity=angular_velocity)
        around = np.linspace(0.0, 2.0 * np.pi, 33)
        body.outline = r * np.column_stack([np.cos(around), np.sin(around)])
        return body

    @classmethod
    def polygon(cls, name: str, vertices, mass: float, velocity=(0.0, 0.0),
                angular_velocity: float = 0.0) -> "RigidBody":
        """A uniform plate bounded by the simple polygon `vertices` (global points in order,
        either way round; a ternary link through its three joints): its frame at the
        area's centroid with axes along the global ones, its inertia about the centroid
        from the polygon's second moment of area (the shoelace sums)."""
        owner = f"body '{name}'"
        try:
            pts = np.array([vector2(p, f"vertices[{k}]", owner)
                            for k, p in enumerate(vertices)])
        except TypeError:
            raise ModelError(f"{owner}: `vertices` must be a list of 2-vectors") from None
        if len(pts) < 3:
            raise ModelError(f"{owner}: a polygon needs at least 3 `vertices`, got {len(pts)}")
        m = scalar(mass, "mass", owner, positive=True)
        x, y = pts[:, 0], pts[:, 1]
        xn, yn = np.roll(x, -1), np.roll(y, -1)
        cross = x * yn - xn * y
        area = cross.sum() / 2.0
        if not abs(area) > 1e-12 * max(1.0, float(np.ptp(pts)) ** 2):
            raise ModelError(f"{owner}: the polygon's `vertices` enclose no area")
        centroid = np.array([((x + xn) * cross).sum(), ((y + yn) * cross).sum()]) / (6 * area)
        polar = (cross * (x * x + x * xn + xn * xn + y * y + y * yn + yn * yn)).sum() / 12.0
        about_centroid = polar / area - centroid @ centroid     # per unit area, > 0
        body = cls(name, mass=m, inertia=m * about_centroid, position=centroid,
                   velocity=velocity, angular_velocity=angular_velocity)
        body.outline = np.vstack([pts, pts[:1]]) - centroid
        return body

    def exact_numbers(self) -> list:
        return super().exact_numbers() + [self.exact_mass, self.exact_inertia,
                                          self._given_velocity, self._given_rate]

    def refresh_numbers(self) -> None:
        super().refresh_numbers()
        owner = f"body '{self.name}'"
        self.velocity = vector2(dual.values(self._given_velocity), "velocity", owner)
        self.angular_velocity = scalar(dual.value_of(self._given_rate), "angular_velocity",
                                       owner)
        self.mass = scalar(dual.value_of(self.exact_mass), "mass", owner, positive=True)
        self.inertia = scalar(dual.value_of(self.exact_inertia), "inertia", owner,
                              nonnegative=True)

    @property
    def initial_coordinates(self) -> np.ndarray:
        return np.array([self.position[0], self.position[1], self.angle])

    def exact_initial_state(self) -> tuple[list, list]:
        position, velocity = self.exact_position, self._given_velocity
        return ([position[0], position[1], self.exact_angle],
                [velocity[0], velocity[1], self._given_rate])

    @property
    def initial_velocities(self) -> np.ndarray:
        return np.array([self.velocity[0], self.velocity[1], self.angular_velocity])

    @property
    def mass_diagonal(self) -> np.ndarray:
        return np.array([self.mass, self.mass, self.inertia])
