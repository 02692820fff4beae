"""Ready mechanisms, built in a few lines each. They double as test fixtures and as the
Python twins of the scene files in `mechanisms/`.

>>> import mechsim as ms
>>> ms.examples.four_bar().dof().dof
1
"""

from __future__ import annotations

import math

import numpy as np

from .facade import Mechanism
from .model import (Driver, FlexibleBeam, Prismatic, Revolute, RigidBody, Spring,
                    Torque)


def four_bar(tilt: float = math.radians(10.0), length: float = 1.0, mass: float = 1.0,
             gravity=(0.0, -9.81)) -> Mechanism:
    """The seed paper's falling parallelogram: crank = coupler = rocker = ground = `length`,
    uniform slender rods of `mass`, released at rest with the cranks `tilt` above horizontal.
    Singular (all bars aligned) when the cranks pass horizontal."""
    mech = Mechanism("four-bar", gravity=gravity)
    c, s = length * math.cos(tilt), length * math.sin(tilt)
    coupler = RigidBody.rod("coupler", (c, s), (length + c, s), mass)
    return _parallelogram(mech, coupler, tilt, length, mass)


def _parallelogram(mech, coupler, tilt, length, link_mass, crank_mass=None) -> Mechanism:
    """Crank and rocker rods of `link_mass` (the crank of `crank_mass` if given) at `tilt`,
    joined by `coupler` (already built, rigid or elastic): the seed's falling four-bar with
    joints A, B, C, D."""
    c, s = length * math.cos(tilt), length * math.sin(tilt)
    crank = mech.add(RigidBody.rod("crank", (0.0, 0.0), (c, s),
                                   link_mass if crank_mass is None else crank_mass))
    mech.add(coupler)
    rocker = mech.add(RigidBody.rod("rocker", (length, 0.0), (length + c, s), link_mass))
    mech.add(Revolute(mech.ground, crank, at=(0.0, 0.0), name="A"))
    mech.add(Revolute(crank, coupler, at=(c, s), name="B"))
    mech.add(Revolute(coupler, rocker, at=(length + c, s), name="C"))
    mech.add(Revolute(mech.ground, rocker, at=(length, 0.0), name="D"))
    return mech


def flexible_four_bar(youngs_modulus: float = 117e9, density: float = 8910.0,
                      width: float = 0.01, n_elements: int = 10, n_modes: int = 2,
                      tilt: float = math.radians(10.0), length: float = 1.0,
                      link_mass: float = 1.0, damping_ratio: float = 0.0,
                      rigid: bool = False, gravity=(0.0, -9.81),
                      crank_mass: float | None = None) -> Mechanism:
    """The seed's flexible four-bar: the falling parallelogram of `four_bar` with the coupler
    an elastic beam (square section `width`, copper by default: E = 117 GPa, ρ = 8910 kg/m³;
    10 elements, 2 pinned–pinned modes); crank and rocker rigid rods of `link_mass` (the
    crank of `crank_mass` if given). With `rigid=True` the coupler is a rigid rod of the
    same mass (the rigid limit)."""
    mech = Mechanism("flexible four-bar" if not rigid else "four-bar (rigid coupler)",
                     gravity=gravity)
    c, s = length * math.cos(tilt), length * math.sin(tilt)
    area = width * width
    if rigid:
        coupler = RigidBody.rod("coupler", (c, s), (length + c, s), density * area * length)
    else:
        coupler = FlexibleBeam("coupler", length=length, youngs_modulus=youngs_modulus,
                               density=density, area=area, second_moment=width**4 / 12.0,
                               n_elements=n_elements, n_modes=n_modes, start=(c, s), angle=0.0,
                               damping_ratio=damping_ratio)
    return _parallelogram(mech, coupler, tilt, length, link_mass, crank_mass)


