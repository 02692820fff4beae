"""Command line: `mechsim run SCENE`, `mechsim sweep STUDY`, `mechsim optimize DESIGN`,
`mechsim bench [PROBLEM ...]`."""

from __future__ import annotations

import argparse
import contextlib
import os
import sys
import time
from pathlib import Path

import numpy as np


def _run(args) -> int:
    from ..model import ModelError
    from .scene import load_scene

    t0 = time.perf_counter()
    try:
        scene = load_scene(args.scene)
        out_dir, targets = _output_paths(args, scene)
    except ModelError as exc:
        print(f"mechsim: {exc}", file=sys.stderr)
        return 2
    mech = scene.mechanism
    overrides = {key: value for key, value in (
        ("method", args.method), ("t_end", args.t_end), ("rtol", args.rtol),
        ("atol", args.atol), ("max_step", args.max_step), ("output_step", args.output_step),
        ("h", args.fixed_step), ("integrator", args.integrator)) if value is not None}
    try:
        if overrides:
            from ..run.solver import check_simulate_arguments
            settings = {**scene.simulation, **overrides}
            check_simulate_arguments(len(mech.coordinate_names), settings.pop("t_end"),
                                     settings.pop("method", None), settings)
        mech.problem()
        t_build = time.perf_counter() - t0
        report = mech.dof()
        assembly = mech.assemble(t=scene.simulation.get("t_start", 0.0))
        if not args.quiet:
            _header(scene, mech, report, assembly, t_build)
            _analyses(args, mech, scene.simulation.get("t_start", 0.0))
            if sys.stderr.isatty():                 # a progress bar on a terminal only
                overrides["progress"] = True
        if args.kinematics:
            settings = {**scene.simulation, **overrides}
            t_end = settings["t_end"]
            step = settings.get("output_step") or (t_end - settings.get("t_start", 0.0)) / 1000
            res = mech.kinematics(t_end, step, settings.get("t_start", 0.0))
        else:
            res = scene.simulate(**overrides)
    except (ModelError, ValueError) as exc:
        print(f"mechsim: {exc}", file=sys.stderr)
        return 2
    written = []
    wants_reactions = bool(scene.output.get("reactions") or scene.output.get("efforts"))
    # The result first, with Ctrl-C and SIGTERM held: a finished run is never lost to an
    # interrupt during its summary or plots (each output is staged: `mechsim.files`).
    saves = [target for target in targets if target[0] == "save"]
    stage = "saving the result"
    try:
        with _signals_held():
            for kind, path in saves:
                written.append(_write(kind, path, res, scene.output, wants_reactions))
        stage = "the summary"
        if not args.quiet:
            _summary(scene, res)
        elif not res.success:
            print(f"mechsim: {res.status}: {res.message}", file=sys.stderr)
        for kind, path in targets:
            if kind != "save":
                stage = f"writing {path}"
                written.append(_write(kind, path, res, scene.output, wants_reactions))
    except KeyboardInterrupt:
        print(f"mechsim: interrupted during {stage} (nothing of it was written); written "
              f"before: {', '.join(str(w) for w in written) or 'nothing'}", file=sys.stderr)
        return 130
    except OSError as exc:
        print(f"mechsim: {stage} failed: {exc}; written before: "
              f"{', '.join(str(w) for w in written) or 'nothing'}", file=sys.stderr)
        return 1
    for w in written if not args.quiet else ():
        print(f"wrote      {w}")
    return 0 if res.success else 1


@contextlib.contextmanager
def _terminate_as_interrupt():
    """Within the block SIGTERM (a job scheduler's stop, `kill`) is taken as Ctrl-C: a run
    ends with its partial result, and an output being written is left out whole, instead
    of the process dying mid-file."""
    import signal

    def interrupt(signum, frame):
        raise KeyboardInterrupt

    try:
        before = signal.signal(signal.SIGTERM, interrupt)
    except (ValueError, OSError):        # not the main thread
        yield
        return
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, before)


@contextlib.contextmanager
def _signals_held():
    """SIGINT and SIGTERM held (delivered when the block ends) where the platform can."""
    import signal
    held = {signal.SIGINT, signal.SIGTERM}
    try:
        signal.pthread_sigmask(signal.SIG_BLOCK, held)
    except (AttributeError, ValueError, OSError):
        yield
        return
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_UNBLOCK, held)


