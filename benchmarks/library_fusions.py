"""XLA's YNNPACK library fusions on the solver programs: each program compiled twice from
one lowering, with the package's compile options (:data:`simsoft_jax.math.xla.CANDIDATE_OPTIONS`:
no library fusions) and with the same options less ``xla_cpu_experimental_ynn_fusion_type``
(XLA's default: some dot products and reductions handed to YNNPACK), then called in
alternation; the fastest process CPU time of the repeats of each, in milliseconds.

    PYTHONPATH=. python benchmarks/library_fusions.py [--quick] [--out DIR]   (by hand)

The cosseratbench pile, the program where the difference is largest, is measured through
the benchmark itself (docs/cosseratbench.md). Not a test.
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
from simsoft_jax.math import xla  # noqa: E402
from simsoft_jax.solvers.dynamics.rollout import rollout_program  # noqa: E402
from simsoft_jax.solvers.statics import static_program  # noqa: E402

OPTION = "xla_cpu_experimental_ynn_fusion_type"


def programs(quick: bool):
    """(name, function, arguments) of the measured programs."""
    out = []
    for elements in (16,) if quick else (16, 64):
        model, settings = common.static_setup(common.scene_with("princeton_theta30.toml",
                                                                elements=elements))
        out.append((f"Princeton static, {elements} elements", static_program.__wrapped__,
                    (model, settings)))
    for name, elements in (("helical_synthetic.json", 10),) if quick else (
            ("helical_synthetic.json", 10), ("helical_spring_steel.json", 20)):
        model, settings = common.dynamic_setup(common.scene_with(name, elements=elements))
        out.append((f"{name.removesuffix('.json')} rollout, {elements} elements",
                    rollout_program.__wrapped__, (model, settings, sj.initial_state(model))))
    model, settings = common.static_setup(common.scene_with("princeton_theta30.toml"))

    def tip(scale):
        return sj.solve_static(model.replace(nodal_dead=model.nodal_dead * scale), settings).p[-1]
    out.append(("Princeton static sweep, 64 loads (vmap)", jax.vmap(tip),
                (jnp.linspace(0.25, 2.0, 64),)))
    return out


def fastest_cpu_ms(calls, repeats: int) -> list[float]:
    """Fastest process CPU time (ms) of each of ``calls``, called in alternation."""
    best = [np.inf] * len(calls)
    for call in calls:
        jax.block_until_ready(call())
    for _ in range(repeats):
        for i, call in enumerate(calls):
            start = time.process_time()
            jax.block_until_ready(call())
            best[i] = min(best[i], 1e3 * (time.process_time() - start))
    return best


def run(quick=False, out=Path("out/bench")):
    """Fastest CPU time of each program without and with library fusions."""
    ours = xla.compiler_options()
    if OPTION not in ours:
        print(f"this jaxlib does not take {OPTION}: nothing to compare")
        return []
    default = {k: v for k, v in ours.items() if k != OPTION}
    rows = []
    for name, fun, args in programs(quick):
        lowered = jax.jit(fun).lower(*args)
        calls = [lambda c=lowered.compile(compiler_options=o): c(*args) for o in (ours, default)]
        without, with_ = fastest_cpu_ms(calls, 5 if quick else 20)
        rows.append(dict(program=name, without_ms=without, with_ms=with_, ratio=without / with_))
    common.table(rows, [("program", "program", ""), ("without_ms", "without, ms", ".3f"),
                        ("with_ms", "with, ms", ".3f"), ("ratio", "without / with", ".2f")],
                 "process CPU, fastest: without YNNPACK fusions (the package's) and with")
    common.save_json(out, "library_fusions", rows)
    return rows


main = common.standalone(run)

if __name__ == "__main__":
    sys.exit(main())