def double_four_bar(n: int = 2, length: float = 1.0, mass: float = 1.0,
                    crank_speed: float = -1.0, gravity=(0.0, -9.81)) -> Mechanism:
    """IFToMM benchmark A02 (N four-bars in a row): N+1 vertical cranks at x = 0, L, …, NL and
    N horizontal couplers, all uniform rods of `mass`; cranks turn at `crank_speed` rad/s
    (−1: tips moving at +1 m/s). On the parallelogram branch every crank has the same angle
    θ with M_eff θ̈ = −K cos θ (see `parallelogram_exact`). `mass` may also be a sequence
    of 2N + 1 masses, the cranks' first, then the couplers' (numbers or Parameters)."""
    if n < 1:
        raise ValueError(f"`n` must be at least 1, got {n}")
    masses = list(mass) if isinstance(mass, (list, tuple)) else [mass] * (2 * n + 1)
    if len(masses) != 2 * n + 1:
        raise ValueError(f"`mass`: one number, or 2n + 1 = {2 * n + 1} of them (cranks, then "
                         f"couplers), got {len(masses)}")
    mech = Mechanism(f"{n}-window four-bar" if n != 2 else "double four-bar", gravity=gravity)
    w = crank_speed
    cranks = []
    for i in range(n + 1):
        x = i * length
        crank = mech.add(RigidBody.rod(f"crank{i + 1}", (x, 0.0), (x, length), masses[i],
                                       velocity=(-w * length / 2, 0.0), angular_velocity=w))
        mech.add(Revolute(mech.ground, crank, at=(x, 0.0), name=f"A{i + 1}"))
        cranks.append(crank)
    for i in range(n):
        x = i * length
        coupler = mech.add(RigidBody.rod(f"coupler{i + 1}", (x, length), (x + length, length),
                                         masses[n + 1 + i], velocity=(-w * length, 0.0)))
        mech.add(Revolute(cranks[i], coupler, at=(x, length), name=f"B{i + 1}"))
        mech.add(Revolute(coupler, cranks[i + 1], at=(x + length, length), name=f"C{i + 1}"))
    return mech


def parallelogram_constants(n: int = 1, length: float = 1.0, mass: float = 1.0,
                            g: float = 9.81) -> tuple[float, float]:
    """(M_eff, K) of the parallelogram branch M_eff θ̈ = −K cos θ for N windows of uniform
    rods: M_eff = (N+1) m L²/3 + N m L², K = g ((N+1) m L/2 + N m L)."""
    m_eff = (n + 1) * mass * length**2 / 3.0 + n * mass * length**2
    k = g * ((n + 1) * mass * length / 2.0 + n * mass * length)
    return m_eff, k


def parallelogram_exact(t, theta0: float, omega0: float, n: int = 1, length: float = 1.0,
                        mass: float = 1.0, g: float = 9.81, rtol: float = 1e-13):
    """Crank angle θ(t) and rate θ̇(t) on the parallelogram branch, integrated independently
    (scipy DOP853 at `rtol` on the 1-DOF equation). Returns arrays shaped like `t`."""
    from scipy.integrate import solve_ivp
    m_eff, k = parallelogram_constants(n, length, mass, g)
    t = np.atleast_1d(np.asarray(t, float))
    sol = solve_ivp(lambda _, y: [y[1], -k / m_eff * math.cos(y[0])], (0.0, float(t.max())),
                    [theta0, omega0], method="DOP853", rtol=rtol, atol=rtol * 1e-3,
                    t_eval=t, dense_output=False)
    return sol.y[0], sol.y[1]


