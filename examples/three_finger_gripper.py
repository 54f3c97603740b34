"""A 3-finger tendon-driven gripper on a palm closing dynamically on a sphere (bodies,
joints, tendons, obstacle contact with friction and rod-rod contact in one run).

    python examples/three_finger_gripper.py [--out out/three_finger_gripper] [--fast]

Scene (built here, dynamic): a rigid palm (a body at the origin) held by a short stiff
wrist rod clamped below it (welded to the palm); three fingers, straight rods 100 mm long
along world z (EI = 0.01 N m^2, contact radius 4 mm, mass-proportional damping 30/s),
welded to the palm at 20 mm from the axis at 0, 120 and 240 degrees. Each finger has a
tendon from its base to its tip at 5 mm from the centreline on the side facing the axis;
the tensions rise to T = 3 N by a smoothstep over 0.3 s. A fixed sphere (radius 15 mm,
friction 0.3) sits on the axis at z = 80 mm, leaving a gap g = 1 mm to each finger's
surface. The fingers may touch each other (``[contact] self = true``).

The tendons bend the fingers towards the axis (a tendon at a constant offset d bends its
finger with the uniform moment T d) until they press on the sphere; the run goes on to
0.5 s, when the damped fingers have settled. The friction, regularized on the sliding
velocity, fades as they come to rest, so the final squeeze is that of the frictionless
equilibrium: small-deflection beam theory for each finger (a cantilever bent by T d and
held back by the contact force F at height z_c over the palm) gives
``T d z_c^2 / (2 EI) - F z_c^3 / (3 EI) = g``, so ``F = 3 T d / (2 z_c) - 3 EI g / z_c^3``.
Physical checks written into summary.json: the squeeze per finger (a third of the
sphere's total normal force) against that formula, the three-fold symmetry (the net
force of the sphere on the fingers has no horizontal part), the largest penetration as
a fraction of the finger's contact radius, the finger-finger contact force (zero here:
the fingers close on the sphere before they meet) and how far the palm moved.

Writes snapshots.png (finger 0's inward deflection against height at 6 times, with the
sphere's surface, and the view from above at the end), contact_force.png (squeeze per finger and tendon tension
against time, with the beam theory's squeeze) and summary.json (``--fast``: 8 elements
per finger instead of 16, dt = 10 ms instead of 5 ms).
"""
import numpy as np

import simsoft_jax as sj

from _common import parse_args, save, write_summary

LENGTH, EI, OFFSET, R_FINGER, R_BASE = 0.1, 0.01, 0.005, 0.004, 0.02
Z_SPHERE, GAP, TENSION, T_CLOSE, T_END, FRICTION = 0.08, 0.001, 3.0, 0.3, 0.5, 0.3
R_SPHERE = R_BASE - R_FINGER - GAP
ANGLES = (0.0, 120.0, 240.0)
UP = {"axis": [0, 1, 0], "angle_deg": -90.0}          # local x along world z
WRIST = 0.02


def finger(name: str, angle_deg: float, elements: int) -> dict:
    a = np.radians(angle_deg)
    return {"name": name, "elements": elements,
            "geometry": {"kind": "straight", "length": LENGTH},
            "base": {"position": [R_BASE * np.cos(a), R_BASE * np.sin(a), 0.0],
                     "rotation": UP},
            "stiffness": {"EA": 1e5, "GAy": 1e5, "GAz": 1e5, "GJ": EI, "EIy": EI, "EIz": EI},
            "inertia": {"rhoA": 0.1, "rhoJ": 1e-6, "rhoIy": 1e-6, "rhoIz": 1e-6},
            "material": {"E": 1e6, "nu": 0.5, "density": 1000.0, "mass_damping": 30.0},
            "contact_radius": R_FINGER}


def inward_offset(angle_deg: float) -> list:
    """Tendon offset (y, z) in the section frame of a finger at ``angle_deg``: d towards
    the axis. With UP the section's y is world y and its z is world -x, so the inward
    direction -(cos a, sin a, 0) is (-sin a, cos a) there."""
    a = np.radians(angle_deg)
    return [-OFFSET * np.sin(a), OFFSET * np.cos(a)]


