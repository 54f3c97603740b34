"""Command line: ``simsoft-jax run SCENE -o OUT.json|.npz`` and ``simsoft-jax validate SCENE``."""
from __future__ import annotations

import argparse
import sys


def _run(args) -> int:
    from .results import run
    def progress(t, t_end):
        print(f"\r  t = {t:.4g} / {t_end:.4g} s", end="", file=sys.stderr, flush=True)

    try:
        result = run(args.scene, progress=progress)
    except (ValueError, NotImplementedError) as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    if result.time is not None:
        print(file=sys.stderr)  # end the progress line
    if args.output:
        result.save(args.output)
    if result.converged:
        status = "converged"
    elif result.time is not None:
        status = f"NOT converged (step failed at t = {result.failed_at:.6g} s)"
    else:
        status = f"NOT converged (load level {result.load_level:.4g})"
    detail = (f"{len(result.time)} saved states" if result.time is not None
              else f"residual {result.residual_norm:.3g}")
    print(f"{result.name or args.scene}: {status}; {result.newton_iterations} Newton iterations, "
          f"{detail}, solve {result.wall_time_s:.3f} s, "
          f"compile {result.compile_time_s:.2f} s"
          + (f"; wrote {args.output}" if args.output else ""))
    return 0 if result.converged else 1


def _validate(args) -> int:
    from .scene import load_scene
    try:
        scene = load_scene(args.scene)
    except ValueError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    rods = ", ".join(f"{r.name} ({r.elements} elements)" for r in scene.rods)
    print(f"{args.scene}: valid {scene.solver.kind} scene; rods: {rods}")
    return 0


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="simsoft-jax", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)
    p_run = sub.add_parser("run", help="solve a scene file and optionally write the result")
    p_run.add_argument("scene", help="scene file (.toml or .json)")
    p_run.add_argument("-o", "--output", help="result file (.json or .npz)")
    p_run.set_defaults(func=_run)
    p_val = sub.add_parser("validate", help="check a scene file without solving it")
    p_val.add_argument("scene")
    p_val.set_defaults(func=_validate)
    args = parser.parse_args(argv)
    return args.func(args)


if __name__ == "__main__":
    sys.exit(main())
