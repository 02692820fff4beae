"""Sizing a single-cylinder engine's crank train: pin forces, crank torque, flywheel.

A slider-crank (crank 40 mm, rod 140 mm, bore 80 mm) runs at a steady 3000 rpm while gas
pressure acts on its piston: polytropic compression towards top dead centre and expansion
after it, with the pressure raised by combustion. The crank is driven at constant speed,
so the motion is known and a kinematic analysis (no integration) gives, at every crank
angle, the torque the crankshaft must hold (inverse dynamics) and the forces on every pin.

From the torque over a revolution follow the mean torque and power, and the energy the
flywheel must store to keep the speed within ±Cs/2: ΔE = max − min of ∫ (T − T_mean) dθ,
I = ΔE / (Cs ω²).

    python examples/engine_sizing.py [--out DIR] [--rpm 3000] [--cs 0.02]
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from scipy.integrate import cumulative_trapezoid, trapezoid

import mechsim as ms

R, L, BORE = 0.040, 0.140, 0.080           # crank, rod, bore [m]
AREA = math.pi * BORE ** 2 / 4
CLEARANCE = 0.010                          # gas column at top dead centre [m]
P0, N_POLY, FIRING = 1.0e5, 1.3, 3.0       # intake pressure [Pa], polytropic index, rise


def gas_pressure(theta):
    """Cylinder pressure [Pa] at crank angle θ (0 at top dead centre, the piston outwards):
    compression on the way in, expansion (FIRING times higher) on the way out."""
    x = R * (1 - np.cos(theta)) + L - np.sqrt(L * L - (R * np.sin(theta)) ** 2)   # from TDC
    ratio = (2 * R + CLEARANCE) / (x + CLEARANCE)
    expanding = np.sin(theta) > 0
    return P0 * ratio ** N_POLY * np.where(expanding, FIRING, 1.0)


def engine(rpm: float) -> ms.Mechanism:
    """The crank train at top dead centre, the cylinder head on the +x side."""
    mech = ms.Mechanism("single-cylinder engine")
    crank = mech.add(ms.RigidBody("crank", mass=2.5, inertia=2.5 * R * R / 2,
                                  position=(0.0, 0.0)))        # balanced: its centre on the axis
    rod = mech.add(ms.RigidBody.rod("rod", (R, 0.0), (R + L, 0.0), mass=0.55))
    piston = mech.add(ms.RigidBody("piston", mass=0.45, inertia=4e-4, position=(R + L, 0.0)))
    main = mech.add(ms.Revolute(mech.ground, crank, at=(0, 0), name="main bearing"))
    mech.add(ms.Revolute(crank, rod, at=(R, 0), name="crank pin"))
    mech.add(ms.Revolute(rod, piston, at=(R + L, 0), name="wrist pin"))
    mech.add(ms.Prismatic(mech.ground, piston, axis=(1, 0), at=(R + L, 0), name="cylinder"))
    omega = rpm * 2 * math.pi / 60
    mech.add(ms.Driver(main, f"{omega!r}*t", name="crankshaft"))
    # The gas pushes the piston towards the crank: a force of the crank angle.
    mech.add(ms.Force(piston, lambda t, theta, rate: (-AREA * float(gas_pressure(theta)), 0.0),
                      joint=main, name="gas"))
    return mech


def main(out_dir: Path, rpm: float, cs: float):
    mech = engine(rpm)
    omega = rpm * 2 * math.pi / 60
    period = 2 * math.pi / omega
    res = mech.kinematics(period, period / 720)           # every half degree
    assert res.success, res.message
    theta = res.joint_coordinate("main bearing")
    # The driver holds the crank at speed: the torque the engine delivers is its opposite.
    torque = -res.driver_effort("crankshaft")
    t_mean = trapezoid(torque, theta) / (theta[-1] - theta[0])
    energy = cumulative_trapezoid(torque - t_mean, theta, initial=0.0)
    delta_e = energy.max() - energy.min()
    inertia = delta_e / (cs * omega ** 2)
    figures = res.cycle_figures()
    print(f"{mech.name} at {rpm:g} rpm, {len(res.t)} crank angles "
          f"({res.stats['wall_time']:.3f} s of kinematic analysis)")
    print(f"mean torque {t_mean:.2f} N·m, mean power {t_mean * omega / 1000:.2f} kW")
    print(f"torque from {torque.min():.1f} to {torque.max():.1f} N·m; "
          f"energy fluctuation ΔE = {delta_e:.1f} J")
    print(f"flywheel for ±{cs / 2:.1%} speed: I = {inertia:.4f} kg·m² "
          f"(a steel disc 30 mm thick: {_disc_diameter(inertia, 0.03) * 1000:.0f} mm across)")
    for name, j in figures.joints.items():
        print(f"peak force on '{name}': {j['peak_force'] / 1000:.2f} kN at "
              f"{math.degrees(theta[np.argmin(np.abs(res.t - j['at']))]):.1f}°")
    out_dir.mkdir(parents=True, exist_ok=True)
    fig = Figure(figsize=(7.5, 6.5), layout="constrained")
    top, bottom = fig.subplots(2, 1, sharex=True)
    degrees = np.degrees(theta)
    top.plot(degrees, torque, label="crank torque delivered")
    top.axhline(t_mean, color="k", lw=0.8, ls="--", label=f"mean {t_mean:.1f} N·m")
    top.set_ylabel("torque [N·m]")
    top.legend(fontsize="small")
    for name in ("main bearing", "crank pin", "wrist pin", "cylinder"):
        bottom.plot(degrees, np.linalg.norm(res.joint_force(name), axis=1) / 1000, label=name)
    bottom.set_xlabel("crank angle from top dead centre [°]")
    bottom.set_ylabel("pin force [kN]")
    bottom.legend(fontsize="small")
    for ax in (top, bottom):
        ax.grid(True, alpha=0.3)
    fig.suptitle(f"Engine crank train at {rpm:g} rpm")
    fig.savefig(out_dir / "engine_sizing.png", dpi=120)
    print(f"wrote {out_dir / 'engine_sizing.png'}")


def _disc_diameter(inertia, thickness, density=7850.0):
    """The diameter of a steel disc of `thickness` with polar inertia `inertia`."""
    return 2 * (2 * inertia / (density * math.pi * thickness)) ** 0.25


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="out/examples", type=Path)
    parser.add_argument("--rpm", default=3000.0, type=float)
    parser.add_argument("--cs", default=0.02, type=float,
                        help="coefficient of speed fluctuation (max − min)/mean")
    args = parser.parse_args()
    main(args.out, args.rpm, args.cs)
