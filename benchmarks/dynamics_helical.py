"""The seed's helical-motion scenes (synthetic rod, spring-steel rod, silicone body):
compile time, Newton iterations per step and wall time per simulated second after
compilation, at 10 and 40 elements, dt = 0.01 s, t_end = 3 s.

    python benchmarks/dynamics_helical.py

Prints a table; wall times are medians of 3 runs after warm-up. Not a test.
"""
import platform
import time
from pathlib import Path

import jax
import numpy as np

import simsoft_jax as sj

SCENES = Path(__file__).resolve().parents[1] / "examples" / "scenes"
NAMES = ("helical_synthetic.json", "helical_spring_steel.json", "helical_silicone.json")


def measure(path, elements, repeats=3):
    d = sj.load_scene(path).to_dict()
    d["rods"][0]["elements"] = elements
    scene = sj.Scene.from_dict(d)
    model = sj.build_model(scene)
    dyn = sj.build_dynamics(model, scene)
    solver = scene.solver
    steps = int(round(solver.t_end / solver.dt))
    settings = sj.DynamicSettings(dt=solver.dt, steps=steps, rho_inf=solver.rho_inf,
                                  save_every=1, max_iterations=solver.max_iterations)
    damped = bool(np.any(np.asarray(model.viscosity) != 0))
    state = sj.dynamics.initial_state(model, dyn, damped=damped)
    start = time.perf_counter()
    compiled = sj.dynamics._simulate.lower(model, dyn, settings, state, damped=damped).compile()
    compile_s = time.perf_counter() - start
    traj = jax.block_until_ready(compiled(model, dyn, state))
    walls = []
    for _ in range(repeats):
        start = time.perf_counter()
        traj = jax.block_until_ready(compiled(model, dyn, state))
        walls.append(time.perf_counter() - start)
    return traj, compile_s, float(np.median(walls)) / solver.t_end


def main():
    print(f"machine: {platform.machine()}, jax {jax.__version__}")
    print(f"{'scene':>28} {'elem':>5} {'conv':>5} {'its/step':>9} {'max its':>8} "
          f"{'substeps':>9} {'compile s':>10} {'wall s per sim s':>17}")
    for name in NAMES:
        for elements in (10, 40):
            traj, compile_s, wall = measure(SCENES / name, elements)
            its = np.asarray(traj.iterations)
            print(f"{name:>28} {elements:>5} {str(bool(traj.converged)):>5} {its.mean():>9.2f} "
                  f"{its.max():>8d} {int(np.asarray(traj.substeps).max()):>9d} "
                  f"{compile_s:>10.2f} {wall:>17.4f}")


if __name__ == "__main__":
    main()
