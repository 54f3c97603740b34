"""Shared helpers of the benchmark scripts: machine description, median timings, scene
variants, tables and plots. Not a test; nothing here asserts on time."""
from __future__ import annotations

import functools
import json
import os
import platform
import subprocess
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

import simsoft_jax as sj

SCENES = Path(__file__).resolve().parents[1] / "examples" / "scenes"
HELICAL = ("helical_synthetic.json", "helical_spring_steel.json", "helical_silicone.json")


def machine() -> dict:
    """CPU model, core count, load average, jax version and device of this run."""
    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    try:
        nproc = int(subprocess.run(["nproc"], capture_output=True, text=True).stdout)
    except (OSError, ValueError):
        nproc = os.cpu_count()
    return {"cpu": cpu, "nproc": nproc, "load_average": os.getloadavg()[0],
            "jax": jax.__version__, "device": str(jax.devices()[0]),
            "simsoft_jax": sj.__version__, "yardstick_ms": yardstick_ms()}


@functools.lru_cache(maxsize=None)
def yardstick_ms() -> float:
    """A fixed workload that puts figures taken on other machines or at other moments on
    one scale (issue 19): 300 steps of three dense 66 x 66 solves in one ``lax.scan``
    (the size of the helical scenes' iteration matrix; each matrix depends on the carry,
    so each is factorized), the fastest of 5 runs after compiling, in ms. Figures of two
    runs compare after dividing by their yardsticks. Measured once per process, at the
    first call (:func:`machine` is called at the start and at the end of several
    scripts)."""
    rng = np.random.default_rng(0)
    a = jnp.asarray(8.0 * np.eye(66) + rng.uniform(-1.0, 1.0, (66, 66)))
    b = jnp.asarray(rng.uniform(-1.0, 1.0, 66))

    @jax.jit
    def run(a, b):
        def step(x, _):
            for _ in range(3):
                x = jnp.linalg.solve(a + jnp.diag(x), x + b)   # factorized every time
            return x / jnp.linalg.norm(x), None
        return jax.lax.scan(step, b, None, length=300)[0]

    jax.block_until_ready(run(a, b))
    walls = []
    for _ in range(5):
        start = time.perf_counter()
        jax.block_until_ready(run(a, b))
        walls.append(time.perf_counter() - start)
    return 1e3 * min(walls)


def describe(info: dict) -> str:
    return (f"machine: {info['cpu']}, nproc {info['nproc']}, jax {info['jax']} "
            f"({info['device']}), load average {info['load_average']:.2f}, "
            f"yardstick {info['yardstick_ms']:.2f} ms")


def median_time(fn, *args, repeats=5, warmup=1):
    """Median wall time (s) of ``fn(*args)`` (blocked until ready) after ``warmup`` calls,
    and the last result."""
    out = None
    for _ in range(warmup):
        out = jax.block_until_ready(fn(*args))
    walls = []
    for _ in range(repeats):
        start = time.perf_counter()
        out = jax.block_until_ready(fn(*args))
        walls.append(time.perf_counter() - start)
    return float(np.median(walls)), out


def timed(fn, *args):
    """(seconds, result) of one call, blocked until ready."""
    start = time.perf_counter()
    out = jax.block_until_ready(fn(*args))
    return time.perf_counter() - start, out


def scene_with(name: str, elements: int | None = None, dt: float | None = None,
               **solver) -> sj.Scene:
    """An example scene with another element count (all rods) and/or time step."""
    d = sj.load_scene(SCENES / name).to_dict()
    if elements is not None:
        for rod in d["rods"]:
            rod["elements"] = int(elements)
    if dt is not None:
        d["solver"]["dt"] = float(dt)
    d["solver"].update(solver)
    return sj.Scene.from_dict(d)


