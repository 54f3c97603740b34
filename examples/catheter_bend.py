"""A catheter pushed through a curved vessel (a curved tube obstacle, a GIF).

    python examples/catheter_bend.py [--out out/catheter_bend] [--fast]

Scene (built here): a polymer tube catheter (E = 200 MPa, outer 2 mm, inner 1 mm:
EI = 1.47e-4 N m^2, contact radius 1 mm, 100 mm long) lies on the axis of the straight
inlet of a vessel (obstacle ``"vessel"``, kind ``curved_tube``, radius 4 mm): the vessel
turns by 90 degrees about z with a bend radius of 40 mm (centreline from the origin along
+x, bending towards +y) and goes on straight along +y. The catheter's base is driven 80
mm forward along x in 2 s (a drive: clamped, moving), so its tip goes through the whole
bend into the outlet, sliding along the outer wall (friction 0.05). Dynamic, dt = 0.01 s,
rho_inf = 0.5, mass-proportional damping 20/s (the catheter is light and follows its
quasi-static path); the default penalty (1e3 EI/h^4 per element) keeps the penetration
far below the contact radius.

Prints the vessel's normal force, the largest penetration and the tip's place at a few
times; writes snapshots.png (catheter and vessel walls in the x-y plane),
contact_force.png, catheter_bend.gif (an animation of the push: matplotlib's
PillowWriter, Pillow is a matplotlib dependency) and summary.json (``--fast``: 10
elements instead of 20, one GIF frame in 10 instead of 1 in 4).
"""
import numpy as np

import simsoft_jax as sj

from _common import parse_args, save, write_summary

LENGTH, PUSH, T_PUSH = 0.1, 0.08, 2.0
R_VESSEL, R_BEND, ANGLE = 0.004, 0.04, 0.5 * np.pi
CENTER = np.array([0.0, R_BEND, 0.0])


def scene(elements: int) -> dict:
    return {
        "name": "catheter_bend",
        "solver": {"kind": "dynamic", "t_end": T_PUSH, "dt": 0.01, "rho_inf": 0.5},
        "materials": [{"name": "polymer", "E": 2e8, "nu": 0.4, "density": 1100,
                       "mass_damping": 20.0}],
        "rods": [{"name": "catheter", "material": "polymer",
                  "section": {"shape": "tube", "outer_diameter": 2e-3,
                              "inner_diameter": 1e-3},
                  "elements": elements, "geometry": {"kind": "straight", "length": LENGTH},
                  "base": {"position": [-LENGTH, 0.0, 0.0]}}],
        "constraints": [{"kind": "drive", "rod": "catheter", "node": 0,
                         "times": [0.0, T_PUSH], "displacement": [[0, 0, 0], [PUSH, 0, 0]],
                         "rotation": [[0, 0, 0], [0, 0, 0]]}],
        "obstacles": [{"name": "vessel", "kind": "curved_tube", "center": CENTER.tolist(),
                       "normal": [0, 0, 1], "start": [0, 0, 0], "angle": ANGLE,
                       "radius": R_VESSEL, "friction": 0.05}],
    }


def centreline(n: int = 200):
    """The vessel's centreline in the x-y plane: inlet, bend, outlet (m), (3n, 2)."""
    phi = np.linspace(0.0, ANGLE, n)
    bend = np.stack([R_BEND * np.sin(phi), R_BEND * (1.0 - np.cos(phi))], 1)
    s = np.linspace(0.0, 1.2 * LENGTH, n)
    inlet = np.stack([-s[::-1], 0 * s], 1)
    outlet = np.stack([R_BEND + 0 * s, R_BEND + s], 1)
    return np.concatenate([inlet, bend, outlet])


def walls(ax):
    """Draw the vessel's two walls (its centreline offset by the radius) in mm."""
    c = centreline()
    t = np.gradient(c, axis=0)
    nrm = np.stack([-t[:, 1], t[:, 0]], 1) / np.linalg.norm(t, axis=1)[:, None]
    for side in (1.0, -1.0):
        w = (c + side * R_VESSEL * nrm) * 1e3
        ax.plot(w[:, 0], w[:, 1], color="gray", lw=1.5)


