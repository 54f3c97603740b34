"""Batched sweep: the Princeton tip deflection over load angle x load.

    python examples/princeton_sweep.py [--out DIR] [--fast]

40 angles (0-90 deg) x 25 loads (0.5-4 f0) = 1000 static solves with gravity, in one
compiled call (``princeton.load_angle_sweep``, built on ``simsoft_jax.studies.sweeps.static_sweep``):
by default each point starts from its neighbour's equilibrium (a continuation along the
grid, a few Newton iterations per point); ``--vmap`` solves all points at once from the
straight beam instead. Figure: flapwise and edgewise tip deflection maps.
"""
import time

import matplotlib.pyplot as plt
import numpy as np

from _common import parse_args, save, write_summary

from simsoft_jax.apps import princeton as pr


def main() -> int:
    args = parse_args("princeton_sweep", __doc__, lambda parser: parser.add_argument(
        "--vmap", action="store_true", help="all points at once (jax.vmap), no warm start"))
    n_angles, n_loads, elements = (8, 8, 8) if args.fast else (40, 25, 16)
    theta = np.linspace(0.0, 90.0, n_angles)
    load = np.linspace(0.5, 4.0, n_loads) * pr.F0
    start = time.perf_counter()
    tip, ok = pr.load_angle_sweep(theta, load, elements=elements, warm_start=not args.vmap)
    first = time.perf_counter() - start
    start = time.perf_counter()
    tip, ok = pr.load_angle_sweep(theta, load, elements=elements, warm_start=not args.vmap)
    second = time.perf_counter() - start
    mode = "vmapped" if args.vmap else "warm-started"
    print(f"{tip.shape[0] * tip.shape[1]} cases ({mode}), {elements} elements: all converged {bool(ok.all())}; "
          f"{first:.1f} s with compilation, {second:.1f} s compiled")
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.8))
    for ax, k, name in zip(axes, (0, 1), ("flapwise y", "edgewise z")):
        c = ax.contourf(load / pr.F0, theta, -1e3 * tip[:, :, k], levels=20)
        fig.colorbar(c, ax=ax, label=f"-{name} tip deflection [mm]")
        ax.set(xlabel="load [f0 = 4.448 N]", ylabel="theta [deg]", title=name)
    save(fig, args.out, "tip_deflection_map.png")
    write_summary(args.out, {"cases": int(ok.size), "elements": elements, "converged": bool(ok.all()),
                             "seconds_with_compile": first, "seconds_compiled": second,
                             "theta_deg": theta.tolist(), "load_N": load.tolist(),
                             "tip_m": tip.tolist()})
    return 0 if ok.all() else 1


if __name__ == "__main__":
    raise SystemExit(main())
