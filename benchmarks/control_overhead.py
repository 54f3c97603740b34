"""Cost of closed-loop control in a rollout: ``simulate(..., control=policy)`` against the
same open-loop rollout.

    PYTHONPATH=. python benchmarks/control_overhead.py [--quick] [--out DIR]

Scene: a clamped tendon-driven arm (L = 0.2 m, 10 elements, one straight tendon at 5 mm,
mass damping), 300 steps of dt = 0.01 s. Cases, each in the plain and the differentiable
rollout:

* open loop: the tendon pulled with a constant tension of 0.02 N from t = 0;
* hold: a policy that sets the same tension at every step (the same motion, so the cost
  of the hook itself: calling the policy, checking its model, selecting it);
* P on tip height: a policy ``T = 0.02 N + kp (z* - z_tip)`` (different motion: more
  Newton iterations and matrix rebuilds, so also compared per Newton iteration).

The cases run in interleaved rounds after warm-up (compilation excluded); the table
gives, for each, the fastest round's wall time (the least disturbed by other work on a
shared machine), the median wall time, and the median CPU time of this process (all its
threads; other processes' load changes it far less than the wall time). Not a test;
nothing here asserts on time.
"""
from __future__ import annotations

import sys
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import common  # noqa: E402

import simsoft_jax as sj  # noqa: E402
from simsoft_jax.studies import control  # noqa: E402

TENSION, TARGET, GAIN = 0.02, 0.01, 2.0    # N, m, N/m
SCENE = {
    "solver": {"kind": "dynamic", "t_end": 3.0, "dt": 0.01},
    "rods": [{"name": "arm", "elements": 10, "geometry": {"kind": "straight", "length": 0.2},
              "material": {"E": 1e6, "nu": 0.5, "density": 1000.0, "mass_damping": 10.0},
              "stiffness": {"EA": 50.0, "GAy": 20.0, "GAz": 20.0, "GJ": 1.5e-4,
                            "EIy": 2e-4, "EIz": 2e-4},
              "inertia": {"rhoA": 0.03, "rhoJ": 1e-4, "rhoIy": 1e-4, "rhoIz": 1e-4}}],
    "constraints": [{"kind": "clamp", "rod": "arm", "node": 0}],
    "tendons": [{"name": "t", "rod": "arm", "from_node": 0, "to_node": -1,
                 "offset": [0.0, 0.005], "tension": TENSION}]}


def hold(t, state, model, tension):
    """The same tension at every step."""
    return model.replace(tendon_tension=model.tendon_tension.at[0].set(tension))


def proportional(t, state, model, gain):
    """``T = 0.1 N + gain (z* - z_tip)`` from the tip height at the step's start."""
    z = control.tip_pose(model, state, "arm")[1][2]
    return model.replace(
        tendon_tension=model.tendon_tension.at[0].set(TENSION + gain * (TARGET - z)))


def run(quick=False, out=Path("out/bench")):
    """Closed-loop rollout cost relative to the open-loop one."""
    model, settings = common.dynamic_setup(sj.Scene.from_dict(SCENE),
                                           steps=100 if quick else 300)
    rounds = 4 if quick else 10
    rows = []
    for differentiable in (False, True):
        cases = {
            "open loop": jax.jit(lambda m: sj.simulate(m, settings,
                                                       differentiable=differentiable)),
            "hold (same motion)": jax.jit(lambda m: sj.simulate(
                m, settings, differentiable=differentiable, control=hold,
                control_params=jnp.float64(TENSION))),
            "P on tip height": jax.jit(lambda m: sj.simulate(
                m, settings, differentiable=differentiable, control=proportional,
                control_params=jnp.float64(GAIN))),
        }
        walls, cpus = {name: [] for name in cases}, {name: [] for name in cases}
        results = {name: jax.block_until_ready(fn(model)) for name, fn in cases.items()}
        for _ in range(rounds):
            for name, fn in cases.items():
                cpu = time.process_time()
                walls[name].append(common.timed(fn, model)[0])
                cpus[name].append(time.process_time() - cpu)
        base = None
        for name, traj in results.items():
            wall, median, cpu = (min(walls[name]), float(np.median(walls[name])),
                                 float(np.median(cpus[name])))
            iterations = int(traj.iterations.sum())
            if base is None:
                base = (wall, median, cpu)
            rows.append(dict(case=name, differentiable=str(differentiable), ms=wall * 1e3,
                             ratio=wall / base[0], median_ms=median * 1e3,
                             median_ratio=median / base[1], cpu_ms=cpu * 1e3,
                             cpu_ratio=cpu / base[2], iterations=iterations,
                             cpu_us_per_iteration=cpu / iterations * 1e6,
                             converged=str(bool(traj.converged))))
    common.table(rows, [("case", "case", "s"), ("differentiable", "diff.", "s"),
                        ("ms", "best ms", ".1f"), ("ratio", "x open", ".3f"),
                        ("median_ms", "median ms", ".1f"), ("median_ratio", "x open", ".3f"),
                        ("cpu_ms", "CPU ms", ".1f"), ("cpu_ratio", "x open", ".3f"),
                        ("iterations", "Newton its", "d"),
                        ("cpu_us_per_iteration", "CPU us/it", ".1f"),
                        ("converged", "converged", "s")],
                 title=f"closed-loop control overhead ({settings.steps} steps)")
    common.save_json(out, "control_overhead", rows)
    return rows


main = common.standalone(run)

if __name__ == "__main__":
    raise SystemExit(main())