def dynamic_setup(scene: sj.Scene, steps: int | None = None):
    """Model and DynamicSettings of a dynamic scene (float settings as float64 arrays, so
    a compiled rollout can be called with them)."""
    model = sj.build_model(scene)
    s = scene.solver
    steps = int(round(s.t_end / s.dt)) if steps is None else steps
    settings = sj.DynamicSettings(dt=s.dt, steps=steps, rho_inf=s.rho_inf,
                                  tolerance=s.tolerance, max_iterations=s.max_iterations)
    return model, sj.statics.as_traced(settings)


def static_setup(scene: sj.Scene):
    """Model and StaticSettings of a static scene (float settings as float64 arrays)."""
    return (sj.build_model(scene),
            sj.statics.as_traced(sj.statics.settings_from_scene(scene.solver)))


def compile_static(model, settings):
    """(lowered, compiled) static solver for this model structure: the compiled program
    is called as ``compiled(model, settings)``."""
    lowered = sj.statics.static_program.lower(model, settings)
    return lowered, lowered.compile()


def compile_dynamic(model, settings, state):
    """(lowered, compiled) rollout of ``settings.steps`` steps from ``state`` (e.g.
    ``sj.initial_state(model)``, computed outside the timed program) for this model
    structure, called as ``compiled(model, settings, state)``."""
    from simsoft_jax.solvers.dynamics.rollout import rollout_program

    lowered = rollout_program.lower(model, settings, state)
    return lowered, lowered.compile()


def rollout_cost(scene: sj.Scene, repeats: int) -> dict:
    """Compile time (s) and median wall time (s) of ``scene``'s rollout from its initial
    state, its total Newton iterations, steps and whether every step converged."""
    model, settings = dynamic_setup(scene)
    state = sj.initial_state(model)
    start = time.perf_counter()
    _, compiled = compile_dynamic(model, settings, state)
    compile_s = time.perf_counter() - start
    wall, traj = median_time(compiled, model, settings, state, repeats=repeats)
    return dict(converged=bool(traj.converged), compile_s=compile_s, wall_s=wall,
                iterations=int(np.sum(traj.iterations)), steps=int(settings.steps))


def count_hlo_ops(lowered) -> int:
    """Number of operations in a lowered (StableHLO) program: a proxy for compile time."""
    return sum(1 for line in lowered.as_text().splitlines() if " = " in line)


def table(rows, columns, title=None) -> str:
    """Plain-text table of dict rows; columns: (key, header, format)."""
    lines = [title] if title else []
    widths = [max(len(h), 10) for _, h, _ in columns]
    lines.append("  ".join(h.rjust(w) for (_, h, _), w in zip(columns, widths)))
    for row in rows:
        lines.append("  ".join(format(row[k], f).rjust(w) if row.get(k) is not None else
                               "-".rjust(w) for (k, _, f), w in zip(columns, widths)))
    text = "\n".join(lines)
    print(text, flush=True)
    return text


def save_json(out: Path, name: str, data) -> Path:
    out.mkdir(parents=True, exist_ok=True)
    path = out / f"{name}.json"
    path.write_text(json.dumps(data, indent=1, default=float))
    return path


def plot_lines(out: Path, name: str, series, xlabel, ylabel, title, logx=True, logy=True):
    """Save a line plot (Agg backend): series is a list of (label, xs, ys)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out.mkdir(parents=True, exist_ok=True)
    fig, ax = plt.subplots(figsize=(6, 4.2))
    for label, xs, ys in series:
        ax.plot(xs, ys, "o-", label=label)
    ax.set_xscale("log" if logx else "linear")
    ax.set_yscale("log" if logy else "linear")
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title, fontsize=10)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    path = out / f"{name}.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def standalone(run):
    """``main(argv)`` for one benchmark module: ``--quick`` and ``--out DIR``."""
    import argparse

    def main(argv=None) -> int:
        parser = argparse.ArgumentParser(description=run.__doc__)
        parser.add_argument("--quick", action="store_true", help="fewer sizes and repeats")
        parser.add_argument("--out", default="out/bench", help="folder for plots and JSON")
        args = parser.parse_args(argv)
        print(describe(machine()))
        run(quick=args.quick, out=Path(args.out))
        return 0

    return main