def slider_crank(crank_length: float = 0.15, rod_length: float = 0.30,
                 crank_mass: float = 0.36, rod_mass: float = 7870.0 * 0.008**2 * 0.30,
                 slider_mass: float = 0.075552, crank_angle: float = 0.0,
                 crank_speed: float = 150.0, driven: bool = False,
                 gravity=(0.0, -9.81), flexible: bool = False, n_elements: int = 10,
                 n_modes: int = 2, youngs_modulus: float = 2e11, density: float = 7870.0,
                 width: float = 0.008, damping_ratio: float = 0.0) -> Mechanism:
    """An in-line slider-crank (crank pivot at the origin, slider on the x axis), rigid rods.
    Defaults: the dimensions of the seed's flexible slider-crank (crank 0.15 m, rod 0.30 m of
    8 mm × 8 mm steel, slider 0.075552 kg). The crank starts at `crank_angle` turning at
    `crank_speed`; with `driven=True` a driver holds that speed, otherwise it runs free and
    passes its dead centres on its own inertia. With `flexible=True` the rod is an elastic
    beam (square section `width`, pinned–pinned modes, modal `damping_ratio`) whose mass
    follows from its density."""
    r, l = crank_length, rod_length
    if not r < l:
        raise ValueError(f"slider-crank: crank ({r}) must be shorter than the rod ({l})")
    mech = Mechanism("slider-crank", gravity=gravity)
    th, w = crank_angle, crank_speed
    b = np.array([r * math.cos(th), r * math.sin(th)])
    phi = math.asin(-r * math.sin(th) / l)                        # rod angle
    c = np.array([b[0] + l * math.cos(phi), 0.0])
    phid = -r * math.cos(th) * w / (l * math.cos(phi))
    vb = w * r * np.array([-math.sin(th), math.cos(th)])
    e_rod = np.array([-math.sin(phi), math.cos(phi)])
    crank = mech.add(RigidBody.rod("crank", (0.0, 0.0), b, crank_mass,
                                   velocity=vb / 2, angular_velocity=w))
    if flexible:
        rod = mech.add(FlexibleBeam("rod", length=l, youngs_modulus=youngs_modulus,
                                    density=density, area=width**2, second_moment=width**4 / 12,
                                    n_elements=n_elements, n_modes=n_modes, start=b, angle=phi,
                                    velocity=vb, angular_velocity=phid,
                                    damping_ratio=damping_ratio))
        mech.name = "flexible slider-crank"
    else:
        rod = mech.add(RigidBody.rod("rod", b, c, rod_mass, velocity=vb + phid * l / 2 * e_rod,
                                     angular_velocity=phid))
    block = 0.02                                                  # slider block edge, m
    slider = mech.add(RigidBody("slider", mass=slider_mass, inertia=slider_mass * block**2 / 6,
                                position=c, velocity=(vb + phid * l * e_rod)[0] * np.array([1.0, 0.0])))
    crank_pin = mech.add(Revolute(mech.ground, crank, at=(0.0, 0.0), name="O"))
    mech.add(Revolute(crank, rod, at=b, name="A"))
    mech.add(Revolute(rod, slider, at=c, name="B"))
    mech.add(Prismatic(mech.ground, slider, axis=(1.0, 0.0), at=c, name="slide"))
    if driven:
        mech.add(Driver(crank_pin, f"{float(w)!r}*t"))
    return mech


def coupler_four_bar(a, b, c, d, px, py, theta0, branch=1, origin=(0.0, 0.0),
                     tilt=0.0) -> Mechanism:
    """A path-generating four-bar: crank `a` from the ground pivot `origin` at angle
    `theta0` (from the x axis), coupler `b`, rocker `c` to the ground pivot `d` from
    `origin` along the direction `tilt` (default (d, 0)), assembled on the branch with the
    coupler–rocker pin left of the line from the crank pin to the rocker's pivot (`branch`
    1; −1: right of it); the coupler body's frame is its tracing point, `px` along the
    coupler from the crank pin and `py` across it (its mass does not enter a kinematic
    analysis). The crank is driven by "motor" (law t: the crank's turn from theta0). Each
    argument a number or a Parameter (numpy's functions carry them): path synthesis
    (`mechsim.design.PathPoints`), where `origin` and `tilt` place the linkage in the
    plane of the targets."""
    mech = Mechanism("path generator")
    ground = mech.ground
    O2 = np.array([origin[0], origin[1]])
    A = O2 + np.array([a * np.cos(theta0), a * np.sin(theta0)])
    O4 = O2 + np.array([d * np.cos(tilt), d * np.sin(tilt)])
    AO = O4 - A
    span = np.hypot(AO[0], AO[1])
    along = (b * b - c * c + span * span) / (2 * span)
    u = AO / span
    B = A + along * u + branch * np.sqrt(b * b - along * along) * np.array([-u[1], u[0]])
    th3 = np.arctan2(B[1] - A[1], B[0] - A[0])
    P = A + px * np.array([np.cos(th3), np.sin(th3)]) + \
        py * np.array([-np.sin(th3), np.cos(th3)])
    crank = mech.add(RigidBody.rod("crank", O2, A, mass=1.0))
    coupler = mech.add(RigidBody("coupler", mass=1.0, inertia=0.01, position=P,
                                 angle=th3))
    rocker = mech.add(RigidBody.rod("rocker", O4, B, mass=1.0))
    pin = mech.add(Revolute(ground, crank, at=O2))
    mech.add(Revolute(crank, coupler, at=A))
    mech.add(Revolute(coupler, rocker, at=B))
    mech.add(Revolute(rocker, ground, at=O4))
    mech.add(Driver(pin, "t", name="motor"))
    return mech


