"""Batched sweeps against the sequential loop, on one core and on all cores (one run).

    PYTHONPATH=. python benchmarks/sweeps_batched.py [--quick] [--out DIR]

Static: Princeton cases (16 elements, gravity), random load angles (0-90 deg) and tip
loads (0.5-4 lbf) in random order, 1000 (200 with --quick). Dynamic: the synthetic
helical scene (10 elements, dt 0.01 s, 3 s), the load amplitudes and EI varied by a
random factor in [0.7, 1.3], 1000 scenes (64 with --quick). Rows: the sequential loop (a
jitted single solve called per scene from Python, on a subset of 100 / 16 scenes, as
scenes/s), ``sweeps.static_sweep`` / ``dynamic_sweep`` on one device and on every host
device (``sweeps.use_host_devices()``: one per core, set before JAX starts), and for
comparison the plain ``jax.vmap`` of the single solver and a static chunk of
``FLAT_FROM`` (the flat continuation). Also the single synthetic
helical scene after compile. Every row is timed after its compile (one warm-up call);
CPU time (all threads) is given beside wall time because the machine is shared.
"""
from __future__ import annotations

import os
import sys
import time
from pathlib import Path

from simsoft_jax.studies import sweeps

sweeps.use_host_devices()      # every core a JAX device; before any array is created

import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
import common  # noqa: E402

import simsoft_jax as sj  # noqa: E402
from simsoft_jax.apps import princeton  # noqa: E402
from simsoft_jax.math.xla import jit  # noqa: E402


def clock(fn, *args):
    """(wall s, CPU s of this process, result) of one call after a warm-up call."""
    jax.block_until_ready(fn(*args))
    wall, cpu = time.perf_counter(), time.process_time()
    out = jax.block_until_ready(fn(*args))
    return time.perf_counter() - wall, time.process_time() - cpu, out


def row(kind, how, cases, wall, cpu, converged, devices):
    return dict(kind=kind, how=how, cases=cases, devices=devices, wall_s=wall, cpu_s=cpu,
                scenes_per_s=cases / wall, converged=int(converged),
                load=os.getloadavg()[0])


def vary_helical(model, q):
    """Load amplitudes (every nodal dead-load channel) and EI_y, EI_z scaled."""
    channels = model.channels.replace(nodal_dead=model.channels.nodal_dead * q["amplitude"])
    return model.replace(channels=channels,
                         stiffness=model.stiffness.at[:, 4:].multiply(q["ei"]))


# The continuation before the loose intermediate levels (issue 16): every level solved to
# the final tolerance, increments at most 1/load_steps. The same code path with the new
# settings turned off, so "before" and "after" alternate in one run. After: the
# Princeton cases' settings (loose intermediate levels, increments up to the whole load).
BEFORE = sj.StaticSettings(level_tolerance=0.0)
AFTER = princeton.CASE_SETTINGS


def static_rows(cases, rng):
    model = sj.build_model(princeton.scene(16))
    points = {"theta": rng.uniform(0.0, 90.0, cases),
              "load": rng.uniform(0.5, 4.0, cases) * princeton.F0}
    vary = princeton._vary_case
    one = jit(lambda q, st: sj.solve_static(vary(model, q), st))
    seq = min(cases, 100)
    sub = [{k: jnp.asarray(v[i]) for k, v in points.items()} for i in range(seq)]
    rows, results = [], {}
    runs = [("sequential loop", 1, None)] + [
        (f"static_sweep chunk {chunk or sweeps.STATIC_CHUNK}", devices, chunk)
        # vmapped (flat) chunks on one device only: on several CPU devices jaxlib < 0.11.2
        # can hang on them (sweeps._chunk refuses them there)
        for devices, chunk in ((1, sweeps.STATIC_CHUNK), (len(jax.local_devices()), None),
                               (1, sweeps.FLAT_FROM))]
    for how, devices, chunk in runs:
        for label, settings in (("before", BEFORE), ("after", AFTER)):
            settings = sj.statics.as_traced(settings)
            if how == "sequential loop":
                wall, cpu, res = clock(lambda: [one(q, settings) for q in sub])
                converged, n = sum(bool(r.converged) for r in res), seq
                its = np.mean([int(r.iterations) for r in res])
            else:
                wall, cpu, eq = clock(lambda: sweeps.static_sweep(
                    model, vary, points, settings, chunk=chunk, devices=devices))
                converged, n, its = np.sum(eq.converged), cases, float(np.mean(eq.iterations))
                results[label] = eq
            flat = " (flat)" if chunk == sweeps.FLAT_FROM else ""
            rows.append(row("static", f"{how}{flat}, {label}", n, wall, cpu, converged, devices)
                        | {"iterations": its})
    plain = jit(jax.vmap(lambda q: sj.solve_static(vary(model, q), AFTER)))
    arrays = {k: jnp.asarray(v) for k, v in points.items()}
    wall, cpu, ref = clock(plain, arrays)
    rows.append(row("static", "jax.vmap of solve_static, after", cases, wall, cpu,
                    np.sum(ref.converged), 1) | {"iterations": float(np.mean(ref.iterations))})
    diff = float(jnp.max(jnp.abs(results["after"].p - ref.p)))
    change = float(jnp.max(jnp.abs(results["after"].p - results["before"].p)))
    print(f"static: largest |p| difference sweep vs vmap of single solves: {diff:.2e} m; "
          f"after vs before: {change:.2e} m")
    return rows, diff


