"""Solve a static scene file and plot the rod (default: the Princeton beam at 30 degrees).

    python examples/static_cantilever.py [SCENE] [--out OUTDIR]

Prints the tip position, iterations and timings, and writes OUTDIR/<scene name>.png with
the deformed centreline (helical interpolation between nodes) and the section frames.
"""
import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import simsoft_jax as sj  # noqa: E402
from simsoft_jax.analysis import kinematics  # noqa: E402

HERE = Path(__file__).resolve().parent


def plot(result, path):
    fig = plt.figure(figsize=(7, 5))
    ax = fig.add_subplot(projection="3d")
    for info in result.model.structure.rods:
        R, p = result.rotations(info.name), result.positions(info.name)
        _, curve = kinematics.sample_shape(R, p, 8)
        curve = np.asarray(curve)
        ax.plot(*curve.T, lw=2, label=info.name)
        ax.scatter(*p.T, s=8)
        scale = 0.05 * np.ptp(curve, axis=0).max()
        for Ri, pi in zip(R[::2], p[::2]):
            for k, color in zip((1, 2), ("g", "b")):
                ax.plot(*np.stack([pi, pi + scale * Ri[:, k]]).T, color=color, lw=0.8)
    ax.set_xlabel("x [m]"), ax.set_ylabel("y [m]"), ax.set_zlabel("z [m]")
    ax.set_title(f"{result.name} ({result.newton_iterations} Newton iterations; axes not to scale)")
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scene", nargs="?", default=HERE / "scenes" / "princeton_theta30.toml")
    parser.add_argument("--out", default="out")
    args = parser.parse_args()
    result = sj.run(args.scene)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    name = result.name or Path(args.scene).stem
    for info in result.model.structure.rods:
        print(f"{name}: rod {info.name} tip at {np.round(result.positions(info.name)[-1], 6)} m")
    print(f"converged={result.converged}, {result.newton_iterations} Newton iterations, "
          f"solve {result.wall_time_s * 1e3:.1f} ms, compile {result.compile_time_s:.1f} s")
    plot(result, out / f"{name}.png")
    print(f"wrote {out / (name + '.png')}")
    return 0 if result.converged else 1


if __name__ == "__main__":
    raise SystemExit(main())