def scene(elements: int, dt: float) -> dict:
    fingers = [finger(f"f{k}", a, elements) for k, a in enumerate(ANGLES)]
    wrist = {"name": "wrist", "elements": 2, "geometry": {"kind": "straight", "length": WRIST},
             "base": {"position": [0.0, 0.0, -WRIST], "rotation": UP},
             "stiffness": {"EA": 1e6, "GAy": 1e6, "GAz": 1e6, "GJ": 10.0, "EIy": 10.0,
                           "EIz": 10.0},
             "inertia": {"rhoA": 0.5, "rhoJ": 1e-5, "rhoIy": 1e-5, "rhoIz": 1e-5},
             "contact_radius": 0.002}
    close = {"kind": "smoothstep", "t0": 0.0, "t1": T_CLOSE}
    return {
        "name": "three_finger_gripper",
        "solver": {"kind": "dynamic", "dt": dt, "t_end": T_END, "rho_inf": 0.5},
        "rods": [wrist] + fingers,
        "constraints": [{"kind": "clamp", "rod": "wrist", "node": 0}],
        "bodies": [{"name": "palm", "mass": 0.05, "position": [0.0, 0.0, 0.0],
                    "inertia": np.diag([1e-5, 1e-5, 2e-5]).tolist()}],
        "joints": [{"kind": "weld", "a": {"rod": "wrist", "node": -1}, "b": {"body": "palm"}}]
        + [{"kind": "weld", "a": {"rod": f["name"], "node": 0},
            "b": {"body": "palm", "offset": f["base"]["position"]}} for f in fingers],
        "tendons": [{"name": f"t{k}", "rod": f["name"], "from_node": 0, "to_node": -1,
                     "offset": inward_offset(a), "tension": TENSION, "profile": close}
                    for k, (f, a) in enumerate(zip(fingers, ANGLES))],
        "obstacles": [{"name": "sphere", "kind": "sphere", "center": [0.0, 0.0, Z_SPHERE],
                       "radius": R_SPHERE, "friction": FRICTION}],
        "contact": {"self": True, "stiffness": 1e8},
    }


def beam_squeeze(tension):
    """Small-deflection squeeze F (N) per finger at tendon tension T (0 before touching)."""
    f = 1.5 * np.asarray(tension) * OFFSET / Z_SPHERE - 3.0 * EI * GAP / Z_SPHERE**3
    return np.maximum(f, 0.0)


