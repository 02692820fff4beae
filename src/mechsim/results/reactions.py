"""Joint reactions, driver efforts and joint coordinates of a result, computed when asked.

`ReactionTable` answers for one `SimulationResult`: from its model (λ once for all samples,
`NumericProblem.multipliers`; each joint's wrench and coordinates when first asked,
`mechsim.problem.geometry`), or from the arrays a saved result holds. Nothing is computed
for a run whose reactions nobody reads.

Conventions (mechsim's API):

- `force(joint)`: the force (N, 2) the joint applies to `joint.body_b`, in global axes; the
  force on body_a is its opposite;
- `moment(joint)`: the moment (N,) the joint applies to body_b about the joint's point on
  body_b: 0 for a revolute, the anti-rotation couple of a prismatic;
- `effort(driver)`: the torque (revolute) or force along the axis (prismatic) the driver
  applies to body_b, −λ of its row (its power is effort × the joint's rate);
- `coordinate(joint)`, `rate(joint)`: the joint's relative angle or slide and its rate.
"""

from __future__ import annotations

import numpy as np

from ..problem.geometry import joint_coordinates, joint_wrench


def static_multipliers(problem, t, q):
    """λ of the mechanism at rest in equilibrium at (t, q) (`mechsim.problem.multipliers`)."""
    from ..problem.multipliers import static
    return static(problem, t, q)


def item_name(item, kind: str) -> str:
    """The name of a joint or driver given as the object or its name."""
    name = getattr(item, "name", item)
    if not isinstance(name, str):
        raise TypeError(f"expected a {kind} or its name, got {item!r}")
    return name