def frame_axes(ax):
    walls(ax)
    ax.set_xlim(-LENGTH * 1e3, (R_BEND + 0.01) * 1e3)
    ax.set_ylim(-12, (R_BEND + 0.04) * 1e3)
    ax.set_aspect("equal")
    ax.set_xlabel("x [mm]")
    ax.set_ylabel("y [mm]")


def animate(time, p, path, every: int):
    """Write the push as a GIF (PillowWriter): the catheter in the vessel, top view."""
    import matplotlib.pyplot as plt
    from matplotlib.animation import FuncAnimation, PillowWriter

    fig, ax = plt.subplots(figsize=(5, 5))
    frame_axes(ax)
    line, = ax.plot([], [], "o-", color="tab:blue", ms=2, lw=2)
    title = ax.set_title("")
    frames = list(range(0, len(time), every)) + [len(time) - 1]

    def draw(i):
        line.set_data(p[i, :, 0] * 1e3, p[i, :, 1] * 1e3)
        title.set_text(f"catheter pushed through a bend, t = {time[i]:.2f} s")
        return line, title

    FuncAnimation(fig, draw, frames=frames, blit=False).save(path, writer=PillowWriter(fps=10))
    plt.close(fig)
    print(f"wrote {path}")


def main():
    args = parse_args("catheter_bend", __doc__)
    result = sj.run(scene(10 if args.fast else 20))
    vessel, time = result.contacts["vessel"], result.time
    p = result.positions("catheter")
    radius = float(result.model.contact_radius[0])
    print(f"catheter pushed {PUSH * 1e3:g} mm through a {np.degrees(ANGLE):g} degree bend: "
          + ("converged" if result.converged else result.message)
          + f", {result.newton_iterations} Newton iterations ({result.wall_time_s:.1f} s, "
          f"{result.compile_time_s:.1f} s compiling)")
    for i in np.abs(time[:, None] - [0.5, 1.0, 1.5, 2.0]).argmin(axis=0):
        print(f"t = {time[i]:.2f} s: tip at {np.round(p[i, -1] * 1e3, 2)} mm; vessel normal "
              f"force {float(vessel['normal_force'][i]):.4f} N; largest penetration "
              f"{float(vessel['max_penetration'][i]) / radius:.1e} of the rod's radius")

    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(5, 5))
    frame_axes(ax)
    for t in (0.0, 0.5, 1.0, 1.5, 2.0):
        i = int(np.argmin(np.abs(time - t)))
        ax.plot(p[i, :, 0] * 1e3, p[i, :, 1] * 1e3, "o-", ms=2, label=f"t = {time[i]:.1f} s")
    ax.legend(fontsize="small", loc="upper left")
    save(fig, args.out, "snapshots.png")
    fig, ax = plt.subplots(figsize=(6, 3.5))
    ax.plot(time, vessel["normal_force"])
    ax.set_xlabel("t [s]")
    ax.set_ylabel("vessel's normal force [N]")
    save(fig, args.out, "contact_force.png")
    animate(time, p, args.out / "catheter_bend.gif", 10 if args.fast else 4)
    write_summary(args.out, {
        "converged": result.converged, "time_s": time.tolist(), "contact_radius_m": radius,
        "vessel_radius_m": R_VESSEL, "bend_radius_m": R_BEND, "bend_angle_rad": ANGLE,
        "bend_center_m": CENTER.tolist(), "push_m": PUSH, "length_m": LENGTH,
        "positions_m": p.tolist(),
        "normal_force_N": vessel["normal_force"].tolist(),
        "max_penetration_m": vessel["max_penetration"].tolist()})
    return 0 if result.converged else 1


if __name__ == "__main__":
    raise SystemExit(main())
