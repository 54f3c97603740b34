"""The two tangent paths side by side: ``tangent="closed_form"`` (closed-form element
tangents where a term has one) against ``"autodiff"`` (``jax.jacfwd`` of every residual
term), on the chain scenes users run: the Princeton beam (static, gravity) and the seed's
three helical scenes (dynamic, 10 elements, dt = 0.01 s, 3 s). Same answers (the largest
tip difference is reported), different cost: compile time and median run time.

    PYTHONPATH=. python benchmarks/tangent_paths.py [--quick] --out out/bench
"""
from __future__ import annotations

import time

import numpy as np

import common
import simsoft_jax as sj

PATHS = ("closed_form", "autodiff")


def static_rows(repeats: int):
    rows, tips = [], {}
    scene = common.scene_with("princeton_theta30.toml")
    for tangent in PATHS:
        model, settings = common.static_setup(scene)
        settings = settings.replace(tangent=tangent)
        start = time.perf_counter()
        _, compiled = common.compile_static(model, settings)
        compile_s = time.perf_counter() - start
        wall, eq = common.median_time(compiled, model, settings, repeats=repeats)
        tips[tangent] = np.asarray(eq.p[-1])
        rows.append(dict(scene="princeton_theta30", tangent=tangent, compile_s=compile_s,
                         wall_ms=1e3 * wall, iterations=int(eq.iterations),
                         converged=bool(eq.converged)))
    return rows, float(np.abs(tips["closed_form"] - tips["autodiff"]).max())


def dynamic_rows(repeats: int, quick: bool):
    rows, differences = [], {}
    for name in common.HELICAL[:1] if quick else common.HELICAL:
        tips = {}
        for tangent in PATHS:
            model, settings = common.dynamic_setup(common.scene_with(name, elements=10))
            settings = settings.replace(tangent=tangent)
            state = sj.initial_state(model)
            start = time.perf_counter()
            _, compiled = common.compile_dynamic(model, settings, state)
            compile_s = time.perf_counter() - start
            wall, traj = common.median_time(compiled, model, settings, state, repeats=repeats)
            tips[tangent] = np.asarray(traj.p[:, -1])
            rows.append(dict(scene=name.split(".")[0], tangent=tangent, compile_s=compile_s,
                             wall_ms=1e3 * wall, iterations=int(np.sum(traj.iterations)),
                             converged=bool(traj.converged)))
        differences[name] = float(np.abs(tips["closed_form"] - tips["autodiff"]).max())
    return rows, differences


def run(quick: bool, out):
    repeats = 3 if quick else 5
    static, static_diff = static_rows(repeats)
    dynamic, dynamic_diff = dynamic_rows(repeats, quick)
    columns = [("scene", "scene", "s"), ("tangent", "tangent", "s"),
               ("compile_s", "compile s", ".2f"), ("wall_ms", "run ms", ".1f"),
               ("iterations", "Newton its", "d"), ("converged", "converged", "")]
    common.table(static + dynamic, columns, "tangent paths (closed_form vs autodiff)")
    print(f"largest tip difference between the paths: static {static_diff:.1e} m; "
          + ", ".join(f"{k.split('.')[0]} {v:.1e} m" for k, v in dynamic_diff.items()))
    data = dict(rows=static + dynamic, static_difference=static_diff,
                dynamic_difference=dynamic_diff)
    common.save_json(out, "tangent_paths", data)
    return data


if __name__ == "__main__":
    raise SystemExit(common.standalone(run)())
