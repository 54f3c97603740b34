"""Batched throughput: scenes per second of ``jax.vmap``-ped sweeps, static (the Princeton
beam under 1000 tip-load scales, 100 with --quick) and dynamic (the synthetic helical
scene under 32 load scales, 8 with --quick; 10 elements, dt = 0.01 s, 3 s), and of the
warm-started Princeton load-angle map (40 x 25 points, 10 x 10 with --quick).

    PYTHONPATH=. python benchmarks/throughput.py [--quick] [--out DIR]

One compile per sweep (the Model structure is fixed, the load scale is a traced array);
wall time is the median of repeated sweeps after warm-up (one sweep for the 1000-case
static sweep). Not a test.
"""
from __future__ import annotations

import sys
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import common  # noqa: E402

import simsoft_jax as sj  # noqa: E402


def static_sweep(cases: int):
    model, settings = common.static_setup(common.scene_with("princeton_theta30.toml"))

    def one(scale):
        eq = sj.solve_static(model.replace(nodal_dead=model.nodal_dead * scale), settings)
        return eq.p[-1], eq.converged
    sweep = jax.jit(jax.vmap(one))
    scales = jnp.linspace(0.25, 2.0, cases)
    compile_s, (tips, ok) = common.timed(sweep, scales)
    wall, _ = common.median_time(sweep, scales, repeats=1 if cases >= 1000 else 3, warmup=0)
    single, _ = common.median_time(lambda s: one(s), jnp.asarray(1.0), repeats=3)
    return dict(sweep="princeton static", cases=cases, converged=int(np.sum(ok)),
                first_call_s=compile_s, wall_s=wall, scenes_per_s=cases / wall,
                single_scene_s=single)


def warm_map(angles: int, loads: int):
    """The Princeton load-angle x load map (16 elements, gravity) walked as a continuation
    (``sweeps.static_sweep(warm_start=True)`` via ``princeton.load_angle_sweep``)."""
    from simsoft_jax.apps import princeton

    theta = np.linspace(0.0, 90.0, angles)
    load = np.linspace(0.5, 4.0, loads) * princeton.F0
    sweep = lambda: princeton.load_angle_sweep(theta, load)  # noqa: E731
    compile_s, (_, ok) = common.timed(sweep)
    wall, _ = common.median_time(sweep, repeats=3, warmup=0)
    cases = angles * loads
    return dict(sweep="princeton map, warm start", cases=cases, converged=int(np.sum(ok)),
                first_call_s=compile_s, wall_s=wall, scenes_per_s=cases / wall,
                single_scene_s=float("nan"))


def dynamic_sweep(cases: int):
    model, settings = common.dynamic_setup(common.scene_with("helical_synthetic.json"))

    def one(scale):
        channels = model.channels.replace(nodal_dead=model.channels.nodal_dead * scale)
        traj = sj.simulate(model.replace(nodal_dead=model.nodal_dead * scale,
                                         channels=channels), settings)
        return traj.p[-1, -1], traj.converged
    sweep = jax.jit(jax.vmap(one))
    scales = jnp.linspace(0.5, 1.0, cases)
    compile_s, (_, ok) = common.timed(sweep, scales)
    wall, _ = common.median_time(sweep, scales, repeats=3, warmup=0)
    single, _ = common.median_time(jax.jit(one), jnp.asarray(1.0), repeats=3)
    return dict(sweep="helical synthetic 3 s", cases=cases, converged=int(np.sum(ok)),
                first_call_s=compile_s, wall_s=wall, scenes_per_s=cases / wall,
                single_scene_s=single)


def run(quick=False, out=Path("out/bench")):
    """Scenes per second of vmapped static and dynamic sweeps."""
    rows = [static_sweep(100 if quick else 1000),
            warm_map(*((10, 10) if quick else (40, 25))),
            dynamic_sweep(8 if quick else 32)]
    common.table(rows, [("sweep", "sweep", "s"), ("cases", "cases", "d"),
                        ("converged", "converged", "d"), ("first_call_s", "1st call s", ".2f"),
                        ("wall_s", "wall s", ".3f"), ("scenes_per_s", "scenes/s", ".1f"),
                        ("single_scene_s", "1 scene s", ".4f")],
                 title="vmapped sweeps (one compile; first call includes it)")
    common.save_json(out, "throughput", rows)
    return rows


main = common.standalone(run)

if __name__ == "__main__":
    raise SystemExit(main())