def slider_crank_position(theta, crank_length=0.15, rod_length=0.30):
    """Slider x for crank angle θ of an in-line slider-crank: r cos θ + √(l² − r² sin² θ)."""
    r, l = crank_length, rod_length
    return r * np.cos(theta) + np.sqrt(l**2 - (r * np.sin(theta)) ** 2)


def pendulum(length: float = 1.0, mass: float = 1.0, angle: float = 0.0,
             gravity=(0.0, -9.81)) -> Mechanism:
    """A uniform rod pinned at one end at the origin, drawn at `angle` from the +x axis."""
    mech = Mechanism("pendulum", gravity=gravity)
    tip = (length * math.cos(angle), length * math.sin(angle))
    rod = mech.add(RigidBody.rod("rod", (0.0, 0.0), tip, mass))
    mech.add(Revolute(mech.ground, rod, at=(0.0, 0.0), name="pivot"))
    return mech


def shaken_pendulum(omega: float = 4.0, amplitude: float = 1.5,
                    damping: float = 2.0) -> Mechanism:
    """A 0.6 m, 1 kg rod hanging from a pin, shaken by a torque `amplitude` cos(`omega` t)
    and damped by a horizontal dashpot at its tip: a mechanism with a periodic steady
    state (`Mechanism.steady_state` with period 2π/omega)."""
    mech = pendulum(length=0.6, mass=1.0, angle=-math.pi / 2)
    rod = mech.body("rod")
    mech.add(Torque(rod, lambda t: amplitude * math.cos(omega * t), name="shaker"))
    mech.add(Spring(mech.ground, rod, at_a=(0.3, -0.6), at_b=(0.0, -0.6), stiffness=0.0,
                    damping=damping, name="dashpot"))
    return mech


def spring_mass(mass: float = 2.0, stiffness: float = 800.0, stretch: float = 0.05,
                damping: float = 0.0) -> Mechanism:
    """A block on a horizontal prismatic joint, tied to the ground by a spring of rest length
    0.5 m, released `stretch` beyond its rest length."""
    mech = Mechanism("spring-mass", gravity=(0.0, 0.0))
    x0 = 0.5 + stretch
    block = mech.add(RigidBody("block", mass=mass, inertia=mass * 0.1**2 / 6, position=(x0, 0.0)))
    mech.add(Prismatic(mech.ground, block, axis=(1.0, 0.0), at=(x0, 0.0), name="slide"))
    mech.add(Spring(mech.ground, block, at_a=(0.0, 0.0), at_b=(x0, 0.0), stiffness=stiffness,
                    rest_length=0.5, damping=damping, name="spring"))
    return mech


# --- Four-bars of any proportions, and random mechanisms for studies and tests -----------------