class ReactionTable:
    """Reactions, efforts and joint coordinates of one result.

    Parameters
    ----------
    t, q, v : the result's samples
    problem : its NumericProblem, or None for a loaded result
    saved : dict of arrays written by `to_arrays` (a loaded result), or None
    multipliers : the `Multipliers` at the samples where the caller has them (a static
        equilibrium's, `static_multipliers`); else from the equations of motion
    passages : the run's `SingularPassage` records (inside them directions of J̃ under the
        projection method's truncation cut are left out, `mechsim.problem.multipliers`), or
        None where no singularity monitor watched the motion
    """

    def __init__(self, t, q, v, problem=None, saved=None, multipliers=None, passages=None):
        self.t, self.q, self.v, self.problem = t, q, v, problem
        self.passages = None if passages is None else [(p.t_start, p.t_end) for p in passages]
        self._multipliers = multipliers
        self._computed: dict = {}
        self.saved = saved or {}

    # --- names -------------------------------------------------------------------------------
    @property
    def joint_names(self) -> list[str]:
        return self._names("joints")

    @property
    def driver_names(self) -> list[str]:
        return self._names("drivers")

    def _names(self, kind) -> list[str]:
        if self.problem is not None:
            return list(self.problem.joints if kind == "joints" else self.problem.driver_joints)
        return list(self.saved.get(kind, []))

    def kind(self, joint) -> str:
        """"revolute" or "prismatic": the kind of `joint` (which decides its units)."""
        name = self._joint(joint)
        if self.problem is not None:
            return self.problem.joints[name].joint.kind
        return self.saved.get("kinds", {}).get(name, "revolute")

    def driver_kind(self, driver) -> str:
        """The kind of the joint `driver` drives."""
        name = self._driver(driver)
        if self.problem is not None:
            return self.kind(self.problem.driver_joints[name])
        return self.saved.get("driver_kinds", {}).get(name, "revolute")

    def _joint(self, joint) -> str:
        return self._named(joint, "joint", "computing the reactions and joint coordinates")

    def _driver(self, driver) -> str:
        return self._named(driver, "driver", "computing the driver efforts")

    def joint_name(self, joint) -> str:
        """The name of a joint of this result (given as the object or its name); KeyError
        listing the valid ones."""
        return self._joint(joint)

    def driver_name(self, driver) -> str:
        """The name of a driver of this result (given as the object or its name); KeyError
        listing the valid ones."""
        return self._driver(driver)

    def _named(self, item, kind, what) -> str:
        """The name of a joint or driver (`kind`) of this result, given as the object or its
        name; KeyError listing the valid ones, RuntimeError where nothing was saved."""
        name = item_name(item, kind)
        if self.problem is None and f"{kind}s" not in self.saved:
            self._need(what)
        names = self._names(f"{kind}s")
        if name not in names:
            raise KeyError(f"no {kind} {name!r} in this result; {kind}s: "
                           f"{', '.join(names) or '(none)'}")
        return name

    def _need(self, what):
        if self.problem is None:
            raise RuntimeError(f"{what} needs the mechanism's model, and this result was "
                               "loaded without it; save results with reactions=True to keep "
                               "the reactions, efforts and joint coordinates")
        return self.problem

    # --- multipliers -------------------------------------------------------------------------
    @property
    def multipliers(self):
        """λ at every sample with the rows whose share is not unique
        (`mechsim.problem.multipliers.Multipliers`), computed on first use."""
        if self._multipliers is None:
            p = self._need("computing the reactions")
            self._multipliers = p.multipliers(self.t, self.q, self.v, self.passages)
        return self._multipliers

    def indeterminate(self, owner: str) -> np.ndarray:
        """(N,) bool: the samples where the reactions of joint or driver `owner` are not
        unique (the minimum-norm values are given there)."""
        key = f"indeterminate:{owner}"
        if key in self.saved:
            return self.saved[key]
        rows = self._need("computing the reactions").rows_of(owner)
        return self.multipliers.indeterminate[:, rows].any(axis=1)

    @property
    def flagged(self) -> np.ndarray:
        """(N,) bool: samples where some reaction or effort is not unique."""
        if "flagged" in self.saved:
            return self.saved["flagged"]
        return self.multipliers.flagged

    def note(self) -> str:
        """"" where every reaction is unique; else which joints and drivers are not, where."""
        flagged = self.flagged
        if not flagged.any():
            return ""
        owners = [o for o in self.joint_names + self.driver_names
                  if self.indeterminate(o).any()]
        times = self.t[flagged]
        where = (f"at {flagged.sum()} of {flagged.size} samples, t = {times[0]:.6g} … "
                 f"{times[-1]:.6g} s")
        return (f"reactions not unique {where} (redundant constraints or a singular "
                f"configuration): minimum-norm values given for "
                f"{', '.join(repr(o) for o in owners)}")

    # --- joints and drivers ------------------------------------------------------------------
    def wrench(self, joint):
        """(force (N, 2) global, moment (N,)) the joint applies to its body_b."""
        name = self._joint(joint)
        if f"force:{name}" in self.saved:
            return self.saved[f"force:{name}"], self.saved[f"moment:{name}"]
        p = self._need("computing the reactions")
        return self._memo(("wrench", name), joint_wrench, p.joints[name], self.q,
                          self.multipliers.lam[:, p.rows_of(name)])

    def force(self, joint, frame: str = "global") -> np.ndarray:
        """The force (N, 2) the joint applies to body_b: in global axes, or with
        frame="body" in body_b's axes (the ground's are the global ones)."""
        if frame not in ("global", "body"):
            raise ValueError(f"`frame` must be 'global' or 'body', got {frame!r}")
        F = self.wrench(joint)[0]
        if frame == "global":
            return F
        angle = self.body_b_angle(self._joint(joint))
        c, s = np.cos(angle), np.sin(angle)
        return np.stack([c * F[:, 0] + s * F[:, 1], -s * F[:, 0] + c * F[:, 1]], axis=1)

    def body_b_angle(self, name) -> np.ndarray:
        key = f"angle_b:{name}"
        if key in self.saved:
            return self.saved[key]
        start = self._need("finding the joint's body").joints[name].start_b
        return np.zeros(len(self.t)) if start is None else self.q[:, start + 2]

    def moment(self, joint) -> np.ndarray:
        return self.wrench(joint)[1]

    def effort(self, driver) -> np.ndarray:
        """(N,): the driver's torque or force on body_b, −λ of its row."""
        name = self._driver(driver)
        if f"effort:{name}" in self.saved:
            return self.saved[f"effort:{name}"]
        p = self._need("computing the driver efforts")
        return -self.multipliers.lam[:, p.rows_of(name)[0]]

    def gear_force(self, gear) -> np.ndarray:
        """(N,): the mesh's force of gear pair `gear` (`mechsim.Gear`): for a spur pair the
        tooth force along the pitch line, positive where it turns gear b counter-clockwise
        on its carrier [N]; for a rack, its force on the rack along the slide's axis [N];
        for a plain ratio coupling, its torque or force on joint b's body_b."""
        name = getattr(gear, "name", gear)
        p = self._need("computing the gear forces")
        if name not in p.gear_signs:
            raise KeyError(f"no gear {name!r} in this result; gears: "
                           f"{', '.join(p.gear_signs) or '(none)'}")
        return p.gear_signs[name] * self.multipliers.lam[:, p.rows_of(name)[0]]

    def coordinates(self, joint):
        """(s, ṡ), each (N,): the joint's coordinate and rate."""
        name = self._joint(joint)
        if f"coordinate:{name}" in self.saved:
            return self.saved[f"coordinate:{name}"], self.saved[f"rate:{name}"]
        p = self._need("computing the joint coordinates")
        return self._memo(("coordinates", name), joint_coordinates, p.joints[name], self.q,
                          self.v)

    def _memo(self, key, compute, *args):
        """compute(*args), once per key."""
        if key not in self._computed:
            self._computed[key] = compute(*args)
        return self._computed[key]

    def driver_rate(self, driver) -> np.ndarray:
        """(N,): the rate of the joint a driver drives (its power is effort × rate)."""
        name = self._driver(driver)
        if f"driver_rate:{name}" in self.saved:
            return self.saved[f"driver_rate:{name}"]
        return self.coordinates(self._need("finding the driver's joint").driver_joints[name])[1]

    # --- persistence -------------------------------------------------------------------------
    @property
    def computed(self) -> bool:
        """Whether anything has been computed or loaded (what `save` keeps by default)."""
        return bool(self.saved) or self._multipliers is not None or bool(self._computed)

    def to_arrays(self) -> dict:
        """Everything this table answers, as arrays (for `SimulationResult.save`)."""
        out = {"flagged": self.flagged}
        for name in self.joint_names:
            F, M = self.wrench(name)
            s, ds = self.coordinates(name)
            out.update({f"force:{name}": F, f"moment:{name}": M, f"coordinate:{name}": s,
                        f"rate:{name}": ds, f"indeterminate:{name}": self.indeterminate(name),
                        f"angle_b:{name}": self.body_b_angle(name)})
        for name in self.driver_names:
            out.update({f"effort:{name}": self.effort(name),
                        f"indeterminate:{name}": self.indeterminate(name),
                        f"driver_rate:{name}": self.driver_rate(name)})
        return out
