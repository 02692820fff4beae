"""The gallery (docs/gallery.md): one picture per analysis mechsim does, each axis with its
unit, made by the code below.

    python examples/gallery.py [--out docs/images]

`figures(quick=True)` makes the same figures from shorter runs (the tests check their
axes).
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

import mechsim as ms


def simulation(quick):
    """A free motion through singular passages: the falling four-bar's energies and balance."""
    res = ms.examples.four_bar().simulate(0.5 if quick else 2.0, rtol=1e-8, output_step=1e-3)
    return res.plot_energy()


def reactions(quick):
    """Inverse dynamics of a driven slider-crank: the forces on its pins over a turn."""
    res = ms.examples.slider_crank(driven=True, crank_speed=100.0).simulate(
        2 * math.pi / 100, rtol=1e-9, output_step=1e-4 if not quick else 1e-3)
    return res.plot_reactions()


def efforts(quick):
    """The torque and power the slider-crank's motor must deliver."""
    res = ms.examples.slider_crank(driven=True, crank_speed=100.0).simulate(
        2 * math.pi / 100, rtol=1e-9, output_step=1e-4 if not quick else 1e-3)
    return res.plot_efforts()


def quantities(quick):
    """Coordinates, a point's path and a joint's angle of the double four-bar over time."""
    res = ms.examples.double_four_bar().simulate(1.0 if quick else 4.0, output_step=1e-3)
    return res.plot(coordinates=["crank1.angle", "coupler1.x"], points=[("coupler1", (0.5, 0.0))],
                    joints=["B1"])


def motion(quick):
    """Snapshots of the falling four-bar and its coupler curve."""
    res = ms.examples.four_bar().simulate(0.5 if quick else 2.0, output_step=1e-3)
    return res.plot_motion(trace=[("coupler", (0.25, 0.0))], snapshots=5)


def kinematics(quick):
    """Kinematic analysis (no integration): the slider's position, velocity and
    acceleration over a turn of the crank, against the crank angle."""
    mech = ms.examples.slider_crank(driven=True, crank_speed=100.0)
    motor = mech.drivers[0]
    angles = np.radians(np.arange(0.0, 361.0, 5.0 if quick else 1.0))
    res = mech.kinematics(over=(motor, angles))
    a = res.accelerations()[:, res.coordinate_names.index("slider.x")]
    fig = Figure(figsize=(7.0, 6.0), layout="constrained")
    axes = fig.subplots(3, 1, sharex=True)
    crank = np.degrees(res.coordinate("crank.angle"))
    for ax, y, label in zip(axes, (res.coordinate("slider.x"), res.v[:, res.coordinate_names.index("slider.x")], a),
                            ("slider position [m]", "slider velocity [m/s]",
                             "slider acceleration [m/s²]")):
        ax.plot(crank, y, lw=1.2)
        ax.set_ylabel(label)
        ax.grid(True, alpha=0.3)
    axes[0].set_title("Slider-crank kinematics at 100 rad/s")
    axes[-1].set_xlabel("crank angle [°]")
    return fig


def modes(quick):
    """Linearized vibration of the flexible four-bar about its hanging equilibrium: the
    mechanism's natural frequencies (one rigid swing, then its coupler's bending) against
    the coupler beam's own pinned–pinned modes."""
    mech = ms.examples.flexible_four_bar()
    beam = mech.body("coupler")
    lin = mech.linearize()
    fig = Figure(figsize=(7.0, 3.6), layout="constrained")
    ax = fig.add_subplot()
    k = np.arange(1, len(lin.frequencies) + 1)
    ax.bar(k - 0.2, lin.frequencies / (2 * math.pi), width=0.4, label="mechanism, linearized")
    kb = np.arange(1, len(beam.frequencies) + 1)
    ax.bar(kb + 0.2, np.asarray(beam.frequencies) / (2 * math.pi), width=0.4,
           label="coupler beam, pinned–pinned")
    ax.set_xticks(k)
    ax.set_xlabel("mode number [-]")
    ax.set_ylabel("natural frequency [Hz]")
    ax.set_yscale("log")
    ax.set_title("Modes of the flexible four-bar")
    ax.grid(True, alpha=0.3, which="both")
    ax.legend()
    return fig


def steady_state(quick):
    """A periodic steady state found by shooting: a damped pendulum under a periodic
    torque, its orbit in the phase plane."""
    w = 4.0
    mech = ms.examples.shaken_pendulum(omega=w)
    sol = mech.steady_state(2 * math.pi / w)
    orbit = sol.trajectory.result
    fig = Figure(figsize=(5.0, 4.4), layout="constrained")
    ax = fig.add_subplot()
    ax.plot(orbit.coordinate("rod.angle"),
            orbit.v[:, orbit.coordinate_names.index("rod.angle")], lw=1.4)
    ax.set_xlabel("rod angle [rad]")
    ax.set_ylabel("rod angular velocity [rad/s]")
    ax.set_title(f"Steady state by shooting ({sol.iterations} Newton iterations)")
    ax.grid(True, alpha=0.3)
    return fig


def study(quick):
    """A parameter study: the motor's peak torque against the crank speed."""
    speeds = np.linspace(40.0, 160.0, 5 if quick else 13)
    result = ms.sweep(lambda w: ms.examples.slider_crank(driven=True, crank_speed=w),
                      {"w": speeds}, simulate=dict(t_end=0.16, output_step=5e-4),
                      measure=lambda res: {"peak": float(np.max(np.abs(
                          res.driver_effort(res.mechanism.drivers[0]))))},
                      workers=1)
    fig = Figure(figsize=(7.0, 3.6), layout="constrained")
    ax = fig.add_subplot()
    ax.plot(result.table["w"], result.table["peak"], "o-")
    ax.set_xlabel("crank speed [rad/s]")
    ax.set_ylabel("peak motor torque [N·m]")
    ax.set_title("Parameter study: driven slider-crank")
    ax.grid(True, alpha=0.3)
    return fig


def work_precision(quick):
    """Run time against error for two solvers on the falling four-bar (`mechsim bench`)."""
    from mechsim.app import bench
    rtols = (1e-5, 1e-7) if quick else (1e-5, 1e-6, 1e-7, 1e-8, 1e-9)
    rows = bench.run(["parallelogram"], ["lu", "hybrid"], rtols, progress=None)
    fig = Figure(figsize=(7.0, 4.0), layout="constrained")
    ax = fig.add_subplot()
    for method in ("lu", "hybrid"):
        mine = [r for r in rows if r.method == method]
        ax.loglog([r.wall_time for r in mine], [r.error for r in mine], "o-", label=method)
    ax.set_xlabel("wall time [s]")
    ax.set_ylabel("crank-tip error [m]")
    ax.set_title("Work–precision: the falling four-bar, 2 s")
    ax.grid(True, alpha=0.3, which="both")
    ax.legend()
    return fig


GALLERY = {"simulation": simulation, "reactions": reactions, "efforts": efforts,
           "quantities": quantities, "motion": motion, "kinematics": kinematics,
           "modes": modes, "steady_state": steady_state, "study": study,
           "work_precision": work_precision}


def figures(quick=False) -> dict:
    """{name: Figure} of every analysis in the gallery."""
    return {name: make(quick) for name, make in GALLERY.items()}


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="docs/images", type=Path)
    out = parser.parse_args().out
    out.mkdir(parents=True, exist_ok=True)
    for name, fig in figures().items():
        fig.savefig(out / f"gallery_{name}.png", dpi=100)
        print(f"wrote {out / f'gallery_{name}.png'}")
