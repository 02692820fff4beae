"""SimulationResult: what a run returns.

Energies and constraint violations are computed on first access (nobody pays for what they do
not read) from the problem that produced the result; a saved result stores them, so a loaded
one answers the same questions without the model.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import numpy as np

from ..kinematics import frame_point, frame_point_acceleration, frame_point_velocity
from ..records import Status, WorkRecord
from .meta import metadata


@dataclass
class EnergyLog:
    """Energies at the output times, each shape (n,). `total` = kinetic + potential + strain;
    `work` = the work done since t₀ by all non-conservative forces (dampers, loads, damped
    beam modes) and drivers, `work_by` the same per channel (shape (n, k), `channels` their
    names); `balance` = total − total(t₀) − work, zero for an exact solution. `includes`
    says what the work covers and how it was found: integrated along the integrator's steps
    with the motion (the default; the balance then measures the solver), or from the output
    samples (Simpson; its accuracy then follows their spacing)."""
    kinetic: np.ndarray
    potential: np.ndarray
    strain: np.ndarray
    work: np.ndarray | None = None
    work_by: np.ndarray | None = None
    channels: tuple[str, ...] = ()
    includes: str = "no work: nothing but gravity and elastic springs acts"

    def __post_init__(self):
        if self.work_by is not None:
            self.work = self.work_by.sum(axis=1)
        if self.work is None:
            self.work = np.zeros_like(self.kinetic)

    @property
    def total(self) -> np.ndarray:
        return self.kinetic + self.potential + self.strain

    @property
    def balance(self) -> np.ndarray:
        return self.total - self.total[0] - self.work


class SimulationResult:
    """Output of `Mechanism.simulate`.

    Attributes
    ----------
    t : ndarray (n,);  q, v : ndarray (n, nq);  coordinate_names : list of str
    status : a `Status` ("success", "failed", "interrupted"; "partial": a stream not
        finished);  message : str
    exception : the exception that ended a failed run (a user's own, such as one raised by a
        load function, is its `__cause__`, with the traceback), else None
    stats : dict (steps, rhs_evaluations, partitions, wall_time, …)
    singular_passages : list of SingularPassage;  switches : list of Switch
    """

    def __init__(self, t, q, v, coordinate_names, *, problem=None, status=Status.SUCCESS,
                 message="", stats=None, singular_passages=(), switches=(),
                 energy: EnergyLog | None = None, constraint_violation=None,
                 exception: BaseException | None = None, work: WorkRecord | None = None,
                 saved_reactions: dict | None = None):
        self.t = np.asarray(t, float)
        self.q = np.asarray(q, float)
        self.v = np.asarray(v, float)
        self.coordinate_names = list(coordinate_names)
        self.problem = problem
        self.status = Status(status)
        self.message = message
        self.exception = exception
        self.stats = dict(stats or {})
        self.singular_passages = list(singular_passages)
        self.switches = list(switches)
        self.work_record = work      # the work integrated with the motion, if any
        self._saved_reactions = saved_reactions
        self.settings: dict = {}      # simulate's settings (what `extend` goes on with)
        # How `extend` goes on: continuation(result, t_end, overrides) -> the joined result;
        # set by the run that made this result (`mechsim.run.solver.continue_run`, or
        # `mechsim.engineering.impacts.extend_piecewise` for runs between events) or by
        # `load_result`. None: the result cannot be continued (kinematics, equilibrium).
        self.continuation = None
        self.mechanism = None         # the Mechanism simulated, where known (saved with it)
        self.model_note = ""          # why a loaded result came without its mechanism
        self.stream_path = None       # the directory a streamed run's samples are in
        self.event = None             # (t, index, q, v) where an event ended the run
        self.impacts = []             # the stops' impacts (`mechsim.engineering.impacts.Impact`)
        self.friction_switches = []   # stick and slip (`mechsim.engineering.friction.FrictionSwitch`)
        # Exact sensitivities at the samples to the Parameters the analysis was asked for
        # (`mechsim.problem.sensitivity.Sensitivities`; `sensitivity`), else None.
        self.sensitivities = None
        if energy is not None:
            self.__dict__["energy"] = energy
        if constraint_violation is not None:
            self.__dict__["constraint_violation"] = np.asarray(constraint_violation, float)

    @property
    def success(self) -> bool:
        return self.status == Status.SUCCESS

    def __repr__(self):
        return (f"SimulationResult(status={self.status!r}, t=[{self.t[0]:.6g}, {self.t[-1]:.6g}], "
                f"{len(self.t)} samples, {len(self.coordinate_names)} coordinates)")

    def _repr_html_(self) -> str:
        """A summary table for Jupyter: status and message, samples, coordinates, method,
        work done and singular passages (nothing computed for it)."""
        import html
        t = self.t
        names = self.coordinate_names
        shown = ", ".join(names[:8]) + (f", … ({len(names)} in all)" if len(names) > 8 else "")
        stats = self.stats
        passages = self.singular_passages
        rows = [
            ("mechanism", self.mechanism.name if self.mechanism is not None else
             (self.problem.title if self.problem is not None else "—")),
            ("status", f"{self.status}: {self.message}"),
            ("samples", f"{len(t)}, t = {t[0]:.6g} … {t[-1]:.6g} s" if len(t) else "none"),
            ("coordinates", shown),
            ("method", f"{stats.get('method', '?')} / {stats.get('integrator', '?')}: "
                       f"{stats.get('steps', '?')} steps, {stats.get('rhs_evaluations', '?')} "
                       f"right-hand sides, {stats.get('wall_time', float('nan')):.3g} s"),
            ("singular passages", ", ".join(f"{p.t_min or p.t_start:.4g} s" for p in passages[:6])
             + (f", … ({len(passages)})" if len(passages) > 6 else "") if passages else "none"),
        ]
        body = "".join(f"<tr><th style='text-align:left'>{html.escape(k)}</th>"
                       f"<td style='text-align:left'>{html.escape(str(v))}</td></tr>"
                       for k, v in rows)
        return f"<table><caption>SimulationResult</caption>{body}</table>"

    # --- coordinates and points --------------------------------------------------------------
    def coordinate(self, name: str) -> np.ndarray:
        """One coordinate over time, by name ("crank.angle")."""
        return self.q[:, self._index(name)]

    def _index(self, name: str) -> int:
        try:
            return self.coordinate_names.index(name)
        except ValueError:
            raise KeyError(f"no coordinate {name!r}; coordinates: "
                           f"{', '.join(self.coordinate_names)}") from None

    def _body_start(self, body) -> int | None:
        name = body if isinstance(body, str) else body.name
        if f"{name}.x" in self.coordinate_names:
            return self._index(f"{name}.x")
        if name == "ground":
            return None
        bodies = sorted({c.rsplit(".", 1)[0] for c in self.coordinate_names})
        raise KeyError(f"no body {name!r} in this result; bodies: {', '.join(bodies)}")

    def _point_modes(self, body, local):
        """(2, k) modal displacement of `local` on a flexible beam, None on a rigid body."""
        if hasattr(body, "point_modes"):
            return body.point_modes(local)
        name = body if isinstance(body, str) else body.name
        for fb in getattr(self.problem, "flexible", ()):
            if fb.name == name:
                return fb.point_modes(local)
        if self.problem is None and f"{name}.eta1" in self.coordinate_names:
            raise RuntimeError(f"the mode shapes of beam '{name}' are not saved with this "
                               "result; pass the FlexibleBeam object itself")
        return None

    def point(self, body, local=(0.0, 0.0)) -> np.ndarray:
        """Global position of a body-fixed point over time, shape (n, 2). On a flexible
        beam `local` = (ξ, y) is a point of the undeformed beam, moved with the modes."""
        return frame_point(self.q, self._body_start(body), local, self._point_modes(body, local))

    def point_velocity(self, body, local=(0.0, 0.0)) -> np.ndarray:
        """Global velocity of a body-fixed point over time, shape (n, 2)."""
        return frame_point_velocity(self.q, self.v, self._body_start(body), local,
                                    self._point_modes(body, local))

    def point_acceleration(self, body, local=(0.0, 0.0)) -> np.ndarray:
        """Global acceleration [m/s²] of a body-fixed point over time, shape (n, 2), from the
        equations of motion at each sample (`accelerations`; needs the model)."""
        return frame_point_acceleration(self.q, self.v, self.accelerations(),
                                        self._body_start(body), local,
                                        self._point_modes(body, local))

    def sensitivity(self, name: str, of: str = "q", body=None, local=(0.0, 0.0),
                    driver=None, joint=None) -> np.ndarray:
        """The exact sensitivity to the Parameter `name` of a quantity over time, with the
        quantity's shape: of "q" (∂q/∂k, the shape of `q`), "v", "a" (of q̈), "point"
        (∂r/∂k of the body-fixed point `local` of `body`, (n, 2): r's Jacobian in q
        applied to ∂q/∂k), "lambda" (of the multipliers, (n, m)), "driver_effort"
        (of `driver_effort(driver)`, (n,)), "joint_force" (of `joint_force(joint)`,
        global axes, (n, 2)), "joint_coordinate" (of `joint_coordinate(joint)`, (n,):
        through the states and the joint's own geometry), "kinetic_energy" or
        "potential_energy" (of `energy.kinetic` and `energy.potential`, (n,); rigid
        bodies). The analysis must have been asked for it
        (`kinematics(..., sensitivities=[name])`, `simulate(..., sensitivities=[name])`);
        the multipliers' (and what follows from them) are computed when first asked, for
        the loads that are differentiated (`mechsim.problem.sensitivity`)."""
        table = self.sensitivities
        if table is None or name not in table:
            raise ValueError(f"sensitivity: no sensitivities to {name!r:.60} in this result; "
                             f"it has {', '.join(table or []) or 'none'} (ask the analysis "
                             "for them: sensitivities=[...])")
        if of in ("q", "v", "a"):
            return table.state(name, of)
        if of == "point":
            if body is None:
                raise ValueError("sensitivity(of='point') needs the `body` the point is on")
            return frame_point_velocity(self.q, table.state(name, "q"),
                                        self._body_start(body), local,
                                        self._point_modes(body, local))
        if of == "lambda":
            return table.multipliers(name)
        if of == "driver_effort":
            if driver is None:
                raise ValueError("sensitivity(of='driver_effort') needs the `driver`")
            row = self.problem.rows_of(self.reactions.driver_name(driver))[0]
            return -table.multipliers(name)[:, row]
        if of == "joint_force":
            if joint is None:
                raise ValueError("sensitivity(of='joint_force') needs the `joint`")
            owner = self.reactions.joint_name(joint)
            return table.joint_force(name, self.problem.joints[owner],
                                     self.problem.rows_of(owner))
        if of == "joint_coordinate":
            if joint is None:
                raise ValueError("sensitivity(of='joint_coordinate') needs the `joint`")
            owner = self.reactions.joint_name(joint)
            model = self.mechanism.joint(owner) if self.mechanism is not None else None
            exact = model.parameter_values() if model is not None else ()
            return table.joint_coordinate(name, self.problem.joints[owner], exact)
        if of in ("kinetic_energy", "potential_energy"):
            return table.energy(name, of)
        raise ValueError(f"sensitivity: `of` must be 'q', 'v', 'a', 'point', 'lambda', "
                         f"'driver_effort', 'joint_force', 'joint_coordinate', "
                         f"'kinetic_energy' or 'potential_energy', got {of!r:.40}")

    def angular_velocity(self, body) -> np.ndarray:
        """The angular velocity [rad/s] of a body's frame over time, shape (n,) (0 for the
        ground)."""
        start = self._body_start(body)
        return np.zeros(len(self.t)) if start is None else np.array(self.v[:, start + 2])

    def accelerations(self) -> np.ndarray:
        """q̈ at the output times, shape (n, nq), from the equations of motion at each sample
        (computed when asked, not stored). Near a singular configuration the constraint
        forces are found in the least-squares sense."""
        p = self._need_problem("computing the accelerations")
        out = np.empty_like(self.v)
        for i, (t, q, v) in enumerate(zip(self.t, self.q, self.v)):
            _, J, _, gamma = p.terms(q, v, t)
            out[i] = p.accelerations(J, p.forces(t, q, v), gamma, q)[0]
        return out

    # --- continuing -----------------------------------------------------------------------------
    def extend(self, t_end: float, **overrides) -> "SimulationResult":
        """This run continued from its last sample to `t_end` with the same settings (or
        `overrides` of them), joined into one result: samples, passages, switches and
        statistics, and the work of every channel carried on from where it stood, so the
        energy balance keeps its baseline. The integrator starts afresh at the join; the
        joined run equals an uninterrupted one to the integration tolerance."""
        self._need_problem("extending the run")
        if not self.settings or self.continuation is None:
            raise RuntimeError("this result does not hold the settings of the run that made "
                               "it; simulate again from its last state instead")
        t_end = float(t_end)
        if not t_end > self.t[-1]:
            raise ValueError(f"extend: `t_end` must be after the last sample "
                             f"t = {self.t[-1]:.9g}, got {t_end!r}")
        return self.continuation(self, t_end, overrides)

    # --- reactions, efforts and joint coordinates ---------------------------------------------
    @cached_property
    def reactions(self):
        """The `ReactionTable` of this result (`mechsim.results.reactions`): the Lagrange
        multipliers at every sample, computed on first use, and which reactions are not
        unique where (`reactions.note()`, `reactions.flagged`)."""
        from .reactions import ReactionTable
        watched = self.stats.get("method") not in ("kinematics", "equilibrium")
        return ReactionTable(self.t, self.q, self.v, self.problem, self._saved_reactions,
                             passages=self.singular_passages if watched else None)

    def joint_force(self, joint, frame: str = "global") -> np.ndarray:
        """The force [N] the joint applies to `joint.body_b` at each sample, shape (n, 2): in
        global axes, or with frame="body" in body_b's axes. The force on body_a is its
        opposite. Where the reactions are not unique (redundant constraints, a singular
        configuration) the minimum-norm values; `reactions.note()` says where."""
        return self.reactions.force(joint, frame)

    def joint_moment(self, joint) -> np.ndarray:
        """The moment [N·m] the joint applies to body_b about the joint's point on body_b,
        shape (n,): 0 for a revolute, the anti-rotation couple of a prismatic."""
        return self.reactions.moment(joint)

    def driver_effort(self, driver) -> np.ndarray:
        """The torque [N·m] (revolute) or force [N] (prismatic) the driver applies to
        body_b of its joint, shape (n,): what the motor or actuator must deliver."""
        return self.reactions.effort(driver)

    def gear_force(self, gear) -> np.ndarray:
        """The mesh force of a gear pair at each sample, shape (n,): a spur pair's tooth
        force along the pitch line [N] (positive turning gear b counter-clockwise on its
        carrier), a rack's force along its slide [N], a ratio coupling's effort on joint b
        (`ReactionTable.gear_force`)."""
        return self.reactions.gear_force(gear)

    def friction_force(self, friction) -> np.ndarray:
        """The torque [N·m] (revolute) or force [N] (prismatic) that the friction `friction`
        (the element or its name) applies to its joint's body_b along the joint's
        coordinate at each sample, shape (n,): −μ × the load while slipping, the holding
        force while stuck (`SimulationResult.friction_switches` says when)."""
        return self._joint_contact(friction, "friction")

    def stop_force(self, stop) -> np.ndarray:
        """The torque [N·m] or force [N] that `stop` (the element or its name) applies to its
        joint's body_b along the joint's coordinate at each sample while the joint rests on
        it (0 elsewhere: its impacts are impulses, `SimulationResult.impacts`), shape (n,)."""
        return self._joint_contact(stop, "stop")

    def _joint_contact(self, element, kind) -> np.ndarray:
        p = self._need_problem(f"computing {kind} forces")
        name = getattr(element, "name", element)
        names = [e.name for e in p.friction.elements if e.kind == kind] \
            if p.friction is not None else []
        if name not in names:
            raise KeyError(f"this result has no {kind} named {name!r}; {kind}s: "
                           f"{', '.join(names) or '(none)'}")
        k = next(i for i, e in enumerate(p.friction.elements) if e.name == name)
        F = p.load_model.forces_at(self.t, self.q, self.v)
        states = p.friction.solve_many(p, self.t, self.q, self.v, F)
        return np.array([s.forces[k] for s in states]).reshape(len(self.t))

    def driver_power(self, driver) -> np.ndarray:
        """The power [W] the driver delivers, effort × the rate of its joint, shape (n,)."""
        return self.reactions.effort(driver) * self.reactions.driver_rate(driver)

    def cycle_figures(self):
        """Peak and RMS driver effort and power, peak joint forces and four-bar
        transmission angles over this result: a `CycleFigures` (printable;
        `mechsim.results.figures`)."""
        from .figures import cycle_figures
        return cycle_figures(self)

    def joint_coordinate(self, joint) -> np.ndarray:
        """The joint's coordinate, shape (n,): relative angle [rad] of body_b to body_a for
        a revolute, slide [m] of a prismatic along its axis from its initial position."""
        return self.reactions.coordinates(joint)[0]

    def joint_rate(self, joint) -> np.ndarray:
        """The rate of `joint_coordinate` [rad/s or m/s], shape (n,)."""
        return self.reactions.coordinates(joint)[1]

    def channel(self, name: str) -> np.ndarray:
        """The mechanism's channel `name` (`mechsim.Channel`) at each sample, shape (n,):
        NaN where its expression is undefined."""
        channels = getattr(self.mechanism, "channels", None)
        if channels is None:
            raise RuntimeError("this result does not carry its mechanism, so it has no "
                               f"channels{': ' + self.model_note if self.model_note else ''}")
        for c in channels:
            if c.name == name:
                return c.values(self)
        raise KeyError(f"mechanism '{self.mechanism.name}' has no channel {name!r}; channels: "
                       f"{', '.join(c.name for c in channels) or '(none)'}")

    # --- energy and constraints --------------------------------------------------------------
    def _need_problem(self, what):
        if self.problem is None:
            why = f" ({self.model_note})" if self.model_note else ""
            raise RuntimeError(f"{what} needs the mechanism's model, and this result was "
                               f"loaded without it{why}; a saved result keeps its mechanism "
                               "where a scene can hold it")
        return self.problem

    @cached_property
    def energy(self) -> EnergyLog:
        p = self._need_problem("computing the energy log")
        energies = (p.kinetic_energy(self.q, self.v), p.potential_energy(self.q),
                    p.strain_energy(self.q))
        channels = tuple(p.work_channels)
        if not channels:
            return EnergyLog(*energies)
        n = len(self.t)
        record = self.work_record
        if record is not None and record.channels == channels and len(record.values):
            W = np.empty((n, len(channels)))
            done = min(len(record.values), n)
            W[:done] = record.values[:done]
            how = "integrated with the motion along the integrator's steps"
            if record.note:
                how += f" ({record.note})"
            if done < n:
                # The samples past the end of the integral (a run that failed inside a step)
                # go on from the output samples.
                rest = self.t[done - 1:]
                rates = p.work_rates_many(rest, self.q[done - 1:], self.v[done - 1:])
                W[done:] = W[done - 1] + _cumulative_integral(rates, rest)[1:]
                how += (f"; after t = {self.t[done - 1]:.9g} from the output samples "
                        "(Simpson)")
        else:
            rates = p.work_rates_many(self.t, self.q, self.v)
            W = _cumulative_integral(rates, self.t) if n > 1 else np.zeros((n, len(channels)))
            how = ("from the power at the output samples (Simpson): its accuracy follows "
                   "their spacing; simulate with work=True to integrate it with the motion")
        return EnergyLog(*energies, work_by=W, channels=channels,
                         includes=f"work of {', '.join(channels)}, {how}")

    @property
    def energy_scale(self) -> float:
        """The scale drift is measured against: the largest of abs(E(0)), the peak kinetic energy
        and the peak change of potential energy, so a mechanism whose total starts near zero
        still has a meaningful relative drift."""
        e = self.energy
        v = e.potential + e.strain
        return float(max(abs(e.total[0]), np.max(e.kinetic), np.max(np.abs(v - v[0])),
                         np.max(np.abs(e.work)), 1e-300))

    @property
    def energy_drift(self) -> np.ndarray:
        """(E(t) − E(0) − W(t)) / energy_scale, shape (n,): W is the work of non-conservative
        forces and drivers, so a driven or damped mechanism has a meaningful drift too;
        `energy.includes` says which forces W covers and how it was integrated."""
        return self.energy.balance / self.energy_scale

    def passage_drift(self) -> np.ndarray:
        """The change of `energy_drift` across each singular passage, shape (number of
        passages,): from the last output sample before `t_start` to the first after
        `t_end`. A method that steps through a passage off its branch gains or loses energy
        there (seed 001's Fig. 5 for LU partitioning), and this says at which passage;
        outside the passages the drift changes by the integrator's error alone."""
        drift = self.energy_drift
        out = np.empty(len(self.singular_passages))
        for k, p in enumerate(self.singular_passages):
            before = max(int(np.searchsorted(self.t, p.t_start, side="right")) - 1, 0)
            after = min(int(np.searchsorted(self.t, p.t_end, side="left")), len(self.t) - 1)
            out[k] = drift[after] - drift[before]
        return out

    @cached_property
    def constraint_violation(self) -> np.ndarray:
        """‖Φ(q(t), t)‖₂ at the output times, shape (n,)."""
        p = self._need_problem("computing the constraint violation")
        return np.array([np.linalg.norm(p.phi(q, t)) for q, t in zip(self.q, self.t)])

    # --- plots -------------------------------------------------------------------------------
    def plot_energy(self, path=None, ax=None):
        """Energy drift over time, singular passages shaded, solver switches marked.
        Returns the matplotlib Figure; writes it to `path` (PNG/PDF/SVG) when given."""
        from .plots import plot_energy
        return plot_energy(self, path=path, ax=ax)

    def plot(self, path=None, *, coordinates=(), points=(), joints=(), reactions=(),
             efforts=()):
        """Quantities over time, one panel per kind: `coordinates` by name ("crank.angle"),
        `points` [(body, local point)] (x and y), `joints` (their coordinates), `reactions`
        (joint force magnitudes), `efforts` (drivers). Returns the Figure; writes it to
        `path` when given."""
        from .plots import plot_quantities
        return plot_quantities(self, coordinates, points, joints, reactions, efforts, path)

    def plot_reactions(self, path=None, joints=None, ax=None):
        """The magnitude of each joint's force over time (`joints`: a list of joints or
        names; None: all), singular passages shaded, non-unique samples marked. Returns the
        Figure; writes it to `path` when given."""
        from .plots import plot_reactions
        return plot_reactions(self, path=path, joints=joints, ax=ax)

    def plot_efforts(self, path=None, ax=None):
        """Each driver's torque or force over time, its power dashed on a second axis.
        Returns the Figure; writes it to `path` when given."""
        from .plots import plot_efforts
        return plot_efforts(self, path=path, ax=ax)

    def plot_motion(self, path=None, trace=(), snapshots=6, exaggeration=1.0, ax=None):
        """`snapshots` states of the mechanism evenly over the result (the earlier ones
        faded), with the whole paths of the `trace` points [(body, local point), …] (a
        coupler curve); beams deformed by `exaggeration` times their modes. Returns the
        Figure; writes it to `path` when given (`mechsim.results.animation`)."""
        from .animation import plot_motion
        return plot_motion(self, path, trace, snapshots, exaggeration, ax)

    def animate(self, path, trace=(), fps=30, exaggeration=1.0, max_frames=None) -> Path:
        """Write the motion as a GIF (Pillow) or an MP4 (where ffmpeg is installed) at `fps`
        frames a second, at most 12 s long (longer results decimated; or `max_frames`),
        the `trace` points' paths drawn as they are covered and the singular passages
        shaded on a time bar. Returns the path (`mechsim.results.animation`)."""
        from .animation import animate
        return animate(self, path, trace, fps, exaggeration, max_frames)

    def animation(self, trace=(), fps=30, exaggeration=1.0, max_frames=None):
        """The motion drawn as `animate` draws it, as an `Animation` held in memory: a GIF
        that Jupyter shows inline (the last value of a cell), `.save(path)` writes, and
        whose `pace` says how fast it plays against real time."""
        from .animation import animation_gif
        return animation_gif(self, trace, fps, exaggeration, max_frames)

    def export(self, path, every: int = 1) -> Path:
        """Write the motion as a meshio time series (`.xdmf` opens in ParaView, its data in
        HDF5 beside it where h5py is installed; `.vtu` gives one binary file per output time
        and a `.pvd` collection): rigid bodies as lines through their joints, beams as
        deformed polylines with displacement, velocity and modal fields; `every`: every k-th
        sample. See `mechsim.results.export`."""
        from .export import export
        p = self._need_problem("drawing the bodies for an export")
        return export(self, path, p.drawing, every)

    # --- persistence -------------------------------------------------------------------------
    def table(self, points=(), joints=None, drivers=None, velocities=True,
              channels=None) -> dict:
        """{column: (n,) array}, each column named with its SI unit: time, coordinates and
        (with `velocities`) their rates, the global positions of `points` ((body, local)
        pairs), for `joints` / `drivers` (names or objects, or True for all) their forces,
        couples, coordinates and rates / efforts and powers, and the user's `channels`
        ({name with unit: a function of the result giving one number per sample})
        (`mechsim.results.table`)."""
        from .table import columns
        return columns(self, points, joints, drivers, velocities, channels)

    def to_csv(self, path, points=(), joints=None, drivers=None, velocities=True,
               channels=None) -> Path:
        """`table` written as CSV to `path` (a header of the columns with their units, a row
        per sample); returns the path."""
        from .table import write_csv
        return write_csv(self.table(points, joints, drivers, velocities, channels), path)

    def to_pandas(self, points=(), joints=None, drivers=None, velocities=True, channels=None):
        """`table` as a pandas DataFrame (needs the `pandas` extra)."""
        from .table import data_frame
        return data_frame(self.table(points, joints, drivers, velocities, channels))

    def save(self, path, reactions: bool | None = None) -> Path:
        """Write the result (with its energy log and constraint violation) to an .npz file.
        `reactions`: also the joint reactions, driver efforts and joint coordinates, so a
        loaded result answers for them (None: where computed already); and the states'
        sensitivities the analysis carried (`StoredSensitivities`)."""
        path = Path(path)
        meta = metadata(self)
        extra = {}
        if self.problem is not None or "energy" in self.__dict__:
            e = self.energy
            extra = {"kinetic": e.kinetic, "potential": e.potential, "strain": e.strain,
                     "work": e.work}
            if e.channels:
                extra["work_by"] = e.work_by
                meta["work_channels"] = list(e.channels)
                meta["work_includes"] = e.includes
        if self.problem is not None or "constraint_violation" in self.__dict__:
            extra["constraint_violation"] = self.constraint_violation
        table = None
        if reactions or (reactions is None and "reactions" in self.__dict__
                         and self.reactions.computed):
            table = self.reactions
        if self.sensitivities is not None:
            stored = self.sensitivities.stored()
            meta["sensitivities"] = {"names": list(self.sensitivities.names), "keys": list(stored)}
            extra.update({f"sensitivity_{k}": a for k, a in stored.items()})
        if table is not None:
            arrays = table.to_arrays()
            meta["reactions"] = {"keys": list(arrays), "joints": table.joint_names,
                                 "drivers": table.driver_names,
                                 "kinds": {j: table.kind(j) for j in table.joint_names},
                                 "driver_kinds": {d: table.driver_kind(d)
                                                  for d in table.driver_names}}
            extra.update({f"reaction_{k}": a for k, a in enumerate(arrays.values())})
        from ..files import written
        final = path if path.suffix == ".npz" else path.with_name(path.name + ".npz")

        def write(p):
            with open(p, "wb") as f:
                np.savez_compressed(f, t=self.t, q=self.q, v=self.v,
                                    meta=np.array(json.dumps(meta, default=float)), **extra)
        return written(final, write)


def _cumulative_integral(y, t):
    """∫_{t₀}^{t} y dt at every sample (along axis 0): Simpson where there are three or
    more samples."""
    from scipy.integrate import cumulative_simpson, cumulative_trapezoid
    if len(t) < 3:
        return cumulative_trapezoid(y, t, initial=0.0, axis=0)
    return cumulative_simpson(y, x=t, initial=0.0, axis=0)