def _write(kind, path, res, output, wants_reactions):
    """Write one of a run's outputs; returns its path."""
    if kind == "energy":
        res.plot_energy(path=path)
    elif kind == "reactions":
        wanted = output.get("reactions")
        res.plot_reactions(path, joints=wanted if isinstance(wanted, list) else None)
    elif kind == "efforts":
        res.plot_efforts(path=path)
    elif kind == "save":
        return res.save(path, reactions=wants_reactions or None)
    elif kind == "animate":
        return res.animate(path, trace=output.get("points", []))
    elif kind == "table":
        return res.to_csv(path, points=output.get("points", ()),
                          joints=output.get("reactions") or None,
                          drivers=True if output.get("efforts") else None)
    else:
        return res.export(path)
    return path


def _output_paths(args, scene):
    """(output directory, [(what, path)]) of a run, checked before anything is built: the
    scene's files stay inside its output directory (`--out`, else its `directory`, else
    out/<scene name>), symbolic links included."""
    from .scene import SceneError
    out = scene.output
    out_dir = Path(args.out or out.get("directory") or Path("out") / scene.path.stem)
    stem = scene.path.stem
    targets = [] if args.no_plots else [(name, out_dir / f"{stem}_{name}.png")
                                        for name in out.get("plots", [])]
    if out.get("save"):
        targets.append(("save", out_dir / f"{stem}.npz"))
    if out.get("export"):
        targets.append(("export", out_dir / out["export"]))
    if out.get("table"):
        targets.append(("table", out_dir / out["table"]))
    if out.get("animate") or args.animate:
        targets.append(("animate", out_dir / f"{stem}.gif"))
    if targets and (out_dir.is_symlink() or (out_dir.exists() and not out_dir.is_dir())):
        raise SceneError(f"{scene.path.name}: the output directory {out_dir} is "
                         f"{'a symbolic link' if out_dir.is_symlink() else 'not a directory'}; "
                         "mechsim writes only into real directories (choose another with "
                         "--out or [output] directory)")
    base = out_dir.resolve()
    for _, path in targets:
        if not path.resolve().is_relative_to(base):
            raise SceneError(f"{scene.path.name}: [output] {path} leaves the output directory "
                             f"{out_dir} (through a link); choose a path inside it")
    return out_dir, targets


def _analyses(args, mech, t) -> None:
    """`--equilibrium` and `--modes`: the static equilibrium and the linearized modes about
    it, printed before the run."""
    if not (args.equilibrium or args.modes):
        return
    eq = mech.equilibrium(t)
    print(f"equilibrium {'found' if eq.converged else 'not found'} ({eq.method}): {eq.message}")
    if eq.converged:
        for name, value in zip(eq.coordinates, eq.q[[mech.coordinate_names.index(c)
                                                        for c in eq.coordinates]]):
            print(f"           {name} = {value:.6g}")
        for joint in mech.joints:
            F = eq.joint_force(joint)
            print(f"           joint '{joint.name}': force ({F[0]:.4g}, {F[1]:.4g}) N on "
                  f"'{joint.body_b.name}'")
        for driver in mech.drivers:
            unit = "N" if driver.joint.kind == "prismatic" else "N·m"
            print(f"           driver '{driver.name}' holds {eq.driver_effort(driver):.4g} "
                  f"{unit}")
    if args.modes and not eq.coordinates:
        print("modes      none: the drivers fix every degree of freedom")
    elif args.modes:
        lin = mech.linearize(eq.q if eq.converged else None, t=t)
        print(f"modes      about the {'equilibrium' if lin.equilibrium else 'assembled state'}"
              f" in {', '.join(lin.coordinates)}:")
        for k, (w, z) in enumerate(zip(lin.frequencies, lin.damping_ratios), start=1):
            print(f"           {k}: ω = {w:.6g} rad/s ({w / (2 * np.pi):.6g} Hz), ζ = {z:.3g}")


