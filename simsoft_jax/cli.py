"""Command line: ``simsoft-jax run | validate | princeton | calibrate | predict | bench``.

* ``run SCENE -o OUT.json|.npz [--force] [--no-stability] [--no-progress] [--plot F.png]
  [--animate F.gif]``: solve a scene (exit 1 if not converged, 2 if the scene or an
  output or figure path is invalid, 130 on Ctrl-C: at once during a compile or a static
  solve, after writing the states computed so far in a dynamic run, a second Ctrl-C
  stopping that writing),
  with a progress line on stderr for dynamic runs and a warning for an unstable static
  equilibrium; prints the compile and the solve time separately;
* ``validate SCENE``: check a scene file without solving it;
* ``princeton``: the 25 load cases of the Princeton beam, a results table and figures
  (the paper's Figs. 15-18 against ``--measurements``; without them, Figs. 16-18 against
  the shipped ANSYS solid-element predictions in ``OUT/vs_ansys_solid``, unless
  ``--no-published``);
* ``calibrate --scenes S... --measurements M.csv --params EIy,EIz,GJ -o fitted.json``:
  fit sectional parameters to measured positions; with an observation file (points at
  offsets, displacements, rotations/twist, reference cases, std), parameters by groups
  (``EIy@0-5=0.5:2`` or ``--groups groups.toml``, priors, ``--smoothness``), held-out
  rows (``--split N``: every N-th row; ``--hold-out-by tip_mass [--hold-out
  upper|lower|alternate] [--within test]``: by a column) predicted after the fit with
  their errors per quantity, and groups the data cannot identify named with the reason;
  ``--table-map pazy-tip-sweep|MAP.toml [--where skin=0]`` reads a data set's own table
  (e.g. the Pazy ``tip_mass_sweep_measured.csv``) as observations (shipped maps:
  ``pazy-tip-sweep``, ``prepazy-tip-sweep``, ``minguet-strips``, ``tdcr-tip-height``);
* ``predict --fitted fitted.json --scenes S... --measurements held_out.csv``: per-row
  predictions and errors with a fitted result;
* ``bench [--quick] [--only NAMES] [--out DIR]``: the benchmark suite of the source
  checkout (tables, plots, JSON; see benchmarks/README.md).

Compiled solver programs are kept in JAX's persistent compilation cache
(:mod:`simsoft_jax.solvers.compile_cache`; ``~/.cache/simsoft_jax/xla`` or
``$SIMSOFT_JAX_CACHE_DIR``), so a second run of a scene structure does not compile
again: ``--cache-dir DIR`` moves it, ``--no-cache`` (or ``SIMSOFT_JAX_CACHE=0``) turns it
off; both go before or after the command name (``bench`` has its own options). A
program compiled for a new scene structure says so on stderr, with the time it took
(``SIMSOFT_JAX_QUIET=1`` silences it).
"""
from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path

import numpy as np


def _check_figures(args, kind: str) -> None:
    """``--plot`` and ``--animate`` checked before solving: suffix, folder, and a dynamic
    scene for an animation."""
    from .pipeline.output import check_figure
    if args.plot:
        from matplotlib.backend_bases import FigureCanvasBase
        check_figure(args.plot, "--plot", tuple(
            "." + s for s in sorted(FigureCanvasBase.get_supported_filetypes())))
    if args.animate:
        check_figure(args.animate, "--animate", (".gif", ".mp4"))
        if kind != "dynamic":
            raise ValueError("--animate: needs a dynamic scene (a static result has no "
                             "motion)")


