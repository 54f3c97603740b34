"""Cost of contact: the catheter example (examples/contact_catheter.py, 1 s, 100 steps of
0.01 s) with its two obstacles and without them (same rod, drive and solver), per step and
per Newton iteration; and the work-precision of the lifted heavy rod
(tests/test_contact_statics.py) in elements: the error of the lifted length (from the tip
lift, beam theory l = (24 EI delta / q)^(1/4) against 2F/q) / rod length.

    PYTHONPATH=. python benchmarks/contact_cost.py [--quick] [--out DIR]

Wall: median of repeated rollouts / solves after compilation. Not a test.
"""
from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent / "examples"))
sys.path.insert(0, str(HERE.parent / "tests"))
import common  # noqa: E402
from contact_catheter import scene as catheter_scene  # noqa: E402

import simsoft_jax as sj  # noqa: E402


def rollout_cost(d: dict, repeats: int):
    model, settings = common.dynamic_setup(sj.Scene.from_dict(d))
    state = sj.initial_state(model)
    start = time.perf_counter()
    _, compiled = common.compile_dynamic(model, settings, state)
    compile_s = time.perf_counter() - start
    wall, traj = common.median_time(compiled, model, settings, state, repeats=repeats)
    steps, iterations = int(settings.steps), int(np.sum(traj.iterations))
    return dict(converged=bool(traj.converged), compile_s=compile_s, wall_s=wall,
                ms_per_step=1e3 * wall / steps, iterations_per_step=iterations / steps,
                ms_per_iteration=1e3 * wall / iterations)


def lifted_rod(elements: int, repeats: int):
    from test_contact_statics import EI, F_LIFT, L_ROD, LIFT, Q
    d = {**LIFT, "rods": [dict(LIFT["rods"][0], elements=elements)]}
    model, settings = common.static_setup(sj.Scene.from_dict(d))
    _, compiled = common.compile_static(model, settings)
    wall, eq = common.median_time(compiled, model, settings, repeats=repeats)
    lifted = (24.0 * EI * float(eq.p[-1, 2]) / Q) ** 0.25
    return dict(elements=elements, wall_s=wall, converged=bool(eq.converged),
                error=abs(lifted - 2.0 * F_LIFT / Q) / L_ROD)


def run(out: Path, quick: bool = False) -> dict:
    repeats = 2 if quick else 3
    info = common.machine()
    print(common.describe(info))
    elements = 10 if quick else 20
    with_contact = catheter_scene(elements)
    without = {k: v for k, v in with_contact.items() if k not in ("obstacles", "contact")}
    rows = [dict(case=name, elements=elements, **rollout_cost(d, repeats))
            for name, d in (("with contact", with_contact), ("without", without))]
    common.table(rows, [("case", "case", "s"), ("elements", "elements", "d"),
                        ("ms_per_step", "ms/step", ".2f"),
                        ("iterations_per_step", "its/step", ".2f"),
                        ("ms_per_iteration", "ms/it", ".3f"), ("compile_s", "compile s", ".1f")],
                 title="catheter, 1 s at dt = 0.01 s")
    counts = (10, 20, 40) if quick else (10, 20, 40, 80)
    precision = [lifted_rod(n, repeats) for n in counts]
    common.table(precision, [("elements", "elements", "d"), ("error", "error / L", ".2e"),
                             ("wall_s", "wall s", ".3f")],
                 title="lifted heavy rod: lifted-length error")
    info["load_average_end"] = common.machine()["load_average"]
    result = {"machine": info, "catheter": rows, "lifted_rod": precision}
    common.save_json(out, "contact_cost", result)
    return result


if __name__ == "__main__":
    import argparse
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--out", default="out/bench")
    args = parser.parse_args()
    run(Path(args.out), args.quick)