def dynamic_rows(cases, rng):
    scene = common.scene_with("helical_synthetic.json")
    model, settings = common.dynamic_setup(scene)
    points = {"amplitude": rng.uniform(0.7, 1.3, cases), "ei": rng.uniform(0.7, 1.3, cases)}
    one = jit(lambda q: sj.simulate(vary_helical(model, q), settings).p[-1])
    seq = min(cases, 16)
    sub = [{k: jnp.asarray(v[i]) for k, v in points.items()} for i in range(seq)]
    wall, cpu, res = clock(lambda: [one(q) for q in sub])
    rows = [row("dynamic", "sequential loop", seq, wall, cpu, seq, 1)]
    single_wall, single_cpu, _ = clock(one, sub[0])
    rows.append(row("dynamic", "one scene", 1, single_wall, single_cpu, 1, 1))
    small = {k: v[:64] for k, v in points.items()}
    for devices, chunk in ((1, 1), (len(jax.local_devices()), 1), (1, 8)):
        batch = points if chunk == 1 else small
        wall, cpu, traj = clock(lambda: sweeps.dynamic_sweep(
            model, vary_helical, batch, settings, chunk=chunk, devices=devices))
        rows.append(row("dynamic", f"dynamic_sweep chunk {chunk}", len(batch["ei"]), wall,
                        cpu, np.sum(traj.converged), devices))
        if chunk == 1:
            full = traj
    diff = float(max(jnp.max(jnp.abs(full.p[i, -1] - r)) for i, r in enumerate(res)))
    print(f"dynamic: largest final |p| difference sweep vs single rollouts: {diff:.2e} m")
    return rows, diff


def run(quick=False, out=Path("out/bench"), static_only=False):
    """Scenes/s of batched sweeps (one core, all cores) against the sequential loop."""
    rng = np.random.default_rng(16)
    print(f"devices: {jax.local_devices()}")
    srows, sdiff = static_rows(200 if quick else 1000, rng)
    drows, ddiff = ([], None) if static_only else dynamic_rows(64 if quick else 1000, rng)
    rows = srows + drows
    common.table(rows, [("kind", "kind", "s"), ("how", "how", "s"), ("cases", "cases", "d"),
                        ("devices", "devices", "d"), ("wall_s", "wall s", ".3f"),
                        ("cpu_s", "cpu s", ".3f"), ("scenes_per_s", "scenes/s", ".1f"),
                        ("converged", "converged", "d"), ("iterations", "Newton its", ".1f"),
                        ("load", "load", ".2f")],
                 title="batched sweeps (after compile)")
    common.save_json(out, "sweeps_batched", {"rows": rows, "static_diff_m": sdiff,
                                             "dynamic_diff_m": ddiff,
                                             "machine": common.machine()})
    return rows


def main(argv=None) -> int:
    """``--quick``, ``--out DIR`` and ``--static-only`` (skip the dynamic sweeps)."""
    import argparse
    parser = argparse.ArgumentParser(description=run.__doc__)
    parser.add_argument("--quick", action="store_true", help="200 / 64 scenes")
    parser.add_argument("--out", default="out/bench", help="folder for the JSON")
    parser.add_argument("--static-only", action="store_true", help="only the static sweeps")
    args = parser.parse_args(argv)
    print(common.describe(common.machine()))
    run(quick=args.quick, out=Path(args.out), static_only=args.static_only)
    return 0

if __name__ == "__main__":
    raise SystemExit(main())