def _header(scene, mech, report, assembly, t_build) -> None:
    """What is about to run, printed before it runs."""
    print(f"scene      {scene.path}  ({mech.name})")
    assembled = getattr(mech.problem().model, "ASSEMBLED", False)
    how = ("assembled from joint-type kernels" if assembled else "fused model") + \
        (", loaded from cache" if mech.from_cache else ", generated and cached")
    print(f"model      {how} in {t_build:.3f} s; {report}")
    print(f"assembly   {assembly}", flush=True)


def _summary(scene, res) -> None:
    """The run's summary on standard output."""
    s = res.stats
    if s.get("method") == "kinematics":
        print(f"kinematics {s['samples']} configurations solved, {s['wall_time']:.3f} s wall")
    else:
        print(f"solver     {s['method']} / {s['integrator']}: {s['steps']} steps, "
              f"{s['rhs_evaluations']} right-hand sides, {s['wall_time']:.3f} s wall")
    print(f"status     {res.status}: {res.message}  (t = {res.t[0]:g} … {res.t[-1]:g} s, "
          f"{len(res.t)} samples)")
    print(f"energy     final drift {res.energy_drift[-1]:+.3e}, "
          f"max |drift| {abs(res.energy_drift).max():.3e} (scale {res.energy_scale:.4g} J)")
    if res.energy.channels:
        print(f"work       {res.energy.includes}")
    if np.any(res.energy.strain):
        print(f"strain     max elastic energy {res.energy.strain.max():.4g} J at "
              f"t = {res.t[np.argmax(res.energy.strain)]:.4f} s")
    print(f"constraint max ‖Φ‖ {res.constraint_violation.max():.3e}")
    if res.singular_passages:
        drift = res.passage_drift()
        print(f"singular   {len(res.singular_passages)} passage(s), largest energy drift across "
              f"one {np.max(np.abs(drift)):.1e}:")
        for p, jump in list(zip(res.singular_passages, drift))[:LISTED]:
            joints = f", joints {', '.join(p.joints)}" if p.joints else ""
            how = "; crossed by the passage bridge" if p.bridged else ""
            print(f"           {p.t_start:.4f} – {p.t_end:.4f} s, closest at {p.t_min:.4f} s "
                  f"(σ_min/σ_max = {p.min_sigma:.3g}, energy drift {jump:+.1e} across)"
                  f"{joints}{how}")
        _more(len(res.singular_passages), "passages")
    for sw in res.switches[:LISTED]:
        print(f"switch     t = {sw.t:.4f} s: {sw.from_method} → {sw.to_method} ({sw.reason})")
    _more(len(res.switches), "switches")
    for i in res.impacts[:LISTED]:
        what = "comes to rest" if i.resting else f"rebounds at {i.rate_after:+.4g}"
        print(f"impact     t = {i.t:.6f} s on stop '{i.stop}' at {i.limit:g}: rate "
              f"{i.rate_before:+.4g}, {what}, {i.energy_lost:.4g} J taken")
    _more(len(res.impacts), "impacts")
    for f in res.friction_switches[:LISTED]:
        print(f"friction   t = {f.t:.6f} s: '{f.friction}' {f.before} → {f.after} (force "
              f"{f.force:+.4g}, static limit {f.limit:.4g})")
    _more(len(res.friction_switches), "stick-slip switches")
    for body, local in scene.output.get("points", []):
        p = res.point(body, local)[-1]
        print(f"point      {body} {tuple(local)} at t = {res.t[-1]:g}: ({p[0]:.6f}, {p[1]:.6f})")
    _reaction_summary(scene.output, res)


# The summary lists this many passages and switches; a saved result holds them all.
LISTED = 4


def _more(count, what) -> None:
    if count > LISTED:
        print(f"           … {count - LISTED} more {what} (all of them in the saved "
              "result)")


def _reaction_summary(output, res) -> None:
    """Peak joint forces (`[output] reactions`) and the drivers' peak and RMS effort and
    power (`[output] efforts`)."""
    wanted, efforts = output.get("reactions"), output.get("efforts")
    if not (wanted or efforts):
        return
    figures = res.cycle_figures()
    names = figures.joints if wanted is True else (wanted or [])
    for name in names:
        j = figures.joints[name]
        print(f"reaction   joint '{name}': peak force {j['peak_force']:.4g} N at "
              f"t = {j['at']:.4g} s")
    for name, mu in figures.transmission.items():
        print(f"reaction   transmission angle at '{name}': {mu['min']:.1f}° … {mu['max']:.1f}°")
    for name, d in (figures.drivers.items() if efforts else ()):
        print(f"effort     driver '{name}': peak {d['peak_effort']:.4g} {d['unit']}, RMS "
              f"{d['rms_effort']:.4g} {d['unit']}; power peak {d['peak_power']:.4g} W, mean "
              f"{d['mean_power']:.4g} W")
    if figures.note:
        print(f"reaction   {figures.note}")


