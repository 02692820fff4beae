"""Ready mechanisms, built in a few lines each. They double as test fixtures and as the
Python twins of the scene files in `mechanisms/`.

>>> import mechsim as ms
>>> ms.examples.four_bar().dof().dof
1
"""

from __future__ import annotations

import math

import numpy as np

from .model import Driver, FlexibleBeam, Mechanism, Prismatic, Revolute, RigidBody, Spring


def four_bar(tilt: float = math.radians(10.0), length: float = 1.0, mass: float = 1.0,
             gravity=(0.0, -9.81)) -> Mechanism:
    """The seed paper's falling parallelogram: crank = coupler = rocker = ground = `length`,
    uniform slender rods of `mass`, released at rest with the cranks `tilt` above horizontal.
    Singular (all bars aligned) when the cranks pass horizontal."""
    mech = Mechanism("four-bar", gravity=gravity)
    c, s = length * math.cos(tilt), length * math.sin(tilt)
    coupler = RigidBody.rod("coupler", (c, s), (length + c, s), mass)
    return _parallelogram(mech, coupler, tilt, length, mass)


def _parallelogram(mech, coupler, tilt, length, link_mass) -> Mechanism:
    """Crank and rocker rods of `link_mass` at `tilt`, joined by `coupler` (already built,
    rigid or elastic): the seed's falling four-bar with joints A, B, C, D."""
    c, s = length * math.cos(tilt), length * math.sin(tilt)
    crank = mech.add(RigidBody.rod("crank", (0.0, 0.0), (c, s), link_mass))
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
                      rigid: bool = False, gravity=(0.0, -9.81)) -> Mechanism:
    """The seed's flexible four-bar: the falling parallelogram of `four_bar` with the coupler
    an elastic beam (square section `width`, copper by default: E = 117 GPa, ρ = 8910 kg/m³;
    10 elements, 2 pinned–pinned modes); crank and rocker rigid rods of `link_mass`. With
    `rigid=True` the coupler is a rigid rod of the same mass (the rigid limit)."""
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
    return _parallelogram(mech, coupler, tilt, length, link_mass)


def double_four_bar(n: int = 2, length: float = 1.0, mass: float = 1.0,
                    crank_speed: float = -1.0, gravity=(0.0, -9.81)) -> Mechanism:
    """IFToMM benchmark A02 (N four-bars in a row): N+1 vertical cranks at x = 0, L, …, NL and
    N horizontal couplers, all uniform rods of `mass`; cranks turn at `crank_speed` rad/s
    (−1: tips moving at +1 m/s). On the parallelogram branch every crank has the same angle
    θ with M_eff θ̈ = −K cos θ (see `double_four_bar_exact`)."""
    if n < 1:
        raise ValueError(f"`n` must be at least 1, got {n}")
    mech = Mechanism(f"{n}-window four-bar" if n != 2 else "double four-bar", gravity=gravity)
    w = crank_speed
    cranks = []
    for i in range(n + 1):
        x = i * length
        crank = mech.add(RigidBody.rod(f"crank{i + 1}", (x, 0.0), (x, length), mass,
                                       velocity=(-w * length / 2, 0.0), angular_velocity=w))
        mech.add(Revolute(mech.ground, crank, at=(x, 0.0), name=f"A{i + 1}"))
        cranks.append(crank)
    for i in range(n):
        x = i * length
        coupler = mech.add(RigidBody.rod(f"coupler{i + 1}", (x, length), (x + length, length),
                                         mass, velocity=(-w * length, 0.0)))
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
        mech.add(Driver(crank_pin, f"{w!r}*t"))
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
