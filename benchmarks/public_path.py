"""Speed where users meet it (issue 19; issue 16 item 6): ``sj.run`` and the command
line next to the kernel (``sj.solve_static`` / ``sj.simulate`` on a built model), in one
run, for a static scene and the three helical scenes.

    PYTHONPATH=. python benchmarks/public_path.py [--quick] [--out DIR] [--base DIR]

Per scene: the kernel (median after a warm-up; dynamic: ``sj.simulate`` of all the
scene's steps from the start state); ``sj.run`` warm (same process, compiled); the
command line ``simsoft-jax run SCENE -o out.json`` in a fresh process: the "solve" and
"compile" seconds it prints, with and without the progress line (``--no-progress``),
cold (an empty persistent compilation cache) and cached (its second run), and its wall
time including the Python start. ``--base DIR``: a checkout of the code before this
work (e.g. ``git archive 333d7e7``), whose command line is run the same way in the same
run (cold: it has no persistent cache). Ratios against the issue's targets: run warm
<= 1.1 x kernel, command-line solve with progress <= 1.3 x kernel, command-line compile
in a fresh process <= 50 % of before (second run: <= 0.5 s). Not a test.
"""
from __future__ import annotations

import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path


sys.path.insert(0, str(Path(__file__).resolve().parent))
import common  # noqa: E402

import simsoft_jax as sj  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
SCENES = ("princeton_theta30.toml",) + common.HELICAL
_PRINTED = re.compile(r"solve ([0-9.]+) s, compile ([0-9.]+) s")


def kernel(scene: sj.Scene, repeats: int) -> float:
    """Median seconds of the solver on a built model (compiled before timing)."""
    if scene.solver.kind == "static":
        model, settings = common.static_setup(scene)
        return common.median_time(sj.solve_static, model, settings, repeats=repeats)[0]
    model, settings = common.dynamic_setup(scene)
    return common.median_time(sj.simulate, model, settings, repeats=repeats)[0]


def run_warm(scene: sj.Scene, repeats: int) -> float:
    """Median seconds of ``sj.run(scene)`` (wall time of the whole call) after a warm-up."""
    return common.median_time(lambda: sj.run(scene).time, repeats=repeats)[0]


def command_line(scene: Path, root: Path, cache: Path | None, progress: bool) -> dict:
    """One ``simsoft-jax run`` in a fresh process from the checkout ``root``: the solve and
    compile seconds it prints and the process's wall time."""
    env = {**os.environ, "PYTHONPATH": str(root)}
    env.pop("SIMSOFT_JAX_CACHE_DIR", None)
    with tempfile.TemporaryDirectory() as tmp:
        args = [sys.executable, "-m", "simsoft_jax.cli", "run", str(scene), "-o",
                str(Path(tmp) / "out.json")]
        if root == REPO:
            args += (["--cache-dir", str(cache)] if cache else ["--no-cache"])
            args += [] if progress else ["--no-progress"]
        start = time.perf_counter()
        out = subprocess.run(args, capture_output=True, text=True, env=env, cwd=tmp)
        wall = time.perf_counter() - start
    found = _PRINTED.search(out.stdout)
    if out.returncode != 0 or not found:
        raise RuntimeError(f"{' '.join(args)} failed:\n{out.stdout}\n{out.stderr}")
    return {"solve": float(found.group(1)), "compile": float(found.group(2)), "wall": wall}


def run(quick: bool = False, out: Path = Path("out/bench"), base: Path | None = None):
    """The table of the module docstring; returns its rows."""
    repeats = 3 if quick else 5
    rows = []
    for name in SCENES[:2] if quick else SCENES:
        path = common.SCENES / name
        scene = sj.load_scene(path)
        row = {"scene": name, "kind": scene.solver.kind}
        with tempfile.TemporaryDirectory() as cache:
            cold = command_line(path, REPO, Path(cache), progress=True)
            cached = command_line(path, REPO, Path(cache), progress=True)
            quiet = command_line(path, REPO, Path(cache), progress=False)
        before = command_line(path, base, None, progress=True) if base else None
        row["kernel_ms"] = 1e3 * kernel(scene, repeats)
        row["run_warm_ms"] = 1e3 * run_warm(scene, repeats)
        row["cli_solve_ms"] = 1e3 * cached["solve"]
        row["cli_solve_quiet_ms"] = 1e3 * quiet["solve"]
        row["compile_cold_s"], row["compile_cached_s"] = cold["compile"], cached["compile"]
        row["wall_cold_s"], row["wall_cached_s"] = cold["wall"], cached["wall"]
        if before:
            row.update(before_solve_ms=1e3 * before["solve"],
                       before_compile_s=before["compile"], before_wall_s=before["wall"])
        row["run_ratio"] = row["run_warm_ms"] / row["kernel_ms"]
        row["cli_ratio"] = row["cli_solve_ms"] / row["kernel_ms"]
        row["compile_ratio"] = (row["compile_cold_s"] / row["before_compile_s"] if before
                                else None)
        rows.append(row)
        print(f"  {name}: done (load {os.getloadavg()[0]:.1f})", flush=True)
    common.table(rows, [
        ("scene", "scene", "s"), ("kernel_ms", "kernel ms", ".1f"),
        ("run_warm_ms", "run warm ms", ".1f"), ("run_ratio", "/kernel", ".2f"),
        ("cli_solve_ms", "cli solve ms", ".1f"), ("cli_ratio", "/kernel", ".2f"),
        ("cli_solve_quiet_ms", "no progress", ".1f"),
        ("before_solve_ms", "before solve", ".1f")],
        title="solve: kernel, sj.run warm, command line (fresh process, cached compile)")
    common.table(rows, [
        ("scene", "scene", "s"), ("compile_cold_s", "cold s", ".2f"),
        ("compile_cached_s", "cached s", ".3f"), ("before_compile_s", "before s", ".2f"),
        ("compile_ratio", "cold/before", ".2f"), ("wall_cold_s", "wall cold", ".2f"),
        ("wall_cached_s", "wall cached", ".2f"), ("before_wall_s", "wall before", ".2f")],
        title="command line in a fresh process: compile as printed, process wall time")
    common.save_json(out, "public_path", {"machine": common.machine(), "rows": rows})
    return rows


def main(argv=None) -> int:
    import argparse
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="two scenes, fewer repeats")
    parser.add_argument("--out", default="out/bench", help="folder for the JSON")
    parser.add_argument("--base", type=Path, help="checkout of the code before (optional)")
    args = parser.parse_args(argv)
    print(common.describe(common.machine()), flush=True)
    run(quick=args.quick, out=Path(args.out), base=args.base)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