def main():
    args = parse_args("three_finger_gripper", __doc__)
    elements, dt = (8, 0.01) if args.fast else (16, 0.005)
    result = sj.run(scene(elements, dt))
    if not result.converged:
        print(result.message)
        return 1
    t = np.asarray(result.time)
    sphere = result.contacts["sphere"]
    squeeze = np.asarray(sphere["normal_force"]) / 3.0
    force = np.asarray(sphere["force"])
    penetration = np.asarray(sphere["max_penetration"])
    rod_rod = np.asarray(result.contacts["rods"]["normal_force"])   # finger-finger
    tension = np.asarray(result.tendon_tension("t0"))
    beam = float(beam_squeeze(TENSION))
    horizontal = float(np.linalg.norm(force[-1, :2]) / max(squeeze[-1], 1e-300))
    palm = result.body_pose("palm")[0]
    tips = np.stack([result.positions(f"f{k}")[:, -1] for k in range(3)], axis=1)
    radial = np.linalg.norm(tips[..., :2], axis=-1)
    print(f"{elements} elements per finger, dt = {dt * 1e3:g} ms: squeeze at t = {t[-1]:g} s "
          f"{squeeze[-1]:.4f} N per finger (beam theory {beam:.4f} N, "
          f"{squeeze[-1] / beam - 1:+.2%}); net sphere force on the fingers "
          f"{np.round(force[-1], 6)} N; largest penetration "
          f"{penetration.max() / R_FINGER:.1e} of the finger's radius; rod-rod contact "
          f"force up to {rod_rod.max():.2e} N; palm moved {np.abs(palm).max():.1e} m")

    import matplotlib.pyplot as plt
    fig, (ax, top) = plt.subplots(1, 2, figsize=(9, 4.5), layout="constrained")
    picks = np.unique(np.searchsorted(t, np.linspace(0.0, T_CLOSE, 6)).clip(0, len(t) - 1))
    cmap = plt.get_cmap("viridis")
    for j, i in enumerate(picks):
        p = result.positions("f0")[i]                  # finger 0 moves along -x
        ax.plot((R_BASE - p[:, 0]) * 1e3, p[:, 2] * 1e3, "-",
                color=cmap(j / max(len(picks) - 1, 1)), lw=1.5, label=f"t = {t[i]:.2f} s")
    z = np.linspace(Z_SPHERE - R_SPHERE, Z_SPHERE + R_SPHERE, 101)
    surface = R_BASE - R_FINGER - np.sqrt(np.maximum(R_SPHERE**2 - (z - Z_SPHERE)**2, 0.0))
    ax.plot(surface * 1e3, z * 1e3, "-", color="tab:red",
            label="sphere's surface less the finger's radius")
    ax.set(xlabel="inward deflection of finger 0 (mm)", ylabel="height z (mm)",
           xlim=(-0.2, 3.0 * GAP * 1e3), title="closing (finger 0, side view)")
    ax.legend(fontsize="small", loc="lower right")
    top.add_patch(plt.Circle((0.0, 0.0), R_SPHERE * 1e3, color="tab:red", alpha=0.3))
    for k in (0, 1, 2):
        p = result.positions(f"f{k}")[-1] * 1e3
        top.plot(p[:, 0], p[:, 1], "-", color=f"C{k}", lw=2, label=f"finger {k}")
        top.add_patch(plt.Circle(tuple(p[-1, :2]), R_FINGER * 1e3, fill=False, color=f"C{k}"))
    top.set(xlabel="x (mm)", ylabel="y (mm)", aspect="equal",
            title=f"from above, t = {t[-1]:g} s")
    top.legend(fontsize="small")
    save(fig, args.out, "snapshots.png")

    fig, ax = plt.subplots(figsize=(6, 3.5), layout="constrained")
    ax.plot(t, squeeze, label="squeeze per finger (sphere normal force / 3)")
    ax.plot(t, rod_rod, label="finger-finger contact force")
    ax.axhline(beam, color="k", ls="--", lw=0.8, label="beam theory at the full tension")
    ax.set(xlabel="t (s)", ylabel="force (N)", title="three fingers closing on a sphere")
    twin = ax.twinx()
    twin.plot(t, tension, color="tab:gray", lw=0.8)
    twin.set_ylabel("tendon tension (N)", color="tab:gray")
    ax.legend(fontsize="small", loc="center right")
    save(fig, args.out, "contact_force.png")

    write_summary(args.out, {
        "converged": bool(result.converged), "elements": elements, "dt_s": dt,
        "time_s": t.tolist(), "tension_N": tension.tolist(),
        "squeeze_N": squeeze.tolist(), "sphere_force_N": force.tolist(),
        "rod_rod_normal_force_N": rod_rod.tolist(),
        "max_penetration_m": penetration.tolist(),
        "max_penetration_over_radius": float(penetration.max() / R_FINGER),
        "final_squeeze_N": float(squeeze[-1]), "beam_squeeze_N": beam,
        "final_horizontal_over_squeeze": horizontal,
        "final_tip_radial_m": radial[-1].tolist(), "palm_max_displacement_m":
        float(np.abs(palm).max()), "tension_final_N": TENSION, "EI_Nm2": EI,
        "tendon_offset_m": OFFSET, "finger_radius_m": R_FINGER, "sphere_z_m": Z_SPHERE,
        "gap_m": GAP, "friction": FRICTION})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