def four_bar_angles(th2, a, b, c, d, branch=1):
    """Coupler and rocker angles (θ3, θ4) of the four-bar with ground pivots (0, 0) and
    (d, 0), crank a, coupler b, rocker c at crank angle θ2 (array-like): the coupler's far
    end is where the circles about the crank tip (radius b) and about (d, 0) (radius c)
    meet, on the side `branch` = ±1 of the line between their centres. NaN where the
    crank angle admits no assembly."""
    th2 = np.asarray(th2, float)
    ax, ay = a * np.cos(th2), a * np.sin(th2)
    dx, dy = d - ax, -ay
    span = np.hypot(dx, dy)
    with np.errstate(invalid="ignore"):
        gamma = np.arccos((b * b + span * span - c * c) / (2 * b * span))
    th3 = np.arctan2(dy, dx) + branch * gamma
    bx, by = ax + b * np.cos(th3), ay + b * np.sin(th3)
    return th3, np.arctan2(by, bx - d)


def grashof_class(a, b, c, d) -> str:
    """The Grashof class of a four-bar with crank a, coupler b, rocker c and ground d:
    "crank-rocker", "double-crank", "double-rocker", "rocker-crank" (the shortest link is
    the one named last turning fully) or "triple rocker" (non-Grashof), and "change point"
    where s + l = p + q (to 1e-12)."""
    s, *_, l = sorted((a, b, c, d))
    excess = s + l - (a + b + c + d - s - l)
    if abs(excess) <= 1e-12 * l:
        return "change point"
    if excess > 0:
        return "triple rocker"
    return {a: "crank-rocker", d: "double-crank", b: "double-rocker"}.get(s, "rocker-crank")


def general_four_bar(a, b, c, d, theta: float, speed: float = 0.0, branch: int = 1,
                     masses=(1.0, 1.0, 1.0), gravity=(0.0, -9.81),
                     name: str = "four-bar") -> Mechanism:
    """A four-bar of uniform rods (crank a from the pivot O2 at the origin, coupler b,
    rocker c from O4 at (d, 0)), assembled at crank angle `theta` on `branch` (see
    `four_bar_angles`), the crank turning at `speed` (`Mechanism.set_speed` on O2: the
    others' speeds follow at assembly). Joints O2, A (crank–coupler), B (coupler–rocker),
    O4."""
    th3, th4 = four_bar_angles(theta, a, b, c, d, branch)
    if not np.isfinite(th3):
        raise ValueError(f"four-bar {a}, {b}, {c}, {d}: no assembly at crank angle {theta}")
    tip = (a * math.cos(theta), a * math.sin(theta))
    joint = (d + c * math.cos(float(th4)), c * math.sin(float(th4)))
    mech = Mechanism(name, gravity=gravity)
    crank = mech.add(RigidBody.rod("crank", (0.0, 0.0), tip, masses[0]))
    coupler = mech.add(RigidBody.rod("coupler", tip, joint, masses[1]))
    rocker = mech.add(RigidBody.rod("rocker", (d, 0.0), joint, masses[2]))
    pivot = mech.add(Revolute(mech.ground, crank, at=(0.0, 0.0), name="O2"))
    mech.add(Revolute(crank, coupler, at=tip, name="A"))
    mech.add(Revolute(coupler, rocker, at=joint, name="B"))
    mech.add(Revolute(mech.ground, rocker, at=(d, 0.0), name="O4"))
    if speed:
        mech.set_speed(pivot, speed)
    return mech


