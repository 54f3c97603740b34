"""A 2-finger tendon-driven gripper closing on a sphere (tendons and contact).

    python examples/gripper.py [--out out/gripper] [--fast]

Scene (built here, static): two fingers, straight rods 100 mm long along world x
(EI = 0.01 N m^2, contact radius 4 mm), clamped at x = 0 at y = +-20 mm, each with a
tendon from its base to its tip at 5 mm from the centreline on the inner side (towards
the other finger). A fixed frictionless sphere sits between them at x = 80 mm, its
radius (15 mm) leaving a gap g = 1 mm to each finger's surface. Pulling the tendons
bends the fingers towards each other (a tendon at a constant offset d bends its finger with the moment T d) until they
press on the sphere.

The tension is swept (one compiled static solve, new tensions as model arrays): the
squeeze (normal force of the sphere on each finger) against small-deflection beam
theory: a cantilever bent by the uniform moment T d and held back by the contact force
F at x_c: T d x_c^2 / (2 EI) - F x_c^3 / (3 EI) = g, so F = 3 T d / (2 x_c) - 3 EI g /
x_c^3 once the fingers touch (T > 2 EI g / (d x_c^2)). Writes grasp.png (the fingers and
the sphere at the largest tension), squeeze.png (F against T, with the beam theory) and
summary.json (``--fast``: 12 elements per finger instead of 24, 4 tensions instead of 8).
"""
import numpy as np

import simsoft_jax as sj
from simsoft_jax.analysis import contacts
from simsoft_jax.solvers import statics

from _common import parse_args, save, write_summary

LENGTH, EI, OFFSET, R_FINGER, HALF_SPAN = 0.1, 0.01, 0.005, 0.004, 0.02
X_SPHERE, GAP = 0.08, 0.001
R_SPHERE = HALF_SPAN - R_FINGER - GAP
TENSIONS = (0.5, 1.0, 1.5, 2.0, 2.5, 3.0, 3.5, 4.0)


def finger(name: str, side: float, elements: int) -> dict:
    return {"name": name, "elements": elements,
            "geometry": {"kind": "straight", "length": LENGTH},
            "base": {"position": [0.0, side * HALF_SPAN, 0.0]},
            "stiffness": {"EA": 1e5, "GAy": 1e5, "GAz": 1e5, "GJ": EI, "EIy": EI, "EIz": EI},
            "inertia": {"rhoA": 0.1, "rhoJ": 1e-6, "rhoIy": 1e-6, "rhoIz": 1e-6},
            "contact_radius": R_FINGER}


def scene(elements: int) -> dict:
    rods = [finger("upper", 1.0, elements), finger("lower", -1.0, elements)]
    return {
        "name": "gripper",
        "solver": {"kind": "static", "load_steps": 10},
        "rods": rods,
        "constraints": [{"kind": "clamp", "rod": r["name"], "node": 0} for r in rods],
        "tendons": [{"name": f"t_{r['name']}", "rod": r["name"], "from_node": 0,
                     "to_node": -1, "offset": [-side * OFFSET, 0.0], "tension": 1.0}
                    for r, side in zip(rods, (1.0, -1.0))],
        "obstacles": [{"name": "sphere", "kind": "sphere", "center": [X_SPHERE, 0.0, 0.0],
                       "radius": R_SPHERE}],
    }


def beam_squeeze(tension):
    """Small-deflection squeeze F (N) at tendon tension T (0 before the fingers touch)."""
    f = 1.5 * np.asarray(tension) * OFFSET / X_SPHERE - 3.0 * EI * GAP / X_SPHERE**3
    return np.maximum(f, 0.0)


def finger_outline(p, radius):
    """Outline (2 M, 2) of a finger of ``radius`` (m) around its centreline ``p`` (M, 2)
    (m) in the x-y plane: the centreline moved by +-radius along its in-plane normal."""
    t = np.gradient(p, axis=0)
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    normal = np.stack([-t[:, 1], t[:, 0]], axis=1)
    return np.concatenate([p + radius * normal, (p - radius * normal)[::-1]])


def main():
    args = parse_args("gripper", __doc__)
    model = sj.build_model(sj.Scene.from_dict(scene(12 if args.fast else 24)))
    settings = statics.settings_from_scene(sj.Scene.from_dict(scene(2)).solver)
    tensions = TENSIONS[1::2] if args.fast else TENSIONS
    squeeze, per_finger, penetration, states = [], [], [], []
    for t in tensions:
        eq = sj.solve_static(model.replace(tendon_tension=model.tendon_tension * t), settings)
        if not bool(eq.converged):
            print(f"T = {t} N: {eq.message()}")
            return 1
        report = contacts.report(model, eq.R, eq.p)["sphere"]
        force = np.asarray(report["force"])
        squeeze.append(float(report["normal_force"]) / 2.0)
        per_finger.append(force.tolist())
        penetration.append(float(report["max_penetration"]))
        states.append(np.asarray(eq.p))
        print(f"T = {t:.1f} N: squeeze {squeeze[-1]:.4f} N per finger (beam theory "
              f"{float(beam_squeeze(t)):.4f} N), net force on the fingers "
              f"{np.round(force, 6)} N, penetration {penetration[-1] / R_FINGER:.1e} of the "
              "finger's radius")

    import matplotlib.pyplot as plt
    n = model.structure.rod("upper").nodes
    fig, ax = plt.subplots(figsize=(6, 3.5), layout="constrained")
    ax.add_patch(plt.Circle((X_SPHERE * 1e3, 0.0), R_SPHERE * 1e3, color="tab:red",
                            alpha=0.3, label=f"sphere (r = {R_SPHERE * 1e3:g} mm)"))
    for p, t, color in ((states[0], tensions[0], "tab:gray"),
                        (states[-1], tensions[-1], "tab:blue")):
        for k, rod in enumerate((slice(0, n), slice(n, 2 * n))):
            band = 1e3 * finger_outline(p[rod, :2], R_FINGER)
            ax.fill(band[:, 0], band[:, 1], color=color, alpha=0.35, lw=0,
                    label=None if k else f"fingers (r = {R_FINGER * 1e3:g} mm), T = {t:g} N")
            ax.plot(p[rod, 0] * 1e3, p[rod, 1] * 1e3, "-", color=color, lw=0.8)
    ax.set_aspect("equal")
    ax.set_xlabel("x [mm]")
    ax.set_ylabel("y [mm]")
    ax.set_title("two tendon-driven fingers squeezing a sphere (top view)")
    fig.legend(loc="outside lower center", ncols=3, fontsize="small")
    save(fig, args.out, "grasp.png")
    fig, ax = plt.subplots(figsize=(5, 3.5))
    fine = np.linspace(0.0, tensions[-1], 100)
    ax.plot(fine, beam_squeeze(fine), "k--", label="small-deflection beam theory")
    ax.plot(tensions, squeeze, "o", label="simsoft_jax")
    ax.set_xlabel("tendon tension T [N]")
    ax.set_ylabel("squeeze per finger [N]")
    ax.legend()
    save(fig, args.out, "squeeze.png")
    write_summary(args.out, {
        "tension_N": list(tensions), "squeeze_N": squeeze, "force_N": per_finger,
        "beam_squeeze_N": beam_squeeze(tensions).tolist(), "max_penetration_m": penetration,
        "finger_radius_m": R_FINGER, "EI_Nm2": EI, "tendon_offset_m": OFFSET,
        "sphere_x_m": X_SPHERE, "gap_m": GAP, "positions_m": [p.tolist() for p in states]})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
