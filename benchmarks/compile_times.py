"""Compile time of ``simsoft_jax.run`` per scene kind, and "model only what a scene needs":
the compiled program of a scene without gravity (static) or without damping (dynamic)
has fewer operations and runs faster than the same scene with the term traced (at zero
value, so the physics and the iterations are the same).

    PYTHONPATH=. python benchmarks/compile_times.py [--quick] [--out DIR]

Compile time: ``Result.compile_time_s`` of ``run`` (trace + XLA compile of the solver
for the scene's structure) in a fresh Python process per scene. HLO operations: lines of
the lowered StableHLO program with an assignment (deterministic, unlike timings on a
shared machine). Not a test.
"""
from __future__ import annotations

import dataclasses
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import common  # noqa: E402

import simsoft_jax as sj  # noqa: E402

RUN_SCENES = ("princeton_theta30.toml", "cantilever_tip_force.toml", "helical_synthetic.json",
              "helical_silicone.json")


_RUN_ONE = ("import json, sys, time; t = time.perf_counter(); import simsoft_jax as sj; "
            "i = time.perf_counter() - t; r = sj.run(sys.argv[1]); "
            "print(json.dumps([i, r.kind, r.compile_time_s, r.wall_time_s, r.converged]))")


def compile_of_run(quick: bool):
    """Each scene in a fresh process (a cold start, as a user sees it; JAX would reuse an
    identical program compiled earlier in the same process)."""
    rows = []
    for name in RUN_SCENES[:3] if quick else RUN_SCENES:
        out = subprocess.run([sys.executable, "-c", _RUN_ONE, str(common.SCENES / name)],
                             capture_output=True, text=True, check=True, env=os.environ)
        import_s, kind, compile_s, wall_s, converged = json.loads(out.stdout.splitlines()[-1])
        rows.append(dict(scene=name, kind=kind, import_s=import_s, compile_s=compile_s,
                         wall_s=wall_s, converged=converged))
    common.table(rows, [("scene", "scene", "s"), ("kind", "kind", "s"),
                        ("import_s", "import s", ".2f"), ("compile_s", "compile s", ".2f"),
                        ("wall_s", "wall s", ".4f")],
                 title="compile time of run (trace + compile in a fresh process)")
    return rows


def _princeton(gravity):
    """The Princeton scene with its gravity, with a zero gravity vector (traced, same
    equilibrium as without) or without gravity (not traced)."""
    d = common.scene_with("princeton_theta30.toml").to_dict()
    if gravity is None:
        d.pop("gravity", None)
    else:
        d["gravity"] = {"vector": list(gravity)}
    return sj.Scene.from_dict(d)


def needs(quick: bool):
    """HLO size and run time of a scene with and without an optional term traced. The
    pairs "zero gravity traced / not traced" and "zero viscosity traced (a zero
    ``Model.viscosity`` array) / not traced (None)" have the same physics, so they
    isolate the cost of tracing the term."""
    rows = []
    repeats = 3 if quick else 5
    for label, gravity in (("gravity -9.81", (0.0, 0.0, -9.81)), ("gravity 0", (0.0, 0.0, 0.0)),
                           ("no gravity", None)):
        model, settings = common.static_setup(_princeton(gravity))
        lowered, solve = common.compile_static(model, settings)
        wall, eq = common.median_time(solve, model, settings, repeats=repeats)
        rows.append(dict(case="princeton static", variant=label,
                         traced=model.gravity is not None,
                         hlo_ops=common.count_hlo_ops(lowered), wall_ms=wall * 1e3,
                         iterations=int(eq.iterations),
                         per_iteration_us=wall / int(eq.iterations) * 1e6))
    # helical_synthetic has no viscosity (Model.viscosity None); a zero viscosity array
    # traces zero viscous terms (set with dataclasses.replace: Model.replace refuses a
    # part the scene lacks)
    plain, settings = common.dynamic_setup(common.scene_with("helical_synthetic.json"))
    for damped in (True, False):
        model = dataclasses.replace(plain, viscosity=np.zeros((plain.structure.n_elements, 6))
                                    if damped else None)
        state = sj.initial_state(model)
        lowered, roll = common.compile_dynamic(model, settings, state)
        wall, traj = common.median_time(roll, model, settings, state, repeats=repeats)
        its = int(np.sum(np.asarray(traj.iterations)))
        rows.append(dict(case="synthetic dynamic", variant="zero viscosity" if damped else
                         "no viscosity", traced=damped, hlo_ops=common.count_hlo_ops(lowered),
                         wall_ms=wall * 1e3, iterations=its, per_iteration_us=wall / its * 1e6))
    common.table(rows, [("case", "case", "s"), ("variant", "variant", "s"),
                        ("traced", "traced", ""), ("hlo_ops", "HLO ops", "d"),
                        ("wall_ms", "wall ms", ".2f"), ("iterations", "iterations", "d"),
                        ("per_iteration_us", "us/iteration", ".1f")],
                 title="model only what a scene needs (terms not in the scene are not traced)")
    return rows


def run(quick=False, out=Path("out/bench")):
    """Compile time of run per scene kind; HLO size with and without optional terms."""
    data = {"run": compile_of_run(quick), "needs": needs(quick)}
    common.save_json(out, "compile_times", data)
    return data


main = common.standalone(run)

if __name__ == "__main__":
    raise SystemExit(main())