def _numbers(text, option, default) -> list[float]:
    """A comma-separated list of positive numbers (or the default when not given)."""
    if not text:
        return list(default)
    try:
        values = [float(x) for x in text.split(",")]
    except ValueError:
        values = []
    if not values or not all(v > 0 for v in values):
        raise ValueError(f"`{option}` takes comma-separated positive numbers, got {text!r}")
    return values


def _peers(rows, problems, repeat, out, floor=None) -> list:
    """`mechsim bench peers`: MuJoCo and Exudyn on `problems` beside mechsim's `rows`, and
    the exact 1-DOF floor (`floor`, timed in the rounds of mechsim's runs)."""
    from . import peers
    try:
        import exudyn  # noqa: F401
        import mujoco  # noqa: F401
    except ImportError:
        raise ValueError("bench peers needs mujoco and exudyn: pip install mujoco exudyn "
                         "(from a checkout, pip install '.[peers]')") from None
    peer_rows = peers.run(problems, repeat=repeat, floor=floor)
    print("peers (fixed steps) and mechsim's cheapest run at least as accurate:")
    for line in peers.compare(rows, peer_rows):
        print(line)
    against = peers.against_reference(rows, peer_rows)
    if against:
        print("mechsim's runs against scipy's DOP853 on the exact 1-DOF equation at the "
              "same error:")
        for line in against:
            print(line)
    return peers.write(rows, peer_rows, out)


def _bench(args) -> int:
    from . import bench

    problems = args.problems or [*bench.DEFAULT_PROBLEMS, "random"]
    shooting = "coulomb" in problems
    sweep = "random" in problems
    analysis = "analysis" in problems
    costs = "costs" in problems
    peers = "peers" in problems
    problems = [p for p in problems if p not in ("coulomb", "random", "analysis", "costs",
                                                 "peers")]
    if peers and not problems:
        problems = ["double-four-bar", "crank-rocker"]
    methods = args.methods.split(",") if args.methods else list(bench.DEFAULT_METHODS)
    try:
        rtols = _numbers(args.rtols, "--rtols", bench.DEFAULT_RTOLS)
        accuracies = _numbers(args.accuracies, "--accuracies", bench.DEFAULT_ACCURACIES)
        written = []
        if problems:
            repeat = 1 if args.repeat is None else args.repeat
            bench.check(problems, methods, repeat)
            print(bench.HEADER)
            floor = None
            if peers:                      # the floor in the rounds of mechsim's runs
                from .peers import Floor
                floor = Floor()
            rows = bench.run(problems, methods, rtols, integrator=args.integrator,
                             max_steps=args.max_steps, repeat=repeat, beside=floor)
            for rtol in rtols:
                for name, r in bench.ratios(rows, rtol).items():
                    print(f"ratios at rtol {rtol:.0e}, {name}: " +
                          ", ".join(f"{k} = {v:.2f}" for k, v in r.items()))
            for name, error, best in bench.equal_error(rows):      # at equal accuracy
                print(bench.format_within(name, error, best))
            for line in bench.proportionality(rows):
                print(line)
            written += bench.write(rows, args.out)
            if peers:
                written += _peers(rows, problems, repeat, args.out, floor)
        if sweep:
            print(f"random mechanisms: the default method against projection at rtol "
                  f"{rtols[-1]:.0e}")
            print(bench.RANDOM_HEADER)
            random_rows = bench.random_run(rtol=rtols[-1])
            print(bench.random_summary(random_rows))
            written += bench.write_random(random_rows, args.out)
        if analysis:
            print("engineering analysis: reactions against the simulation's own time; "
                  "equilibrium and linearization of the 40-window chain")
            from . import bench_analysis
            print(bench_analysis.ANALYSIS_HEADER)
            arows = bench_analysis.analysis_run(repeat=3 if args.repeat is None else args.repeat)
            for r in arows:
                print(bench_analysis.format_analysis(r))
            written += bench_analysis.write_analysis(arows, args.out)
        if costs:
            from . import costs as cost_cases
            print("the work of the cases whose counts the tests leave to this bench")
            print(cost_cases.HEADER)
            written += cost_cases.write(cost_cases.run(), args.out)
        if shooting:
            print("Coulomb oscillator: shooting against brute force to the same accuracy")
            print(bench.SHOOTING_HEADER)
            srows = bench.shooting_run(accuracies=accuracies,
                                       repeat=20 if args.repeat is None else args.repeat)
            written += bench.write_shooting(srows, args.out)
    except ValueError as exc:
        print(f"mechsim: {exc}", file=sys.stderr)
        return 2
    for path in written:
        print(f"wrote {path}")
    return 0


