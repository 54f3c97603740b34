"""Static work-precision: error against a converged reference versus wall time when
refining elements, for the Princeton beam (theta = 30 deg, 2 lbf, gravity) and a
large-deflection elastica (the same strip as a cantilever, dead tip force along the
flexible axis, P L^2 / EI = 5). Also compile time and Newton iterations.

    PYTHONPATH=. python benchmarks/statics_princeton.py [--quick] [--out DIR]

Error: tip position distance to the reference (finest mesh, 256 elements; 128 with
--quick), divided by the reference tip deflection. Wall: median of repeated solves after
compilation. Not a test.
"""
from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import common  # noqa: E402

import simsoft_jax as sj  # noqa: E402

ELASTICA_LOAD = 5.0  # P L^2 / EI_z


def elastica_scene(elements: int) -> sj.Scene:
    """The strip of cantilever_tip_force.toml with a dead tip force along local y (the
    flexible direction, EI_z) of P = 5 EI_z / L^2: tip rotation ~ 70 degrees."""
    d = common.scene_with("cantilever_tip_force.toml", elements).to_dict()
    model = sj.build_model(sj.Scene.from_dict(d))
    ei_z, length = float(model.stiffness[0, 5]), float(np.sum(model.length))
    d["name"] = "elastica"
    d["loads"][0]["vector"] = [0.0, ELASTICA_LOAD * ei_z / length**2, 0.0]
    return sj.Scene.from_dict(d)


CASES = {
    "princeton": lambda n: common.scene_with("princeton_theta30.toml", n),
    "elastica": elastica_scene,
}


def measure(scene: sj.Scene, repeats=5):
    """(Equilibrium, compile s, median solve s) of one static scene."""
    model, settings = common.static_setup(scene)
    start = time.perf_counter()
    _, solver = common.compile_static(model, settings)
    compile_s = time.perf_counter() - start
    wall, eq = common.median_time(solver, model, settings, repeats=repeats)
    return eq, compile_s, wall


def work_precision(case: str, quick: bool):
    make = CASES[case]
    ref_n = 128 if quick else 256
    ref, _, _ = measure(make(ref_n), repeats=1)
    tip_ref = np.asarray(ref.p[-1])
    p0 = np.asarray(sj.build_model(make(ref_n)).p0[-1])
    deflection = float(np.linalg.norm(tip_ref - p0))
    rows = []
    for n in ((2, 4, 8, 16, 32) if quick else (2, 4, 8, 16, 32, 64)):
        eq, compile_s, wall = measure(make(n), repeats=3 if quick else 5)
        err = float(np.linalg.norm(np.asarray(eq.p[-1]) - tip_ref))
        rows.append(dict(case=case, elements=n, iterations=int(eq.iterations),
                         load_steps=int(eq.load_steps), converged=bool(eq.converged),
                         compile_s=compile_s, wall_ms=wall * 1e3,
                         error=err / deflection))
    return rows, deflection


def run(quick=False, out=Path("out/bench")):
    """Static work-precision (Princeton, elastica) when refining elements."""
    results = {}
    series = []
    for case in CASES:
        rows, deflection = work_precision(case, quick)
        common.table(rows, [("elements", "elements", "d"), ("iterations", "iters", "d"),
                            ("load_steps", "steps", "d"), ("compile_s", "compile s", ".2f"),
                            ("wall_ms", "wall ms", ".2f"), ("error", "rel. tip err", ".3e")],
                     title=f"{case}: tip deflection {deflection:.4g} m")
        results[case] = rows
        series.append((case, [r["wall_ms"] for r in rows], [r["error"] for r in rows]))
    common.save_json(out, "statics_work_precision", results)
    common.plot_lines(out, "statics_work_precision", series, "wall time per solve (ms)",
                      "relative tip error", "statics: work-precision (refining elements)")
    return results


main = common.standalone(run)

if __name__ == "__main__":
    raise SystemExit(main())