def _run(args) -> int:
    from .scene.key_checks import readable
    from .model.built_models import scene_of
    from .pipeline.output import check_output
    from .pipeline.results import run
    def progress(t, t_end):
        print(f"\r  t = {t:.4g} / {t_end:.4g} s", end="", file=sys.stderr, flush=True)

    try:
        if args.output:  # before solving: a bad output path must not cost a solve
            check_output(args.output, force=args.force)
        scene = scene_of(args.scene)
        _check_figures(args, scene.solver.kind)
        result = run(scene, progress=None if args.no_progress else progress,
                     stability=not args.no_stability)
    except (ValueError, NotImplementedError) as err:
        print(f"error: {readable(str(err))}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("\ninterrupted before any state was computed: nothing written", file=sys.stderr)
        return 130
    if result.time is not None and not args.no_progress:
        print(file=sys.stderr)  # end the progress line
    if args.output:
        if result.status == "interrupted":
            print(f"writing the states computed so far to {args.output} (Ctrl-C again "
                  "stops the writing)", file=sys.stderr, flush=True)
        try:
            result.save(args.output)
        except OSError as err:
            print(f"error: output: cannot write {args.output!r}: {err.strerror or err} "
                  "(the old file, if any, is unchanged)", file=sys.stderr)
            return 2
        except KeyboardInterrupt:
            print(f"\ninterrupted while writing: {args.output} not written (the old file, "
                  "if any, is unchanged)", file=sys.stderr)
            return 130
    if result.status == "interrupted":
        print(f"interrupted at t = {result.failed_at:.6g} s; "
              + (f"wrote the states computed so far to {args.output}" if args.output
                 else "nothing written (no -o)"), file=sys.stderr)
        return 130
    if args.plot or args.animate:
        try:
            _figures(result, args.plot, args.animate)
        except (ValueError, RuntimeError) as err:
            print(f"error: {err}", file=sys.stderr)
            return 2
    if result.stability is not None and not result.stability["stable"]:
        print(f"warning: unstable equilibrium: {result.stability['negative_eigenvalues']} "
              "negative eigenvalues of the tangent (past a buckling or snap-through load; "
              "a small perturbation leaves this state)", file=sys.stderr)
    status = "converged" if result.converged else f"NOT converged: {result.message}"
    detail = (f"{len(result.time)} saved states" if result.time is not None
              else f"residual {result.residual_norm:.3g}")
    print(readable(f"{result.name or args.scene}: {status}; {result.newton_iterations} "
                   f"Newton iterations, {detail}, solve {result.wall_time_s:.4f} s, "
                   f"compile {result.compile_time_s:.2f} s"
                   + (f"; wrote {args.output}" if args.output else "")))
    if not result.converged:
        print(f"error: {result.message}", file=sys.stderr)
    return 0 if result.converged else 1


def _figures(result, plot, animate):
    """``--plot``: the final shape (static) or six time snapshots (dynamic) of every rod;
    ``--animate``: the motion of the first rod (GIF, or MP4 with ffmpeg)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from . import plotting
    rods = [r.name for r in result.model.structure.rods]
    if plot:
        fig = None
        for k, rod in enumerate(rods):
            ax = None if fig is None else fig.axes[0]
            color = f"C{k}"
            if result.time is None:
                fig = plotting.plot_result(result, rod, ax=ax, color=color, label=rod,
                                           title=result.name)
            elif k == 0:
                fig = plotting.plot_result_snapshots(result, rod, title=result.name)
            else:
                p, R = plotting.sample_result(result, rod)
                idx = np.unique(np.linspace(0, len(p) - 1, 6).round().astype(int))
                plotting.plot_configurations(p[idx], R[idx], ax=ax)
        fig.savefig(plot, dpi=120, bbox_inches="tight")
        plt.close(fig)
        print(f"wrote {plot}")
    if animate:
        plotting.animate_result(result, rods[0], animate)
        print(f"wrote {animate}" + (f" (rod {rods[0]!r} of {len(rods)})" if len(rods) > 1 else ""))


def _validate(args) -> int:
    from .scene.key_checks import readable
    from .scene.scene import load_scene
    try:
        scene = load_scene(args.scene)
    except ValueError as err:
        print(f"error: {readable(str(err))}", file=sys.stderr)
        return 2
    rods = ", ".join(f"{r.name} ({r.elements} elements)" for r in scene.rods)
    print(readable(f"{args.scene}: valid {scene.solver.kind} scene; rods: {rods}"))
    return 0


def _princeton(args) -> int:
    from .apps import princeton
    from .apps.princeton_figures import all_figures
    try:
        stations = [float(v) for v in args.stations.split(",")]
        measured = (princeton.read_measurements(args.measurements) if args.measurements
                    else None)
        if measured is not None:
            errors = princeton.errors(measured, args.elements, not args.no_gravity,
                                      args.relative)
            replay = errors.replay
        else:
            errors = None
            replay = princeton.replay(elements=args.elements, gravity=not args.no_gravity,
                                      relative=args.relative, stations=stations)
    except (ValueError, RuntimeError) as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    table = princeton.write_table(out / "princeton_replay.csv", replay, errors)
    figures = all_figures(replay, out, errors)
    print(f"Princeton replay: {len(replay.theta_deg)} cases, {args.elements} elements, "
          f"gravity {'off' if args.no_gravity else 'on'}, deflections "
          f"{'relative to self-weight' if args.relative else 'absolute'}; "
          f"all converged: {bool(replay.converged.all())}")
    print(" theta  load [N]   tip y [mm]   tip z [mm]" + ("   e_mu [%]  tip e [%]" if errors else ""))
    for c in range(len(replay.theta_deg)):
        line = (f"{replay.theta_deg[c]:6g}  {replay.load_N[c]:8.4g}  "
                f"{1e3 * replay.deflection[c, -1, 0]:11.4f}  {1e3 * replay.deflection[c, -1, 1]:11.4f}")
        if errors is not None:
            line += f"  {errors.e_mu[c]:9.4f}  {errors.tip[c]:9.4f}"
        print(line)
    if errors is not None:
        print(f"average mean error {errors.e_mu.mean():.4f} % +- {errors.e_mu.std():.4f}; "
              f"average tip error {errors.tip.mean():.4f} % +- {errors.tip.std():.4f}")
    if not args.measurements and not args.no_published:
        try:
            figures += _princeton_published(args.elements, out / "vs_ansys_solid")
        except (ValueError, RuntimeError) as err:
            print(f"error: {err}", file=sys.stderr)
            return 2
    print("wrote " + ", ".join(str(p) for p in [table, *figures]))
    return 0 if replay.converged.all() else 1


def _princeton_published(elements: int, out: Path) -> list:
    """Eq. (112) at the tip against the shipped ANSYS solid-element predictions (no
    gravity, dead tip loads; model output, see the data README): table and Figs. 16-18
    in ``out``; prints the tip errors. Returns the written paths."""
    from .apps import princeton
    from .data_files import data_path
    from .apps.princeton_figures import summary, station_errors
    err = princeton.errors(princeton.read_published_tip(
        data_path("princeton", "model_predictions_tip.csv")), elements, gravity=False)
    out.mkdir(parents=True, exist_ok=True)
    paths = [princeton.write_table(out / "tip_errors.csv", err.replay, err),
             station_errors(err, out / "fig16_errors.png"), summary(err, out / "fig17_mean_errors.png"),
             summary(err, out / "fig18_error_spread.png", spread=True)]
    print(f"vs ANSYS solid elements (published model output, no gravity, "
          f"{len(err.tip)} tip cases): eq. (112) tip error mean {err.tip.mean():.4f} %, "
          f"max {err.tip.max():.4f} %")
    return paths


def _calibrate(args) -> int:
    import json
    from .studies.calibration import fit_static
    from .studies.measurements import is_observation_file, static_targets
    from .scene.scene import load_scene
    if args.groups or args.split or args.hold_out_by or args.table_map or (
            Path(args.measurements).is_file()
                                     and is_observation_file(args.measurements)):
        return _calibrate_observations(args)
    try:
        scenes = [load_scene(path) for path in args.scenes]
        targets = static_targets(args.measurements, scenes)
        fit = fit_static(targets, args.params or "", max_steps=args.max_steps)
    except (ValueError, RuntimeError) as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    for name, scale, std in zip(fit.params, fit.scale, fit.std):
        print(f"{name:>9s} = {fit.values[name]:.6g}  (x {scale:.5f} +- {std:.5f} of the scenes' value)")
    print(f"rms residual {fit.rms:.4g} m over {len(fit.residuals)} measured components; "
          f"loss {fit.loss_history[0]:.4g} -> {fit.loss_history[-1]:.4g} m^2 in {fit.iterations} steps")
    if args.output:
        Path(args.output).write_text(json.dumps(fit.to_dict(), indent=1))
        print(f"wrote {args.output}")
    return 0


def _observations(args, path):
    """The observation set of ``path`` against the scenes (CLI helper): an observation
    file, or a data set's table read through ``--table-map`` and ``--where``."""
    from .studies.measurements import load_table_map, observation_set
    from .scene.scene import load_scene
    table_map = None
    if args.table_map:
        where = {}
        for item in args.where or ():
            column, sep, values = item.partition("=")
            if not sep or not column.strip() or not values.strip():
                raise ValueError(f"where: expected COLUMN=VALUE[,VALUE...], got {item!r}")
            where[column.strip()] = tuple(v.strip() for v in values.split(","))
        table_map = load_table_map(args.table_map, where)
    elif args.where:
        raise ValueError("where: filters rows read through --table-map; give --table-map")
    return observation_set(path, [load_scene(p) for p in args.scenes], table_map)


def _print_rows(obs, predicted, title):
    """Per-row prediction, measurement, error and error / std, then the rms."""
    print(f"{title}: {len(obs.rows)} rows")
    print(f"{'line':>5s} {'scene':>16s} {'quantity':>8s} {'predicted':>12s} {'measured':>12s} "
          f"{'error':>11s} {'error/std':>9s}")
    for row, pred in zip(obs.rows, predicted):
        err = pred - row.value
        print(f"{row.line:5d} {row.scene[-16:]:>16s} {row.quantity:>8s} {pred:12.6g} "
              f"{row.value:12.6g} {err:11.4g} {err / row.std:9.3f}")
    err = np.asarray(predicted) - obs.value
    print(f"rms error {np.sqrt(np.mean(err ** 2)):.4g}; rms error/std "
          f"{np.sqrt(np.mean((err / obs.std) ** 2)):.4g}")


def _held_out(args, obs) -> np.ndarray:
    """Rows (n,) held out of the fit: every ``--split``-th row, or by a column
    (``--hold-out-by``, ``--hold-out``, ``--within``; :mod:`simsoft_jax.studies.observation_splits`)."""
    from .studies import observation_splits
    held = np.zeros(len(obs.rows), bool)
    if args.split and args.hold_out_by:
        raise ValueError("split: give --split or --hold-out-by, not both")
    if args.split:
        if args.split < 2:
            raise ValueError(f"split: must be >= 2 (every N-th row held out), got {args.split}")
        held[args.split - 1::args.split] = True
    elif args.hold_out_by:
        within = [c for c in (args.within or "").split(",") if c]
        if args.hold_out == "alternate":
            held = observation_splits.alternate(obs, args.hold_out_by, within)[1]
        else:
            lower, upper = observation_splits.lower_upper(obs, args.hold_out_by, within)
            held = upper if args.hold_out == "upper" else lower
    return held


def _calibrate_observations(args) -> int:
    """``calibrate`` with an observation file, groups (``--params`` items or ``--groups``
    TOML) and an optional ``--split N`` (every N-th row held out and predicted)."""
    import json
    from .studies.calibration_groups import fit_groups, load_groups, parse_groups, predict, print_fit
    from .studies.calibration_report import metrics
    try:
        if not args.params and not args.groups:
            raise ValueError("params: give --params or --groups")
        groups = (load_groups(args.groups) if args.groups else ()) + (
            parse_groups(args.params) if args.params else ())
        obs = _observations(args, args.measurements)
        held = _held_out(args, obs)
        fit = fit_groups(obs.subset(~held), groups, max_steps=args.max_steps,
                         smoothness=args.smoothness)
        held_pred = predict(obs.subset(held), groups, fit.scale) if held.any() else None
    except (ValueError, RuntimeError) as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    print_fit(fit)
    print(f"rms residual {fit.rms:.4g} over {int((~held).sum())} fitted rows; loss "
          f"{fit.loss_history[0]:.4g} -> {fit.loss_history[-1]:.4g} in {fit.iterations} steps")
    if held_pred is not None:
        _print_rows(obs.subset(held), held_pred, "held-out rows")
        for quantity, m in metrics(obs.subset(held), held_pred).items():
            print(f"held-out {quantity}: {m['n']} rows, rms {m['rms']:.4g}, max "
                  f"{m['max_abs']:.4g}, mean {m['mean']:.4g}, rms/std {m['rms_over_std']:.3g}")
    if args.output:
        Path(args.output).write_text(json.dumps(fit.to_dict(), indent=1))
        print(f"wrote {args.output}")
    return 0


def _predict(args) -> int:
    """``predict --fitted F.json --scenes S... --measurements M.csv``: per-row predictions
    with the fitted group scales, and their errors."""
    import json
    from .studies.calibration_groups import groups_from_dict, predict
    try:
        try:
            fitted = json.loads(Path(args.fitted).read_text())
        except (OSError, ValueError) as err:
            raise ValueError(f"fitted: cannot read {args.fitted}: {err}") from None
        groups, scale = groups_from_dict(fitted)
        obs = _observations(args, args.measurements)
        predicted = predict(obs, groups, scale)
    except (ValueError, RuntimeError) as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    _print_rows(obs, predicted, f"predictions with {args.fitted}")
    return 0


def _add_calibration_commands(sub):
    """The ``calibrate`` and ``predict`` sub-commands."""
    p_cal = sub.add_parser("calibrate", help="fit section parameters to measurements",
                           parents=[_cache_flags()])
    p_cal.add_argument("--scenes", nargs="+", required=True, help="static scene files")
    p_cal.add_argument("--measurements", required=True,
                       help="CSV: scene,rod,node,x,y,z (positions) or the observation "
                       "layout scene,rod,node,[offset_x,offset_y,offset_z,]quantity,value"
                       "[,std,reference]")
    _add_table_options(p_cal)
    p_cal.add_argument("--params", help="e.g. EIy,EIz,GJ (or E,G); with an observation "
                       "file also groups EIy@0-5, EIy@wing:0-5, bounds EIy@0-5=0.5:2")
    p_cal.add_argument("--groups", help="TOML file of [[groups]] (param, rod, elements, "
                       "bounds, prior, name)")
    p_cal.add_argument("--split", type=int, default=0,
                       help="hold out every N-th row (N >= 2) and predict it after the fit")
    p_cal.add_argument("--hold-out-by", help="a column of the observation file (e.g. "
                       "tip_mass): hold out whole values of it and predict them after the fit")
    p_cal.add_argument("--hold-out", choices=("upper", "lower", "alternate"), default="upper",
                       help="which values of --hold-out-by: the upper or lower half, or every "
                       "other one (default upper: calibrate light, predict heavy)")
    p_cal.add_argument("--within", help="columns whose values split separately, e.g. test")
    p_cal.add_argument("--smoothness", type=float, help="log std of the differences of "
                       "neighbouring groups of one parameter (a smoothness prior)")
    p_cal.add_argument("--max-steps", type=int, default=100,
                       help="optimizer steps at most (default 100)")
    p_cal.add_argument("-o", "--output", help="fitted parameters (.json)")
    p_cal.set_defaults(func=_calibrate)
    p_pre = sub.add_parser("predict", help="predict measurements with a fitted result",
                           parents=[_cache_flags()])
    p_pre.add_argument("--fitted", required=True, help="JSON written by calibrate -o "
                       "(observation layout)")
    p_pre.add_argument("--scenes", nargs="+", required=True, help="static scene files")
    p_pre.add_argument("--measurements", required=True, help="observation CSV (or a data "
                       "set's table with --table-map)")
    _add_table_options(p_pre)
    p_pre.set_defaults(func=_predict)


def _add_table_options(parser):
    """``--table-map`` and ``--where``: read a data set's own table as observations."""
    parser.add_argument("--table-map", help="read --measurements as a data set's own table "
                        "through a map: a TOML file (scene/reference templates, rod, node, "
                        "[[quantities]] column, quantity, scale, std, offset; see "
                        "simsoft_jax.studies.measurements.load_table_map) or a shipped one: "
                        "pazy-tip-sweep, prepazy-tip-sweep (the Pazy and Pre-Pazy tip-mass "
                        "sweeps), minguet-strips (the Minguet-Dugundji displacements), "
                        "tdcr-tip-height (the ISIR tendon robot)")
    parser.add_argument("--where", action="append", metavar="COLUMN=VALUE[,VALUE]",
                        help="with --table-map: keep only the table rows whose COLUMN holds "
                        "one of the values (repeatable, e.g. --where skin=0 --where "
                        "test=bending)")


def _bench(bench_args: list) -> int:
    """Run ``benchmarks/run_all.py`` of the source checkout this package is installed from
    with ``bench_args`` (its own options: --only, --quick, --out, --help)."""
    import importlib.util
    script = Path(__file__).resolve().parents[1] / "benchmarks" / "run_all.py"
    if not script.is_file():
        print(f"error: bench: {script} not found; the benchmarks live in the source "
              "checkout (install it with pip install -e .)", file=sys.stderr)
        return 2
    spec = importlib.util.spec_from_file_location("simsoft_jax_benchmarks", script)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.main(bench_args, prog="simsoft-jax bench")


def _cache_flags() -> argparse.ArgumentParser:
    """``--no-cache`` and ``--cache-dir``, accepted before the command and after it
    (absent ones leave no attribute, so the two places do not overwrite each other)."""
    flags = argparse.ArgumentParser(add_help=False)
    flags.add_argument("--no-cache", action="store_true", default=argparse.SUPPRESS,
                       help="compile without the persistent compilation cache")
    flags.add_argument("--cache-dir", default=argparse.SUPPRESS,
                       help="folder of the persistent compilation cache (default "
                       "$SIMSOFT_JAX_CACHE_DIR or ~/.cache/simsoft_jax/xla)")
    return flags


def _configure_cache(args) -> None:
    """Apply ``--no-cache`` / ``--cache-dir`` (:mod:`simsoft_jax.solvers.compile_cache`)."""
    import os
    from .solvers import compile_cache
    if getattr(args, "no_cache", False):
        os.environ[compile_cache.ENV_SWITCH] = "0"   # also for sj.run inside this process
    else:
        compile_cache.enable(getattr(args, "cache_dir", None))


def main(argv=None) -> int:
    description = re.sub(r":\w+:`([^`]+)`", r"\1", __doc__).replace("``", "")  # plain text
    parser = argparse.ArgumentParser(prog="simsoft-jax", description=description,
                                     formatter_class=argparse.RawDescriptionHelpFormatter,
                                     parents=[_cache_flags()])
    sub = parser.add_subparsers(dest="command", required=True)
    p_run = sub.add_parser("run", help="solve a scene file and optionally write the result",
                           parents=[_cache_flags()])
    p_run.add_argument("scene", help="scene file (.toml or .json)")
    p_run.add_argument("-o", "--output", help="result file (.json or .npz); checked "
                       "before solving, written atomically")
    p_run.add_argument("--force", action="store_true",
                       help="replace the output file if it exists")
    p_run.add_argument("--no-stability", action="store_true",
                       help="static scenes: skip the stability check (the count of negative "
                       "eigenvalues of the tangent at the equilibrium)")
    p_run.add_argument("--no-progress", action="store_true",
                       help="dynamic scenes: no progress line")
    p_run.add_argument("--plot", help="figure of the solution (.png, .pdf, .svg)")
    p_run.add_argument("--animate", help="animation of a dynamic run (.gif, or .mp4 with ffmpeg)")
    p_run.set_defaults(func=_run)
    p_val = sub.add_parser("validate", help="check a scene file without solving it",
                           parents=[_cache_flags()])   # accepted everywhere; no solve here
    p_val.add_argument("scene", help="scene file (.toml or .json)")
    p_val.set_defaults(func=_validate)
    p_pr = sub.add_parser("princeton", help="replay the 25 Princeton load cases (table + figures)",
                          parents=[_cache_flags()])
    p_pr.add_argument("--elements", type=int, default=16,
                      help="finite elements along the beam (default 16)")
    p_pr.add_argument("--no-gravity", action="store_true", help="leave the beam's weight out")
    p_pr.add_argument("--relative", action="store_true",
                      help="deflections relative to the self-weight state")
    p_pr.add_argument("--stations", default="0.25,0.5,0.75,1",
                      help="stations r/L, comma separated (default 0.25,0.5,0.75,1)")
    p_pr.add_argument("--measurements", help="measured deflections CSV (simsoft_jax.apps.princeton)")
    p_pr.add_argument("--no-published", action="store_true",
                      help="skip the comparison with the shipped ANSYS solid-element "
                           "predictions (made when no --measurements are given)")
    p_pr.add_argument("--out", default="out/princeton", help="output folder")
    p_pr.set_defaults(func=_princeton)
    _add_calibration_commands(sub)
    sub.add_parser("bench", add_help=False,     # listed in --help; dispatched below
                   help="run the benchmarks (benchmarks/run_all.py; bench --help for options)")
    argv = sys.argv[1:] if argv is None else list(argv)
    if argv[:1] == ["bench"]:          # its options belong to benchmarks/run_all.py
        return _bench(argv[1:])
    args = parser.parse_args(argv)
    if args.func is not _validate or getattr(args, "no_cache", False):
        _configure_cache(args)   # plain validate reads the scene only: no JAX import
    return args.func(args)


def console() -> None:
    """The ``simsoft-jax`` command: :func:`main`, and on Ctrl-C (exit status 130) leave at
    once (``os._exit`` after flushing the output): a solve or a compile still running
    inside XLA would otherwise hold the interpreter's exit until it ends, or crash its
    teardown."""
    import os
    from .pipeline.interrupts import install
    install()    # a Ctrl-C that lands in a garbage-collector callback is not lost
    try:
        code = main()
    except KeyboardInterrupt:     # outside a command's own handling (an import, a figure)
        print("\ninterrupted", file=sys.stderr)
        code = 130
    if code == 130:
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(130)
    sys.exit(code)


if __name__ == "__main__":
    console()
