"""Sizing a crank's counterweight and the wrist-pin offset for the lowest peak motor torque.

A vertical slider-crank lifts a 5 kg plunger (a reciprocating pump, crank 0.15 m, rod
0.40 m) at a steady 2 rad/s. Gravity on the plunger makes the motor's torque swing over
each turn; a counterweight on the crank, opposite its pin, and the guide's offset from
the crank's axis reshape that swing. The design is the counterweight's mass and radius
and the offset; the objective is a smooth stand-in for the peak torque (the 16-norm mean
over one turn, `ms.EffortNorm`), whose gradient is exact: the driver effort's
sensitivities from the kinematic analysis.

The crank with its counterweight is one rigid body: its frame at their common centre of
mass, its inertia by the parallel-axis theorem, each a function of the Parameters.

    python examples/counterweight.py
"""

from __future__ import annotations

import time

import numpy as np

import mechsim as ms

R, L, SPEED = 0.15, 0.40, 2.0              # crank, rod [m], crank speed [rad/s]
M_CRANK, M_ROD, M_PLUNGER = 0.6, 0.8, 5.0  # [kg]
THETA0 = 0.0                               # crank angle at t = 0 (along +x)
START = dict(m_cw=1.0, r_cw=0.05, e=0.0)
BOUNDS = dict(m_cw=(0.0, 8.0), r_cw=(0.02, 0.20), e=(-0.06, 0.06))


def pump(m_cw, r_cw, e):
    """The pump with a counterweight `m_cw` [kg] at `r_cw` [m] behind the crank's pivot
    and the plunger's guide the vertical line x = e; numbers or Parameters."""
    mech = ms.Mechanism("counterweighted pump", gravity=(0.0, -9.81))
    u = np.array([np.cos(THETA0), np.sin(THETA0)])
    mass = M_CRANK + m_cw
    centre = (M_CRANK * R / 2 - m_cw * r_cw) / mass          # along the crank from O
    inertia = M_CRANK * R * R / 12 + M_CRANK * (R / 2 - centre) ** 2 + \
        m_cw * (r_cw + centre) ** 2
    pin = R * u
    top = np.array([e, pin[1] + np.sqrt(L * L - (e - pin[0]) ** 2)])
    crank = mech.add(ms.RigidBody("crank", mass=mass, inertia=inertia, position=centre * u,
                                  angle=THETA0))
    rod = mech.add(ms.RigidBody.rod("rod", pin, top, mass=M_ROD))
    plunger = mech.add(ms.RigidBody("plunger", mass=M_PLUNGER, inertia=0.01, position=top))
    motor_pin = mech.add(ms.Revolute(mech.ground, crank, at=(0.0, 0.0), name="O"))
    mech.add(ms.Revolute(crank, rod, at=pin, name="A"))
    mech.add(ms.Revolute(rod, plunger, at=top, name="B"))
    mech.add(ms.Prismatic(mech.ground, plunger, axis=(0.0, 1.0), at=top, name="guide"))
    mech.add(ms.Driver(motor_pin, f"{SPEED}*t", name="motor"))
    return mech


def objective(p=16.0):
    """The 16-norm mean of the motor torque over one turn, 2° apart."""
    return ms.EffortNorm("motor", p=p, over=("motor", np.radians(np.arange(0.0, 361.0, 2.0))))


def peak(mech):
    """The largest |torque| over one turn, 0.25° apart [N·m]."""
    kin = mech.kinematics(over=("motor", np.radians(np.arange(0.0, 360.01, 0.25))))
    return float(np.max(np.abs(kin.driver_effort("motor"))))


def size(gradient="exact"):
    """(the Design `ms.optimize` finds from START, wall time [s], the pump set to it)."""
    parameters = {k: ms.Parameter(k, v) for k, v in START.items()}
    mech = pump(**parameters)
    began = time.perf_counter()
    design = ms.optimize(mech, objective(), list(parameters), bounds=BOUNDS,
                         gradient=gradient, tol=1e-12)
    return design, time.perf_counter() - began, mech


def main():
    print(f"peak torque without a counterweight: {peak(pump(0.0, 0.05, 0.0)):.3f} N·m; "
          f"at the start: {peak(pump(**START)):.3f} N·m")
    for gradient in ("exact", "2-point"):
        design, seconds, mech = size(gradient)
        chosen = ", ".join(f"{k} = {v:.4f}" for k, v in design.parameters.items())
        print(f"{gradient:>8}: {chosen}; peak {peak(mech):.3f} N·m; "
              f"{design.evaluations} evaluations, {seconds:.2f} s")


if __name__ == "__main__":
    main()
