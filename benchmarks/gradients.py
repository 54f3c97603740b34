"""Cost of a gradient relative to the forward run: d(tip z)/d(stiffness) through a static
solve (Princeton beam) and through a 300-step rollout (synthetic helical scene, 10
elements, dt = 0.01 s), by the implicit function theorem.

    PYTHONPATH=. python benchmarks/gradients.py [--quick] [--out DIR]

The rollout gradient runs ``simulate(..., differentiable=True)`` (one Newton solve per
step, checkpointed scan); it is compared with the default forward rollout and with the
differentiable forward rollout. Medians after warm-up. Not a test.
"""
from __future__ import annotations

import sys
from pathlib import Path

import jax

sys.path.insert(0, str(Path(__file__).resolve().parent))
import common  # noqa: E402

import simsoft_jax as sj  # noqa: E402


def run(quick=False, out=Path("out/bench")):
    """Gradient cost relative to the forward run (static solve, 300-step rollout)."""
    repeats = 3 if quick else 5
    model, settings = common.static_setup(common.scene_with("princeton_theta30.toml"))

    def static_tip(K):
        return sj.solve_static(model.replace(stiffness=K), settings).p[-1, 2]
    fwd, _ = common.median_time(jax.jit(static_tip), model.stiffness, repeats=repeats)
    grad, _ = common.median_time(jax.jit(jax.grad(static_tip)), model.stiffness,
                                 repeats=repeats)
    rows = [dict(case="static solve (Princeton)", forward_ms=fwd * 1e3,
                 gradient_ms=grad * 1e3, ratio=grad / fwd)]
    dmodel, dsettings = common.dynamic_setup(common.scene_with("helical_synthetic.json"),
                                             steps=300)

    def rollout_tip(K, differentiable):
        return sj.simulate(dmodel.replace(stiffness=K), dsettings,
                           differentiable=differentiable).p[-1, -1, 2]
    fwd, _ = common.median_time(jax.jit(lambda K: rollout_tip(K, False)), dmodel.stiffness,
                                repeats=repeats)
    fwd_d, _ = common.median_time(jax.jit(lambda K: rollout_tip(K, True)), dmodel.stiffness,
                                  repeats=repeats)
    grad, _ = common.median_time(jax.jit(jax.grad(lambda K: rollout_tip(K, True))),
                                 dmodel.stiffness, repeats=repeats)
    rows.append(dict(case="300-step rollout (synthetic)", forward_ms=fwd * 1e3,
                     forward_differentiable_ms=fwd_d * 1e3, gradient_ms=grad * 1e3,
                     ratio=grad / fwd, ratio_differentiable=grad / fwd_d))
    common.table(rows, [("case", "case", "s"), ("forward_ms", "forward ms", ".1f"),
                        ("forward_differentiable_ms", "fwd (diff.) ms", ".1f"),
                        ("gradient_ms", "gradient ms", ".1f"), ("ratio", "grad/fwd", ".2f"),
                        ("ratio_differentiable", "grad/fwd(diff.)", ".2f")],
                 title="gradient cost (d tip z / d stiffness)")
    common.save_json(out, "gradients", rows)
    return rows


main = common.standalone(run)

if __name__ == "__main__":
    raise SystemExit(main())
