"""Time to first answer: the README's "Using it" snippet, call by call, in a fresh process,
with an empty compilation cache (cold) and again in a new process with the cache it left
(warm). CPU seconds per call (all threads: XLA compiles on several), and each as a ratio
to a compile yardstick measured in the same process (the CPU seconds to compile a fixed
JAX program: a 300-step scan of three dense 66 x 66 solves, never read from the cache), so
runs on other machines or at other loads compare.

    PYTHONPATH=. python benchmarks/first_answer.py [--base DIR] [--out DIR]

``--base DIR``: a checkout of the code before a change (``git worktree add /tmp/base REV``),
measured the same way in the same run, alternating with this checkout. Prints one table
per checkout and writes ``first_answer.json`` into ``--out`` (default out/bench).
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

# The snippet of README.md, "Using it", one call per step (run from the checkout's root).
CHILD = r'''
import json, sys, time
def cpu():
    return time.process_time()
steps = {}
t = cpu()
import jax, jax.numpy as jnp, numpy as np
import simsoft_jax as sj
steps["import"] = cpu() - t

def yardstick():
    a = jnp.asarray(8.0 * np.eye(66) + np.random.default_rng(0).uniform(-1, 1, (66, 66)))
    b = jnp.ones(66)
    def run(a, b):
        def step(x, _):
            for _ in range(3):
                x = jnp.linalg.solve(a + jnp.diag(x), x + b)
            return x / jnp.linalg.norm(x), None
        return jax.lax.scan(step, b, None, length=300)[0]
    # compiled, never read from the persistent cache (which may keep every program)
    from jax.experimental.compilation_cache import compilation_cache
    jax.config.update("jax_enable_compilation_cache", False)
    compilation_cache.reset_cache()
    t = cpu()
    jax.jit(run).lower(a, b).compile()
    return cpu() - t

def timed(name, fn):
    t = cpu()
    out = jax.block_until_ready(fn())
    steps[name] = cpu() - t
    return out

scene = sj.load_scene("examples/scenes/cantilever_tip_force.toml")
timed("sj.run(static scene)", lambda: sj.run(scene).positions("beam"))
timed("sj.run(static scene), again", lambda: sj.run(scene).positions("beam"))
model = sj.build_model(scene)
timed("sj.solve_static(model)", lambda: sj.solve_static(model).p)
timed("sj.solve_static(model), again", lambda: sj.solve_static(model).p)
grad = lambda: jax.grad(lambda K: sj.solve_static(model.replace(stiffness=K)).p[-1, 2])(
    model.stiffness)
timed("jax.grad of the static tip", grad)
timed("jax.grad of the static tip, again", grad)
dyn_scene = sj.load_scene("examples/scenes/helical_synthetic.json")
timed("sj.run(dynamic scene)", lambda: sj.run(dyn_scene).positions("rod"))
dyn = sj.build_model(dyn_scene)
settings = sj.DynamicSettings(dt=0.01, steps=100, rho_inf=0.9)
timed("sj.simulate(model), 100 steps", lambda: sj.simulate(dyn, settings).p)
timed("sj.simulate(model), 100 steps, again", lambda: sj.simulate(dyn, settings).p)
final_tip = lambda K: sj.simulate(dyn.replace(stiffness=K), settings,
                                  differentiable=True).p[-1, -1, 2]
timed("jax.grad through 100 steps", lambda: jax.grad(final_tip)(dyn.stiffness))
timed("jax.grad through 100 steps, again", lambda: jax.grad(final_tip)(dyn.stiffness))
steps["yardstick (compile)"] = yardstick()
print("RESULT " + json.dumps(steps))
'''


def measure(checkout: Path, cache: Path) -> dict:
    """CPU seconds per step of the snippet in a fresh process of ``checkout`` with the
    compilation cache folder ``cache``."""
    env = dict(os.environ, PYTHONPATH=str(checkout), SIMSOFT_JAX_CACHE_DIR=str(cache),
               JAX_COMPILATION_CACHE_DIR=str(cache), SIMSOFT_JAX_QUIET="1")
    proc = subprocess.run([sys.executable, "-c", CHILD], cwd=checkout, env=env,
                          capture_output=True, text=True)
    for line in proc.stdout.splitlines():
        if line.startswith("RESULT "):
            return json.loads(line[len("RESULT "):])
    raise RuntimeError(f"the snippet failed in {checkout}:\n{proc.stderr[-3000:]}")


def table(name: str, cold: dict, warm: dict) -> str:
    stick_c, stick_w = cold["yardstick (compile)"], warm["yardstick (compile)"]
    rows = [f"{name}  (yardstick: compile of a fixed program, {stick_c:.2f} s CPU cold "
            f"process, {stick_w:.2f} s warm)",
            f"{'call':40s} {'cold s':>8s} {'/stick':>7s} {'warm s':>8s} {'/stick':>7s}"]
    for key in cold:
        if key == "yardstick (compile)":
            continue
        rows.append(f"{key:40s} {cold[key]:8.2f} {cold[key] / stick_c:7.2f} "
                    f"{warm[key]:8.2f} {warm[key] / stick_w:7.2f}")
    total_c = sum(v for k, v in cold.items() if k not in ("yardstick (compile)", "import"))
    total_w = sum(v for k, v in warm.items() if k not in ("yardstick (compile)", "import"))
    rows.append(f"{'all calls':40s} {total_c:8.2f} {total_c / stick_c:7.2f} "
                f"{total_w:8.2f} {total_w / stick_w:7.2f}")
    return "\n".join(rows)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    parser.add_argument("--base", type=Path, help="checkout of the code before (optional)")
    parser.add_argument("--out", type=Path, default=Path("out/bench"))
    args = parser.parse_args(argv)
    checkouts = {"this checkout": ROOT}
    if args.base is not None:
        checkouts["base"] = args.base.resolve()
    results = {}
    with tempfile.TemporaryDirectory() as tmp:
        for name, checkout in checkouts.items():     # one after the other, cold then warm
            cache = Path(tmp) / name.replace(" ", "_")
            cache.mkdir()
            results[name] = {"cold": measure(checkout, cache), "warm": measure(checkout, cache)}
            print(table(name, results[name]["cold"], results[name]["warm"]), flush=True)
    load = os.getloadavg()[0]
    print(f"load average at the end: {load:.2f}")
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "first_answer.json").write_text(json.dumps(
        dict(results, load_average=load), indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
