"""Princeton beam (theta = 30 deg, 2 lbf, gravity): compile time, Newton iterations, wall
time after compilation, and mesh convergence of the tip against a 256-element reference.

    python benchmarks/statics_princeton.py

Prints a table; figures are medians of 5 runs after warm-up. Not a test.
"""
import platform
import time
from pathlib import Path

import jax
import numpy as np

import simsoft_jax as sj

SCENE = Path(__file__).resolve().parents[1] / "examples" / "scenes" / "princeton_theta30.toml"


def scene_with(elements):
    d = sj.load_scene(SCENE).to_dict()
    d["rods"][0]["elements"] = elements
    return sj.Scene.from_dict(d)


def measure(elements, repeats=5):
    scene = scene_with(elements)
    model = sj.build_model(scene)
    settings = sj.statics.settings_from_scene(scene.solver)
    start = time.perf_counter()
    solver = sj.solve_static.lower(model, settings).compile()
    compile_s = time.perf_counter() - start
    eq = jax.block_until_ready(solver(model))
    walls = []
    for _ in range(repeats):
        start = time.perf_counter()
        eq = jax.block_until_ready(solver(model))
        walls.append(time.perf_counter() - start)
    return eq, compile_s, float(np.median(walls))


def main():
    print(f"machine: {platform.processor() or platform.machine()}, jax {jax.__version__}, "
          f"devices {jax.devices()}")
    reference, _, _ = measure(256, repeats=1)
    tip_ref = np.asarray(reference.p[-1])
    print(f"reference tip (256 elements): {tip_ref}")
    print(f"{'elements':>8} {'iters':>6} {'steps':>6} {'compile s':>10} {'wall ms':>8} "
          f"{'tip error m':>12} {'rel. to defl.':>13}")
    deflection = np.linalg.norm(tip_ref - np.array([0.508, 0, 0]))
    for n in (4, 8, 16, 32, 64):
        eq, compile_s, wall = measure(n)
        err = np.linalg.norm(np.asarray(eq.p[-1]) - tip_ref)
        print(f"{n:>8} {int(eq.iterations):>6} {int(eq.load_steps):>6} {compile_s:>10.2f} "
              f"{wall * 1e3:>8.1f} {err:>12.3e} {err / deflection:>13.3e}")


if __name__ == "__main__":
    main()
