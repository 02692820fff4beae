"""A four-bar's joint reactions through its singular configurations.

The seed's parallelogram four-bar falls under gravity through three positions where all its
bars align (singular configurations, where the constraint Jacobian loses rank): the pin
forces stay finite and smooth through them, and the few samples closest to each, where the
projection method left the vanishing direction out of the motion, carry the minimum-norm
reactions and are flagged. The same four-bar driven at constant speed through its aligned
position (a kinematic analysis) needs a finite motor torque, but there the drivers do not
decide the branch and the reactions are not unique: the analysis says so.

    python examples/four_bar_reactions_singular.py [--out DIR]
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

import mechsim as ms


def main(out_dir: Path):
    mech = ms.examples.four_bar()
    res = mech.simulate(2.0, rtol=1e-9, atol=1e-11, output_step=1e-3)
    print(f"falling parallelogram: {res.status}, {len(res.singular_passages)} singular "
          f"passages at " + ", ".join(f"{p.t_min:.4f} s" for p in res.singular_passages))
    for joint in mech.joints:
        F = np.linalg.norm(res.joint_force(joint), axis=1)
        print(f"  joint '{joint.name}': |F| from {F.min():.3f} to {F.max():.3f} N")
    flagged = res.reactions.flagged
    print(f"  {flagged.sum()} of {len(res.t)} samples flagged: "
          f"{res.reactions.note() or 'every reaction unique'}")

    driven = ms.examples.general_four_bar(1.0, 1.0, 1.0, 1.0, theta=0.6)
    driven.add(ms.Driver(driven.joint("O2"), "2*t", name="motor"))
    kin = driven.kinematics(2.0, 2e-3)
    effort = kin.driver_effort("motor")
    print(f"driven through its aligned position: {kin.message}")
    print(f"  motor torque from {effort.min():.3f} to {effort.max():.3f} N·m; "
          f"{kin.reactions.note() or 'every reaction unique at the samples'}")

    out_dir.mkdir(parents=True, exist_ok=True)
    fig = Figure(figsize=(7.5, 6.5), layout="constrained")
    top, bottom = fig.subplots(2, 1)
    res.plot_reactions(ax=top)
    kin.plot_efforts(ax=bottom)
    fig.savefig(out_dir / "four_bar_reactions.png", dpi=120)
    print(f"wrote {out_dir / 'four_bar_reactions.png'}")


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="out/examples", type=Path)
    main(parser.parse_args().out)
