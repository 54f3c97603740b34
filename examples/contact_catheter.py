"""A catheter pushed through a guide tube against a spherical obstacle (contact).

    python examples/contact_catheter.py [--out out/contact_catheter] [--fast]

Scene (built here): a steel tube catheter (outer 2 mm, inner 1 mm: EI = 0.155 N m^2,
contact radius 1 mm), 100 mm long, along world x, its base driven forward 40 mm in 1 s
(a drive: clamped, moving). It runs inside a straight guide tube (obstacle ``"guide"``,
kind ``tube``, radius 4 mm around the x axis) and its tip meets a sphere (``"wall"``,
radius 10 mm, centre 4 mm off the axis, friction 0.1) a little beyond x = 110 mm: the
tip slides off the sphere's side and the catheter bends until it leans on the guide's
wall. Dynamic, dt = 0.01 s, rho_inf = 0.5, mass-proportional damping 20/s (the catheter
is light and stiff: it follows its quasi-static path); the default penalty stiffness
(1e3 EI/h^4 per element) keeps the penetration far below the contact radius.

Prints the normal force of each obstacle and the largest penetration at a few times;
writes snapshots.png (catheter, guide walls and sphere in the x-y plane),
contact_forces.png and summary.json (``--fast``: 10 elements instead of 20).
"""
import numpy as np

import simsoft_jax as sj

from _common import parse_args, save, write_summary

LENGTH, PUSH, R_GUIDE, R_WALL = 0.1, 0.04, 0.004, 0.01
WALL_CENTER = [0.12, 0.0088, 0.0]


def scene(elements: int) -> dict:
    return {
        "name": "contact_catheter",
        "solver": {"kind": "dynamic", "t_end": 1.0, "dt": 0.01, "rho_inf": 0.5},
        "materials": [{"name": "steel", "E": 210e9, "nu": 0.3, "density": 7850,
                       "mass_damping": 20.0}],
        "rods": [{"name": "catheter", "material": "steel",
                  "section": {"shape": "tube", "outer_diameter": 2e-3,
                              "inner_diameter": 1e-3},
                  "elements": elements, "geometry": {"kind": "straight", "length": LENGTH}}],
        "constraints": [{"kind": "drive", "rod": "catheter", "node": 0, "times": [0.0, 1.0],
                         "displacement": [[0, 0, 0], [PUSH, 0, 0]],
                         "rotation": [[0, 0, 0], [0, 0, 0]]}],
        "obstacles": [{"name": "guide", "kind": "tube", "axis_point": [0, 0, 0],
                       "axis": [1, 0, 0], "radius": R_GUIDE},
                      {"name": "wall", "kind": "sphere", "center": WALL_CENTER,
                       "radius": R_WALL, "friction": 0.1}],
        "contact": {"stiffness": 1e8},
    }


def main():
    args = parse_args("contact_catheter", __doc__)
    result = sj.run(scene(10 if args.fast else 20))
    contacts, time = result.contacts, result.time
    p = result.positions("catheter")
    radius = float(result.model.contact_radius[0])
    print(f"catheter pushed {PUSH * 1e3:g} mm: converged = {result.converged}, "
          f"{result.newton_iterations} Newton iterations, {result.wall_time_s:.1f} s "
          f"(+ {result.compile_time_s:.1f} s compiling)")
    for t in (0.25, 0.5, 0.75, 1.0):
        i = int(np.argmin(np.abs(time - t)))
        forces = ", ".join(f"{name} {float(c['normal_force'][i]):.3f} N"
                           for name, c in contacts.items())
        pen = max(float(c["max_penetration"][i]) for c in contacts.values())
        print(f"t = {time[i]:.2f} s: tip at {np.round(p[i, -1] * 1e3, 2)} mm; normal "
              f"forces: {forces}; largest penetration {pen / radius:.1e} of the rod's radius")

    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(7, 3.5))
    for t in (0.0, 0.4, 0.7, 1.0):
        i = int(np.argmin(np.abs(time - t)))
        ax.plot(p[i, :, 0] * 1e3, p[i, :, 1] * 1e3, "o-", ms=2, label=f"t = {time[i]:.1f} s")
    ax.axhline(R_GUIDE * 1e3, color="gray")
    ax.axhline(-R_GUIDE * 1e3, color="gray", label="guide wall")
    ax.add_patch(plt.Circle(np.multiply(WALL_CENTER[:2], 1e3), R_WALL * 1e3, color="tab:red",
                            alpha=0.3, label="sphere"))
    ax.set_aspect("equal")
    ax.set_xlabel("x [mm]")
    ax.set_ylabel("y [mm]")
    ax.legend(fontsize="small", loc="lower left")
    save(fig, args.out, "snapshots.png")
    fig, ax = plt.subplots(figsize=(6, 3.5))
    for name, c in contacts.items():
        ax.plot(time, c["normal_force"], label=name)
    ax.set_xlabel("t [s]")
    ax.set_ylabel("normal force [N]")
    ax.legend()
    save(fig, args.out, "contact_forces.png")
    write_summary(args.out, {
        "converged": result.converged, "time_s": time.tolist(), "contact_radius_m": radius,
        "wall_center_m": WALL_CENTER, "wall_radius_m": R_WALL, "guide_radius_m": R_GUIDE,
        "tip_m": p[:, -1].tolist(),
        "contacts": {name: {"normal_force_N": c["normal_force"].tolist(),
                            "force_N": c["force"].tolist(),
                            "max_penetration_m": c["max_penetration"].tolist()}
                     for name, c in contacts.items()}})
    return 0 if result.converged else 1


if __name__ == "__main__":
    raise SystemExit(main())
