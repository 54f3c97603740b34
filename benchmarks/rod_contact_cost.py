"""Cost of rod-rod contact (``[contact] self = true``): two crossing rods, clamped at both
ends, the upper one pushed onto the lower at its middle by a force, solved with and
without rod-rod contact (without it the rods pass through each other: same rods, loads
and solver), per solve and per Newton iteration, statically and dynamically (the force
pressing from rest, ``DYNAMIC_STEPS`` steps of ``DYNAMIC_DT``; the dynamics find the
candidate pairs once per step, the statics at every iterate); and the broad phase alone
on a long unfolded helix, per element, for growing element counts (near O(N)).

    PYTHONPATH=. python benchmarks/rod_contact_cost.py [--quick] [--out DIR]

Wall: median of repeated solves after compilation. Not a test.
"""
from __future__ import annotations

import sys
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
import common  # noqa: E402

import simsoft_jax as sj  # noqa: E402
from simsoft_jax.couplings import rod_pairs  # noqa: E402

L, R_C, F = 0.2, 0.005, 10.0
DYNAMIC_DT, DYNAMIC_STEPS = 2e-3, 50   # s, steps of the dynamic case


def crossing(elements: int, self_contact: bool, dynamic: bool = False) -> dict:
    def rod(name, along_y, z):
        return {"name": name, "elements": elements,
                "geometry": {"kind": "straight", "length": L},
                "base": {"position": [0.0, -L / 2, z] if along_y else [-L / 2, 0.0, z],
                         "rotation": [0.0, 0.0, np.pi / 2 if along_y else 0.0]},
                "stiffness": {"EA": 1e7, "GAy": 1e7, "GAz": 1e7, "GJ": 1.0, "EIy": 1.0,
                              "EIz": 1.0},
                "inertia": {"rhoA": 1.0, "rhoJ": 1e-6, "rhoIy": 1e-6, "rhoIz": 1e-6}}

    solver = ({"kind": "dynamic", "dt": DYNAMIC_DT, "t_end": DYNAMIC_DT * DYNAMIC_STEPS,
               "rho_inf": 0.0} if dynamic else {"kind": "static", "load_steps": 5})
    return {"solver": solver,
            "rods": [rod("top", False, 2 * R_C), rod("bottom", True, 0.0)],
            "constraints": [{"kind": "clamp", "rod": r, "node": n}
                            for r in ("top", "bottom") for n in (0, -1)],
            "loads": [{"kind": "force", "rod": "top", "node": elements // 2,
                       "vector": [0.0, 0.0, -F]}],
            "contact": {"radius": R_C, "self": self_contact}}


def solve_cost(d: dict, repeats: int) -> dict:
    model, settings = common.static_setup(sj.Scene.from_dict(d))
    start = time.perf_counter()
    _, compiled = common.compile_static(model, settings)
    compile_s = time.perf_counter() - start
    wall, eq = common.median_time(compiled, model, settings, repeats=repeats)
    its = int(eq.iterations)
    return dict(converged=bool(eq.converged), compile_s=compile_s, wall_s=wall,
                iterations=its, ms_per_iteration=1e3 * wall / max(its, 1))


def dynamic_cost(d: dict, repeats: int) -> dict:
    cost = common.rollout_cost(sj.Scene.from_dict(d), repeats)
    steps, its = cost.pop("steps"), cost["iterations"]
    return dict(cost, its_per_step=its / steps, ms_per_iteration=1e3 * cost["wall_s"] / max(its, 1))


def broad_phase_cost(elements: int, repeats: int) -> dict:
    """find_pairs on a helix of ``elements`` elements (radius 0.05 m, pitch 0.05 m, no
    contacts)."""
    h = 0.01
    d = {"solver": {"kind": "static"},
         "rods": [{"name": "helix", "elements": elements,
                   "geometry": {"kind": "straight", "length": elements * h},
                   "stiffness": {"EA": 1.0, "GAy": 1.0, "GAz": 1.0, "GJ": 1.0, "EIy": 1.0,
                                 "EIz": 1.0},
                   "inertia": {"rhoA": 1.0, "rhoJ": 1.0, "rhoIy": 1.0, "rhoIz": 1.0}}],
         "constraints": [{"kind": "clamp", "rod": "helix", "node": 0}],
         "contact": {"radius": 0.002, "self": True}}
    model = sj.build_model(sj.Scene.from_dict(d))
    t = np.arange(elements + 1) * h / np.hypot(0.05, 0.05 / (2 * np.pi))
    p = np.stack([0.05 * np.cos(t), 0.05 * np.sin(t), 0.05 / (2 * np.pi) * t], 1)
    find = jax.jit(rod_pairs.find_pairs)
    wall, pairs = common.median_time(find, model, model.R0, jnp.asarray(p), repeats=repeats)
    return dict(elements=elements, wall_ms=1e3 * wall, us_per_element=1e6 * wall / elements,
                pairs=int(np.sum(pairs.active)))


def run(out: Path, quick: bool = False) -> dict:
    """Rod-rod contact: solve cost with and without it, broad-phase cost per element."""
    repeats = 2 if quick else 5
    info = common.machine()
    rows = []
    for elements in ((8,) if quick else (8, 32)):
        for self_contact in (True, False):           # alternately, same load
            rows.append(dict(case="rod-rod" if self_contact else "without", elements=elements,
                             **solve_cost(crossing(elements, self_contact), repeats)))
    columns = [("case", "case", "s"), ("elements", "elements/rod", "d"),
               ("iterations", "its", "d"), ("wall_s", "wall s", ".3f"),
               ("ms_per_iteration", "ms/it", ".2f"), ("compile_s", "compile s", ".1f")]
    common.table(rows, columns, title="two crossing rods pressed together (statics)")
    dynamic = []
    for elements in ((8,) if quick else (8, 32)):
        for self_contact in (True, False):
            dynamic.append(dict(case="rod-rod" if self_contact else "without",
                                elements=elements, **dynamic_cost(
                                    crossing(elements, self_contact, dynamic=True), repeats)))
    common.table(dynamic, columns[:3] + [("its_per_step", "its/step", ".2f")] + columns[3:],
                 title=f"the same, dynamics ({DYNAMIC_STEPS} steps of {DYNAMIC_DT} s)")
    counts = (100, 400) if quick else (100, 400, 1600)
    broad = [broad_phase_cost(n, repeats) for n in counts]
    common.table(broad, [("elements", "elements", "d"), ("wall_ms", "ms", ".2f"),
                         ("us_per_element", "us/element", ".2f"), ("pairs", "pairs", "d")],
                 title="broad phase on an unfolded helix")
    info["load_average_end"] = common.machine()["load_average"]
    result = {"machine": info, "crossing": rows, "crossing_dynamic": dynamic,
              "broad_phase": broad}
    common.save_json(out, "rod_contact_cost", result)
    return result


if __name__ == "__main__":
    sys.exit(common.standalone(run)())