def turning_parallelogram(a: float, b: float, theta: float, speed: float) -> Mechanism:
    """A parallelogram (crank = rocker = a, coupler = ground = b) in zero gravity, its
    cranks at `theta` turning at `speed`: they stay parallel at θ + speed·t, aligned with
    the ground (a singular configuration) at every multiple of π."""
    tip = (a * math.cos(theta), a * math.sin(theta))
    v = (-tip[1] * speed, tip[0] * speed)
    far = (b + tip[0], tip[1])
    mech = Mechanism("turning parallelogram", gravity=(0.0, 0.0))
    crank = mech.add(RigidBody.rod("crank", (0.0, 0.0), tip, 1.0, velocity=(v[0] / 2, v[1] / 2),
                                   angular_velocity=speed))
    coupler = mech.add(RigidBody.rod("coupler", tip, far, 1.0, velocity=v))
    rocker = mech.add(RigidBody.rod("rocker", (b, 0.0), far, 1.0, velocity=(v[0] / 2, v[1] / 2),
                                    angular_velocity=speed))
    mech.add(Revolute(mech.ground, crank, at=(0.0, 0.0), name="A"))
    mech.add(Revolute(crank, coupler, at=tip, name="B"))
    mech.add(Revolute(coupler, rocker, at=far, name="C"))
    mech.add(Revolute(mech.ground, rocker, at=(b, 0.0), name="D"))
    return mech


RANDOM_KINDS = ("crank-rocker", "double-crank", "double-rocker", "triple rocker",
                "slider-crank", "parallelogram")


def random_mechanism(rng: np.random.Generator, kind: str) -> tuple[Mechanism, dict]:
    """A mechanism of `kind` (one of `RANDOM_KINDS`) with proportions, start and speed drawn
    from `rng`, and the parameters drawn. Four-bars of a Grashof class (their crank turning
    at 1–6 rad/s under gravity) and slider-cranks (20–80 rad/s) carry a spring-damper (on
    the coupler's middle, on the slider); parallelograms turn in zero gravity at 1–4 rad/s
    (`turning_parallelogram`), through their aligned positions."""
    if kind == "parallelogram":
        a, b = rng.uniform(0.3, 1.5, 2)
        theta = rng.uniform(0.2, math.pi - 0.2)
        speed = rng.uniform(1.0, 4.0) * rng.choice([-1.0, 1.0])
        return turning_parallelogram(a, b, theta, speed), dict(a=a, b=b, theta=theta,
                                                               speed=speed)
    if kind == "slider-crank":
        r = rng.uniform(0.05, 0.2)
        l = r * rng.uniform(1.5, 4.0)
        theta, speed = rng.uniform(0.0, 2.0 * math.pi), rng.uniform(20.0, 80.0)
        k, c = rng.uniform(10.0, 100.0), rng.uniform(0.1, 1.0)
        mech = slider_crank(crank_length=r, rod_length=l, crank_angle=theta, crank_speed=speed)
        x = mech.body("slider").position
        mech.add(Spring(mech.ground, mech.body("slider"), at_a=(x[0] + 0.5, 0.0), at_b=x,
                        stiffness=k, damping=c, name="spring-damper"))
        return mech, dict(r=r, l=l, theta=theta, speed=speed, stiffness=k, damping=c)
    if kind not in RANDOM_KINDS:
        raise ValueError(f"unknown kind {kind!r}; kinds: {', '.join(RANDOM_KINDS)}")
    while True:
        a, b, c, d = rng.uniform(0.25, 1.2, 4)
        theta = rng.uniform(0.0, 2.0 * math.pi)
        if grashof_class(a, b, c, d) != kind:
            continue
        th3, th4 = four_bar_angles(theta, a, b, c, d)
        if np.isfinite(th3) and abs(math.sin(th3 - th4)) > 0.2:    # clear of a toggle
            break
    speed, k, damping = rng.uniform(1.0, 6.0), rng.uniform(5.0, 40.0), rng.uniform(0.1, 2.0)
    mech = general_four_bar(a, b, c, d, theta, speed, masses=(1.0, 1.5, 1.0), name=kind)
    joint = (d + c * math.cos(float(th4)), c * math.sin(float(th4)))
    middle = ((a * math.cos(theta) + joint[0]) / 2, (a * math.sin(theta) + joint[1]) / 2)
    mech.add(Spring(mech.ground, mech.body("coupler"), at_a=(d / 2, 1.5), at_b=middle,
                    stiffness=k, damping=damping, name="spring-damper"))
    return mech, dict(a=a, b=b, c=c, d=d, theta=theta, speed=speed, stiffness=k,
                      damping=damping)