def _optimize(args) -> int:
    from ..model import ModelError
    from .design_file import load_design, write_design

    try:
        spec = load_design(args.design)
    except (ModelError, OSError) as exc:
        print(f"mechsim: {exc}", file=sys.stderr)
        return 2
    if args.out:
        spec.output = Path(args.out)
    design, _ = spec.run()
    path = write_design(spec, design)
    if not args.quiet:
        chosen = ", ".join(f"{k} = {v:.6g}" for k, v in design.parameters.items())
        print(f"{spec.path.name}: {chosen}")
        print(f"objective {design.value:.6g} after {design.evaluations} evaluations "
              f"({design.failures} designs not evaluable), {design.wall_time:.2f} s: "
              f"{design.message}")
        print(f"wrote {path}")
    return 0 if design.success else 1


def _sweep(args) -> int:
    from ..model import ModelError
    from .study_file import load_study, summary, write_table

    try:
        study_file = load_study(args.study)
        if args.workers is not None and args.workers < 1:
            raise ModelError(f"--workers must be a count ≥ 1, got {args.workers}")
    except (ModelError, OSError) as exc:
        print(f"mechsim: {exc}", file=sys.stderr)
        return 2
    output = Path(args.out) if args.out else study_file.output
    client = None
    if args.scheduler:
        try:
            from distributed import Client
        except ImportError:
            print("mechsim: --scheduler needs dask.distributed (pip install distributed; "
                  "from a checkout, pip install '.[dask]')", file=sys.stderr)
            return 2
        try:
            client = Client(args.scheduler, timeout="10s")
        except (OSError, TimeoutError, ValueError) as exc:
            print(f"mechsim: cannot reach the dask scheduler at {args.scheduler!r}: {exc}; "
                  "check the address (tcp://host:port) and that the scheduler runs",
                  file=sys.stderr)
            return 2
    if not args.quiet:
        where = f"dask scheduler {args.scheduler}" if client else \
            f"{args.workers or study_file.workers or os.cpu_count()} local process(es)"
        print(f"study      {study_file.path} of scene {study_file.scene}, on {where}",
              flush=True)
    try:
        study = study_file.run(client=client, workers=args.workers,
                               progress=not args.quiet and sys.stderr.isatty())
    finally:
        if client is not None:
            client.close()
    write_table(study, output)
    if not args.quiet:
        print("\n".join(summary(study)))
        print(f"wrote {output}")
    return 0 if not len(study.failed) else 1


def _study_commands(sub) -> None:
    """The `sweep` and `optimize` subcommands."""
    study = sub.add_parser("sweep", help="run a parameter study of a scene (a TOML study "
                                         "file, see mechanisms/studies/)")
    study.add_argument("study", help="the study file")
    study.add_argument("--workers", type=int, help="local processes (default: the file's "
                                                   "`workers`, else every core)")
    study.add_argument("--scheduler", metavar="ADDRESS",
                       help="run on this dask.distributed scheduler instead")
    study.add_argument("--out", help="the CSV table (default: the file's `output`)")
    study.add_argument("--quiet", action="store_true", help="print errors only")
    study.set_defaults(func=_sweep)
    design = sub.add_parser("optimize", help="choose some of a scene's parameters for an "
                                             "objective on exact gradients (a TOML design "
                                             "file, see mechanisms/studies/)")
    design.add_argument("design", help="the design file")
    design.add_argument("--out", help="where the design goes (default: the file's `output`)")
    design.add_argument("--quiet", action="store_true", help="print errors only")
    design.set_defaults(func=_optimize)


