"""The seed's helical-motion scenes (synthetic rod, spring-steel rod, silicone body):
real-time factor at dt = 0.01 s with 10/20/40 elements, and work-precision when refining
elements (dt = 0.01 s) and when refining dt (10 elements).

    PYTHONPATH=. python benchmarks/dynamics_helical.py [--quick] [--out DIR]

Error: largest tip-position distance to a reference run over the common save times
(every 0.04 s), divided by the rod length; references: 80 elements (40 with --quick) at
the same dt, and dt = 0.00125 s (0.0025 s with --quick) at the same elements. Wall:
median of repeated 3 s rollouts after compilation. Not a test.
"""
from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import common  # noqa: E402

import simsoft_jax as sj  # noqa: E402

SAVE_DT = 0.04  # s, spacing of the times at which runs are compared


def measure(scene: sj.Scene, repeats=3):
    """Rollout of a dynamic scene: (Trajectory, compile s, median wall s), saving every
    0.04 s (the common comparison times)."""
    model, settings = common.dynamic_setup(scene)
    save_every = max(1, int(round(SAVE_DT / float(settings.dt))))
    settings = settings.replace(save_every=save_every,
                                steps=settings.steps // save_every * save_every)
    state = sj.initial_state(model)
    start = time.perf_counter()
    _, compiled = common.compile_dynamic(model, settings, state)
    compile_s = time.perf_counter() - start
    wall, traj = common.median_time(compiled, model, settings, state, repeats=repeats)
    return traj, compile_s, wall


def tip_error(traj, ref, length):
    return float(np.max(np.linalg.norm(np.asarray(traj.p[:, -1]) - np.asarray(ref.p[:, -1]),
                                       axis=1)) / length)


def _row(name, traj, compile_s, wall, t_end, **extra):
    its = np.asarray(traj.iterations)
    return dict(scene=name.split(".")[0], converged=bool(traj.converged),
                its_per_step=float(its.mean()), compile_s=compile_s, wall_ms=wall * 1e3,
                rtf=t_end / wall, **extra)


def real_time_factor(quick: bool):
    rows = []
    for name in common.HELICAL:
        for n in (10, 20) if quick else (10, 20, 40):
            scene = common.scene_with(name, n, dt=0.01)
            traj, compile_s, wall = measure(scene, repeats=3 if quick else 5)
            rows.append(_row(name, traj, compile_s, wall, scene.solver.t_end, elements=n))
    common.table(rows, [("scene", "scene", "s"), ("elements", "elements", "d"),
                        ("converged", "conv", ""), ("its_per_step", "its/step", ".2f"),
                        ("compile_s", "compile s", ".2f"), ("wall_ms", "wall ms (3 s)", ".1f"),
                        ("rtf", "x real time", ".1f")],
                 title="real-time factor, dt = 0.01 s, t_end = 3 s")
    return rows


def work_precision(quick: bool):
    rows, series = [], []
    for name in common.HELICAL:
        length = float(np.sum(sj.build_model(common.scene_with(name)).length))
        ref_n = 40 if quick else 80
        ref, _, _ = measure(common.scene_with(name, ref_n, dt=0.01), repeats=1)
        by_elements = []
        for n in (5, 10, 20) if quick else (5, 10, 20, 40):
            scene = common.scene_with(name, n, dt=0.01)
            traj, compile_s, wall = measure(scene, repeats=1 if quick else 3)
            by_elements.append(_row(name, traj, compile_s, wall, scene.solver.t_end,
                                    refine="elements", elements=n, dt=0.01,
                                    error=tip_error(traj, ref, length)))
        ref_dt = 0.0025 if quick else 0.00125
        ref, _, _ = measure(common.scene_with(name, 10, dt=ref_dt), repeats=1)
        by_dt = []
        for dt in (0.04, 0.02, 0.01) if quick else (0.04, 0.02, 0.01, 0.005):
            scene = common.scene_with(name, 10, dt=dt)
            traj, compile_s, wall = measure(scene, repeats=1 if quick else 3)
            by_dt.append(_row(name, traj, compile_s, wall, scene.solver.t_end, refine="dt",
                              elements=10, dt=dt, error=tip_error(traj, ref, length)))
        rows += by_elements + by_dt
        label = name.split(".")[0].replace("helical_", "")
        series.append((f"{label}: elements", [r["wall_ms"] for r in by_elements],
                       [r["error"] for r in by_elements]))
        series.append((f"{label}: dt", [r["wall_ms"] for r in by_dt],
                       [r["error"] for r in by_dt]))
    common.table(rows, [("scene", "scene", "s"), ("refine", "refine", "s"),
                        ("elements", "elements", "d"), ("dt", "dt s", ".4f"),
                        ("its_per_step", "its/step", ".2f"), ("wall_ms", "wall ms", ".1f"),
                        ("error", "tip err / L", ".3e")],
                 title="dynamics work-precision (error vs reference over 0-3 s)")
    return rows, series


def run(quick=False, out=Path("out/bench")):
    """Helical scenes: real-time factor and work-precision (elements, dt)."""
    rtf = real_time_factor(quick)
    wp, series = work_precision(quick)
    common.save_json(out, "dynamics_helical", {"real_time_factor": rtf, "work_precision": wp})
    common.plot_lines(out, "dynamics_work_precision", series, "wall time per 3 s run (ms)",
                      "max tip error / rod length", "dynamics: work-precision (elements, dt)")
    return {"real_time_factor": rtf, "work_precision": wp}


main = common.standalone(run)

if __name__ == "__main__":
    raise SystemExit(main())
