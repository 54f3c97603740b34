"""Cost against element count (10 ... 1000): one static solve, one static Newton iteration,
one dynamic Newton iteration (residual, iteration matrix, factorization, solve) and one
dynamic time step. The work per Newton iteration of a chain should grow linearly: the
table gives the cost per element relative to the 100-element value.

    PYTHONPATH=. python benchmarks/scaling.py [--quick] [--out DIR]

Static: cantilever_tip_force.toml; dynamic: helical_synthetic.json (dt = 0.01 s). Newton
iterations are timed as a compiled loop of K iterations (no dispatch overhead), divided
by K; steps as a 20-step rollout divided by 20. Medians after warm-up. Not a test.
"""
from __future__ import annotations

import sys
from functools import partial
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import common  # noqa: E402

import simsoft_jax as sj  # noqa: E402
from simsoft_jax.physics import assembly  # noqa: E402
from simsoft_jax.solvers import dynamics  # noqa: E402
from simsoft_jax.math import lie, linalg  # noqa: E402
from simsoft_jax.solvers.dynamics import residual  # noqa: E402


@partial(jax.jit, static_argnames="k")
def static_iterations(model, k):
    """k full Newton iterations (residual, tangent, factorization, solve, update)."""
    def body(_, c):
        R, p = c
        r, blocks = assembly.residual_and_tangent(model, R, p, 1.0)
        dx = -linalg.block_solve(blocks, r)
        return jax.vmap(lie.compose_exp)(R, p, dx)
    return jax.lax.fori_loop(0, k, body, (model.R0, model.p0))


@partial(jax.jit, static_argnames="k")
def dynamic_iterations(model, state, k):
    """k full dynamic Newton iterations (residual, iteration matrix, factorization,
    solve) of the first step (dt = 0.01 s, rho_inf = 0.9)."""
    inert = dynamics.element_inertia(model)
    residual_and_matrix = residual.step_functions(model, inert, 0.9, state,
                                                  0.01).residual_and_matrix

    def body(_, w):
        r, blocks = residual_and_matrix(w, jnp.zeros(0))   # no couplings: no multipliers
        return w - linalg.block_solve(blocks, r)
    return jax.lax.fori_loop(0, k, body, jnp.zeros_like(state.v))


def run(quick=False, out=Path("out/bench")):
    """Cost of a static solve, a Newton iteration and a dynamic step against elements."""
    sizes = (10, 100, 1000) if quick else (10, 30, 100, 300, 1000)
    repeats = 3 if quick else 5
    rows = []
    for n in sizes:
        k = max(2, 2000 // n)
        scene = common.scene_with("cantilever_tip_force.toml", n)
        model, settings = common.static_setup(scene)
        _, solve = common.compile_static(model, settings)
        solve_s, eq = common.median_time(solve, model, settings, repeats=repeats)
        it_s, _ = common.median_time(static_iterations, model, k, repeats=repeats)
        dscene = common.scene_with("helical_synthetic.json", n, dt=0.01)
        dmodel, dsettings = common.dynamic_setup(dscene, steps=20)
        state = sj.initial_state(dmodel)
        dit_s, _ = common.median_time(dynamic_iterations, dmodel, state, k, repeats=repeats)
        _, roll = common.compile_dynamic(dmodel, dsettings, state)
        step_s, traj = common.median_time(roll, dmodel, dsettings, state, repeats=repeats)
        rows.append(dict(elements=n, solve_ms=solve_s * 1e3, solve_iterations=int(eq.iterations),
                         static_iteration_us=it_s / k * 1e6,
                         dynamic_iteration_us=dit_s / k * 1e6,
                         step_us=step_s / 20 * 1e6,
                         its_per_step=float(np.mean(np.asarray(traj.iterations)))))
    base = next((r for r in rows if r["elements"] == 100), rows[0])
    for r in rows:
        scale = base["elements"] / r["elements"]
        for key in ("static_iteration_us", "dynamic_iteration_us", "step_us"):
            r[key + "_per_element_rel"] = r[key] * scale / base[key]
    common.table(rows, [("elements", "elements", "d"), ("solve_ms", "solve ms", ".2f"),
                        ("solve_iterations", "solve its", "d"),
                        ("static_iteration_us", "stat it us", ".1f"),
                        ("static_iteration_us_per_element_rel", "per elem rel", ".2f"),
                        ("dynamic_iteration_us", "dyn it us", ".1f"),
                        ("dynamic_iteration_us_per_element_rel", "per elem rel", ".2f"),
                        ("step_us", "step us", ".1f"), ("its_per_step", "its/step", ".2f")],
                 title="cost against elements (per-element cost relative to 100 elements)")
    common.save_json(out, "scaling", rows)
    n = [r["elements"] for r in rows]
    common.plot_lines(out, "scaling", [
        ("static Newton iteration", n, [r["static_iteration_us"] for r in rows]),
        ("dynamic Newton iteration", n, [r["dynamic_iteration_us"] for r in rows]),
        ("dynamic step", n, [r["step_us"] for r in rows]),
        ("static solve", n, [r["solve_ms"] * 1e3 for r in rows])],
        "elements", "time (us)", "cost against element count")
    return rows


main = common.standalone(run)

if __name__ == "__main__":
    raise SystemExit(main())
