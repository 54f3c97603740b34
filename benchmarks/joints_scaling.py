"""Cost of mechanisms against element count: a planar parallel robot (two rods clamped
at the floor and welded to a rigid plate, a side force on the plate's left rod) as a
static solve and as dynamic steps, with 8 ... 512 elements per rod, next to the same
two rods without the plate (clamped, free ends). The joints add a fixed-size dense
coupling set (the plate's 6 DOF, 12 multipliers and, per rod, its joint node) to the
block-tridiagonal chains (:mod:`simsoft_jax.couplings.mechanisms`), so the work per Newton
iteration should stay linear in the elements: the table gives the cost per element
relative to the smallest size, and the ratio to the rods alone.

    PYTHONPATH=. python benchmarks/joints_scaling.py [--quick] [--out DIR]

Medians after warm-up; dynamic: 20 steps at dt = 5 ms divided by 20. Not a test.
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import common  # noqa: E402

import simsoft_jax as sj  # noqa: E402


def robot(elements: int, kind: str, plate: bool = True) -> sj.Scene:
    """The parallel robot (or its two rods alone) with ``elements`` per rod."""
    up = {"axis": [0, 1, 0], "angle_deg": -90.0}

    def rod(name, x):
        return {"name": name, "material": {"name": "m_" + name, "E": 5e6, "nu": 0.5,
                                            "density": 1100.0},
                "section": {"shape": "circle", "diameter": 0.02}, "elements": elements,
                "geometry": {"kind": "straight", "length": 0.4},
                "base": {"position": [x, 0.0, 0.0], "rotation": up}}

    solver = ({"kind": "static"} if kind == "static"
              else {"kind": "dynamic", "dt": 0.005, "t_end": 0.1})
    scene = {"solver": solver, "rods": [rod("l", 0.0), rod("r", 0.2)],
             "constraints": [{"kind": "clamp", "rod": "l", "node": 0},
                             {"kind": "clamp", "rod": "r", "node": 0}],
             "loads": [{"kind": "force", "rod": "l", "node": -1, "vector": [0.3, 0.1, 0.0],
                        "frame": "world"}]}
    if plate:
        scene["bodies"] = [{"name": "plate", "mass": 0.05, "position": [0.1, 0.0, 0.4],
                            "inertia": np.diag([1e-4, 2e-4, 2e-4]).tolist()}]
        scene["joints"] = [{"kind": "weld", "a": {"rod": side, "node": -1},
                            "b": {"body": "plate", "offset": [x, 0.0, 0.0]}}
                           for side, x in (("l", -0.1), ("r", 0.1))]
    return sj.Scene.from_dict(scene)


def run(quick=False, out=Path("out/bench")):
    """Static solve and dynamic step of the parallel robot against elements per rod."""
    sizes = (8, 64, 512) if quick else (8, 32, 128, 512)
    repeats = 3 if quick else 5
    rows = []
    for n in sizes:
        row = dict(elements=n)
        for plate in (True, False):
            tag = "robot" if plate else "rods"
            model, settings = common.static_setup(robot(n, "static", plate))
            _, solve = common.compile_static(model, settings)
            seconds, eq = common.median_time(solve, model, settings, repeats=repeats)
            row[f"{tag}_solve_ms"] = seconds * 1e3
            row[f"{tag}_iterations"] = int(eq.iterations)
            row[f"{tag}_iteration_ms"] = seconds * 1e3 / max(int(eq.iterations), 1)
            dmodel, dsettings = common.dynamic_setup(robot(n, "dynamic", plate), steps=20)
            state = sj.initial_state(dmodel)
            _, roll = common.compile_dynamic(dmodel, dsettings, state)
            seconds, traj = common.median_time(roll, dmodel, dsettings, state, repeats=repeats)
            assert bool(traj.converged) and bool(eq.converged)
            row[f"{tag}_step_ms"] = seconds * 1e3 / 20
        rows.append(row)
    base = rows[0]
    for r in rows:
        scale = base["elements"] / r["elements"]
        for key in ("robot_iteration_ms", "robot_step_ms"):
            r[key + "_per_element_rel"] = r[key] * scale / base[key]
        r["step_ratio_to_rods"] = r["robot_step_ms"] / r["rods_step_ms"]
        r["iteration_ratio_to_rods"] = r["robot_iteration_ms"] / r["rods_iteration_ms"]
    common.table(rows, [
        ("elements", "elements/rod", "d"), ("robot_solve_ms", "solve ms", ".2f"),
        ("robot_iterations", "its", "d"), ("robot_iteration_ms", "ms/it", ".3f"),
        ("robot_iteration_ms_per_element_rel", "per elem rel", ".2f"),
        ("iteration_ratio_to_rods", "x rods", ".2f"), ("robot_step_ms", "step ms", ".3f"),
        ("robot_step_ms_per_element_rel", "per elem rel", ".2f"),
        ("step_ratio_to_rods", "x rods", ".2f")],
        title="parallel robot: cost against elements per rod (per-element cost relative "
              "to the smallest; ratio to the two rods without the plate)")
    common.save_json(out, "joints_scaling", rows)
    n = [r["elements"] for r in rows]
    common.plot_lines(out, "joints_scaling", [
        ("static Newton iteration (robot)", n, [r["robot_iteration_ms"] for r in rows]),
        ("static Newton iteration (rods)", n, [r["rods_iteration_ms"] for r in rows]),
        ("dynamic step (robot)", n, [r["robot_step_ms"] for r in rows]),
        ("dynamic step (rods)", n, [r["rods_step_ms"] for r in rows])],
        "elements per rod", "time (ms)", "mechanism cost against element count")
    return rows


main = common.standalone(run)

if __name__ == "__main__":
    raise SystemExit(main())
