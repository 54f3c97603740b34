"""Cost of contact: the catheter example (examples/contact_catheter.py, 1 s, 100 steps of
0.01 s) with its two obstacles and without them (same rod, drive and solver), per step and
per Newton iteration; and the work-precision of the lifted heavy rod
(tests/test_contact_statics.py) in elements: at small lift the error of the lifted length
(from the tip lift, beam theory l = (24 EI delta / q)^(1/4) against 2F/q) / rod length; at
large lift (tip turned ~46 deg) the largest node-position error against the shooting
solution of the elastica (test_contact_statics.shooting_lift) / rod length, and the
tip-height error; wall and Newton iterations of the solve.

    PYTHONPATH=. python benchmarks/contact_cost.py [--quick] [--out DIR]

Wall: median of repeated rollouts / solves after compilation. Not a test.
"""
from __future__ import annotations

import sys
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
    cost = common.rollout_cost(sj.Scene.from_dict(d), repeats)
    steps, iterations, wall = cost.pop("steps"), cost.pop("iterations"), cost["wall_s"]
    return dict(cost, ms_per_step=1e3 * wall / steps, iterations_per_step=iterations / steps,
                ms_per_iteration=1e3 * wall / iterations)


def lifted_rod(elements: int, repeats: int, reference):
    """Small- and large-lift errors / L and walls at ``elements`` (module docstring);
    ``reference`` = (l, sol) of :func:`test_contact_statics.shooting_lift`."""
    from test_contact_statics import EI, F_LIFT, L_ROD, LIFT, LIFT_BIG, Q
    out = dict(elements=elements)
    for name, scene in (("small", LIFT), ("large", LIFT_BIG)):
        d = {**scene, "rods": [dict(scene["rods"][0], elements=elements)]}
        model, settings = common.static_setup(sj.Scene.from_dict(d))
        if name == "small":
            _, compiled = common.compile_static(model, settings)    # one structure for both
        wall, eq = common.median_time(compiled, model, settings, repeats=repeats)
        p = np.asarray(eq.p)
        out.update({f"{name}_wall_s": wall, f"{name}_iterations": int(eq.iterations),
                    f"{name}_converged": bool(eq.converged)})
        if name == "small":
            lifted = (24.0 * EI * float(p[-1, 2]) / Q) ** 0.25
            out["small_error"] = abs(lifted - 2.0 * F_LIFT / Q) / L_ROD
            continue
        l, sol = reference
        S = np.linspace(0.0, L_ROD, elements + 1)
        _, _, xe, ze = sol(np.clip(S - (L_ROD - l), 0.0, None))
        up = S > L_ROD - l
        expected = np.stack([np.where(up, l - xe, L_ROD - S), 0.0 * S,
                             np.where(up, ze, 0.0)], axis=1)
        out["large_error"] = float(np.abs(p - expected).max()) / L_ROD
        out["tip_error"] = abs(p[-1, 2] - sol(l)[3]) / L_ROD
    return out


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
    from test_contact_statics import EI, F_BIG, Q_BIG, shooting_lift
    reference = shooting_lift(F_BIG, Q_BIG, EI)
    precision = [lifted_rod(n, repeats, reference) for n in counts]
    common.table(precision, [("elements", "elements", "d"),
                             ("small_error", "small: l error / L", ".2e"),
                             ("small_wall_s", "wall s", ".3f"),
                             ("large_error", "large: node error / L", ".2e"),
                             ("tip_error", "tip z error / L", ".2e"),
                             ("large_iterations", "Newton its", "d"),
                             ("large_wall_s", "wall s", ".3f")],
                 title="lifted heavy rod: small lift vs beam theory, large lift vs elastica")
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