def main(argv=None) -> int:
    from .. import __version__
    parser = argparse.ArgumentParser(prog="mechsim", description="Planar mechanism simulator")
    parser.add_argument("--version", action="version", version=f"mechsim {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)
    run = sub.add_parser("run", help="simulate a scene file, print a summary, write plots")
    run.add_argument("scene", help="a TOML scene file (see mechanisms/)")
    run.add_argument("--out", help="output directory (default: out/<scene name>)")
    run.add_argument("--method", help="override the scene's method")
    run.add_argument("--t-end", type=float, help="override the scene's end time")
    run.add_argument("--integrator", help="override the method's integrator (DOP853, adams, "
                                          "Radau, BDF, LSODA, trapezoidal, …)")
    run.add_argument("--rtol", type=float,
                     help="relative accuracy of the whole run (its steps are held to a share)")
    run.add_argument("--atol", type=float, help="absolute tolerance")
    run.add_argument("--max-step", type=float, help="largest step [s]")
    run.add_argument("--output-step", type=float, help="spacing of the output samples [s]")
    run.add_argument("--fixed-step", type=float, metavar="H",
                     help="the step of a fixed-step method such as ss-newmark [s]")
    run.add_argument("--quiet", action="store_true", help="print errors only")
    run.add_argument("--animate", action="store_true",
                     help="write <scene>.gif of the motion (tracing the scene's points)")
    run.add_argument("--no-plots", action="store_true", help="write no plots")
    run.add_argument("--equilibrium", action="store_true",
                     help="print the static equilibrium and its reactions first")
    run.add_argument("--modes", action="store_true",
                     help="print the natural frequencies about the equilibrium first")
    run.add_argument("--kinematics", action="store_true",
                     help="solve a fully driven mechanism's motion from its constraints "
                          "(kinematic analysis) instead of integrating it")
    run.set_defaults(func=_run)
    bench = sub.add_parser("bench", help="work–precision table and plots for the solvers")
    bench.add_argument("problems", nargs="*",
                       help="parallelogram, double-four-bar, driven-slider-crank, "
                            "forty-window, flexible-four-bar, random (12 random mechanisms: "
                            "hybrid against projection at the smallest rtol), coulomb "
                            "(shooting against brute force), analysis (reactions, "
                            "equilibrium and linearization), crank-rocker, seven-window, "
                            "ten-window, hundred-window, peers (MuJoCo and Exudyn beside "
                            "mechsim on the problems named, default double-four-bar and "
                            "crank-rocker: the peers extra), "
                            "costs (steps, right-hand sides and bridge evaluations of the "
                            "cases whose counts the tests leave to it); default: the first "
                            "three and random")
    bench.add_argument("--methods", help="comma-separated (default: lu,projection,"
                       "projection-svd,hybrid,baumgarte; projection-svd is the projection "
                       "method with factorization='svd', the seed's)")
    bench.add_argument("--rtols", help="comma-separated tolerances (default: 1e-5,…,1e-9)")
    bench.add_argument("--integrator", help="override every method's default integrator")
    bench.add_argument("--max-steps", type=int, default=20000,
                       help="give up a run after this many steps (default 20000)")
    bench.add_argument("--repeat", type=int,
                       help="run everything this many times in rounds and keep each run's "
                            "shortest wall time (default 1; 20 for coulomb, whose runs take "
                            "milliseconds)")
    bench.add_argument("--accuracies",
                       help="coulomb: comma-separated accuracies of the periodic state "
                            "(default: 1e-4,1e-6,1e-8,1e-10)")
    bench.add_argument("--out", default="out/bench", help="where to write CSV and plots")
    bench.set_defaults(func=_bench)
    _study_commands(sub)
    args = parser.parse_args(argv)
    try:
        with _terminate_as_interrupt():
            return args.func(args)
    except BrokenPipeError:
        # Output piped into `head` and the like: stop quietly, as Unix tools do.
        import os
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0


if __name__ == "__main__":
    sys.exit(main())
