"""Run the benchmark suite: print every table, save plots and JSON under ``--out``, and
suggest resolutions for a few target errors from the work-precision data.

    PYTHONPATH=. python benchmarks/run_all.py [--quick] [--only statics,dynamics] [--out DIR]

Benchmarks: statics (work-precision, Princeton and elastica), dynamics (helical scenes:
real-time factor, work-precision in elements and dt), scaling (cost against elements),
compile (compile time per scene kind, what each scene traces), throughput (vmapped
sweeps), gradients (gradient cost against the forward run), tangents (closed-form
against autodiff tangents). ``main(argv)`` returns 0.
Timings are medians after warm-up; the machine and load average are recorded in
``DIR/machine.json``. Nothing here is a test.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import common  # noqa: E402
import compile_times  # noqa: E402
import dynamics_helical  # noqa: E402
import gradients  # noqa: E402
import scaling  # noqa: E402
import statics_princeton  # noqa: E402
import tangent_paths  # noqa: E402
import throughput  # noqa: E402

from simsoft_jax.analysis import advisor  # noqa: E402

BENCHMARKS = {
    "statics": statics_princeton.run,
    "dynamics": dynamics_helical.run,
    "scaling": scaling.run,
    "compile": compile_times.run,
    "throughput": throughput.run,
    "gradients": gradients.run,
    "tangents": tangent_paths.run,
}
TARGETS = (1e-2, 1e-3, 1e-4)


def advise(results: dict) -> list[str]:
    """Suggested resolutions for TARGETS from the work-precision results."""
    lines = []
    for case, rows in results.get("statics", {}).items():
        for target in TARGETS:
            try:
                s = advisor.suggest_elements([r["elements"] for r in rows],
                                             [r["error"] for r in rows], target)
            except ValueError as err:
                lines.append(f"{case}: {err}")
                break
            lines.append(f"{case}: relative tip error <= {target:g}: {s.elements} elements"
                         f"{' (extrapolated)' if s.extrapolated else ''}")
    rows = results.get("dynamics", {}).get("work_precision", [])
    for scene in dict.fromkeys(r["scene"] for r in rows):
        el = [r for r in rows if r["scene"] == scene and r["refine"] == "elements"]
        ts = [r for r in rows if r["scene"] == scene and r["refine"] == "dt"]
        for target in TARGETS:
            try:
                s = advisor.suggest_resolution(
                    [r["elements"] for r in el], [r["error"] for r in el],
                    [r["dt"] for r in ts], [r["error"] for r in ts], target)
            except ValueError as err:
                lines.append(f"{scene}: {err}")
                break
            lines.append(f"{scene}: tip error / L <= {target:g}: {s.elements} elements, "
                         f"dt = {s.dt:.4g} s (predicted {s.predicted_error:.2e}"
                         f"{', extrapolated' if s.extrapolated else ''})")
    return lines


def main(argv=None, prog=None) -> int:
    """Run the selected benchmarks (``argv`` as for the command line, default sys.argv;
    ``prog``: the command's name in the usage line); returns 0. An unknown ``--only`` name
    exits through argparse (status 2)."""
    parser = argparse.ArgumentParser(prog=prog, description=__doc__.split("\n\n")[0])
    parser.add_argument("--only", default="",
                        help=f"comma-separated subset of {','.join(BENCHMARKS)}")
    parser.add_argument("--quick", action="store_true", help="fewer sizes and repeats")
    parser.add_argument("--out", default="out/bench", help="folder for tables, plots, JSON")
    args = parser.parse_args(argv)
    names = [n.strip() for n in args.only.split(",") if n.strip()] or list(BENCHMARKS)
    unknown = [n for n in names if n not in BENCHMARKS]
    if unknown:
        parser.error(f"--only: unknown benchmark(s) {unknown}; choose from {list(BENCHMARKS)}")
    out = Path(args.out)
    info = common.machine()
    print(common.describe(info), flush=True)
    results, seconds = {}, {}
    for name in names:
        print(f"\n== {name} ==", flush=True)
        start = time.perf_counter()
        results[name] = BENCHMARKS[name](quick=args.quick, out=out)
        seconds[name] = time.perf_counter() - start
    suggestions = advise(results)
    if suggestions:
        print("\n== suggested resolutions (simsoft_jax.analysis.advisor) ==")
        print("\n".join(suggestions))
    info["load_average_end"] = common.machine()["load_average"]
    common.save_json(out, "machine", {**info, "quick": args.quick, "seconds": seconds,
                                      "suggestions": suggestions})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
