"""A spatial parallel continuum robot: six elastic legs clamped in a base, welded at the
top to a rigid plate (Stewart-platform layout): forward and inverse kinematics in statics,
and a dynamic move (bodies, joints, drives; custom actuation of the rest lengths).

    python examples/six_leg_parallel_robot.py [--out out/six_leg_parallel_robot] [--fast]

Robot (built here, no gravity): six straight legs 165 mm long (glass-fibre rods, diameter
2 mm, E = 40 GPa: EA = 1.26e5 N, shear stiffness 4.4e4 N, EI = 3.14e-2 N m^2, GJ =
2.51e-2 N m^2) from the base circle (radius 100 mm, points in pairs at 120 k +- 10 deg)
to the plate circle (radius 50 mm, 150 mm up, points at 120 k +- 50 deg), so each leg
leans sideways by 25 deg like a Stewart platform's. Each leg is clamped at the base along its own axis and welded to the
plate (a rigid body, 0.1 kg). A dead force F = (1, 0.5, -2) N acts on the plate at leg
0's attachment. 24 elements per leg (8 with --fast).

1. Forward kinematics (statics). The legs are actuated by their insertion lengths: a
   leg pushed further through its base clamp is a longer rod between the same clamp and
   the plate. The scene is built once, at the nominal lengths; another length is another
   stress-free shape of the leg's elements (the rest twists ``d0`` and lengths scaled by
   ``L / L_nominal``, :func:`length_actuation`, model arrays: no recompilation). The plate
   pose is solved for given length changes (mm) ``DELTAS``, in increments of at most
   0.1 mm, each solve starting from the last equilibrium (:func:`follow`).
2. Inverse kinematics: ``sj.solve_inverse`` with that actuation map (any differentiable
   ``actuate(model, u)`` will do) finds the six lengths that bring the plate to a target
   pose (translated by (3, -2, 5) mm and turned by 3 deg about (1, 1, 0)): the targets
   are the six legs' top nodes (the plate's six attachment points, which fix its pose).
   The pose is then checked on the plate body of a forward solve at those lengths.
3. Dynamics: a rest length cannot change during a run, so the move is made by six
   prismatic base actuators instead: each leg's base node is a drive pushed along the
   leg's axis by the inverse solution's length change (a smoothstep over 0.25 s, held to
   0.6 s; legs damped by mass-proportional damping 40/s). A sliding drive
   (``slides_along``) leaves the slide free, so it cannot push; these drives prescribe
   the whole base pose. Pushing a clamp up by delta is not the same as inserting delta
   more leg (the clamp point moves), so the move ends near, not at, the target pose; the
   check is that the plate settles at the static equilibrium of the clamps moved by the
   same strokes (held nodes sit at their start frames ``p0`` in statics).

Writes shapes.png (legs and plate at home, forward and inverse solutions, 3-D and top
view), move.png (the plate's position and tilt against time during the move, with the
static end pose) and summary.json (geometry, stiffness, poses, checks).
"""
import numpy as np

import simsoft_jax as sj
from simsoft_jax.math import lie_np
from simsoft_jax.solvers import statics

from _common import parse_args, save, write_summary

R_BASE, R_PLATE, HEIGHT, BETA, ALPHA = 0.1, 0.05, 0.15, 10.0, 50.0
E, NU, DIAMETER, DENSITY = 40e9, 0.25, 2e-3, 2000.0
PLATE_MASS, PLATE_INERTIA = 0.1, (9e-5, 9e-5, 1.8e-4)
FORCE = (1.0, 0.5, -2.0)                                    # N, on the plate at leg 0's top
DELTAS = (3.0, -1.5, 1.5, 3.0, -1.5, -3.0)                  # mm, forward kinematics
TARGET_SHIFT, TARGET_AXIS, TARGET_ANGLE = (0.003, -0.002, 0.005), (1.0, 1.0, 0.0), 3.0
T_MOVE, T_END, DAMPING = 0.25, 0.6, 40.0
LENGTH_STEP = 1e-4                                          # m, statics' length increments


def section() -> dict:
    """Stiffness (EA, GAy, GAz, GJ, EIy, EIz) and inertia per length of the legs' solid
    circle (shear coefficient 6(1 + nu)/(7 + 6 nu), Cowper)."""
    G, A, I = E / (2 * (1 + NU)), np.pi * DIAMETER**2 / 4, np.pi * DIAMETER**4 / 64
    k = 6 * (1 + NU) / (7 + 6 * NU)
    return ({"EA": E * A, "GAy": k * G * A, "GAz": k * G * A, "GJ": 2 * G * I,
             "EIy": E * I, "EIz": E * I},
            {"rhoA": DENSITY * A, "rhoJ": 2 * DENSITY * I, "rhoIy": DENSITY * I,
             "rhoIz": DENSITY * I})


def geometry():
    """Base points (6,3), plate attachment offsets from the plate centre (6,3), leg
    rotation vectors (6,3) taking the local x axis onto the leg's axis, nominal lengths
    (6,) (m). Leg j = 2 k + i (i = 0, 1) runs from the base at 120 k -+ BETA deg to the
    plate at 120 k -+ ALPHA deg."""
    sign = np.array([-1.0, 1.0] * 3)
    k = np.repeat(np.arange(3), 2)
    base_a = np.radians(120.0 * k + sign * BETA)
    plate_a = np.radians(120.0 * k + sign * ALPHA)
    base = R_BASE * np.stack([np.cos(base_a), np.sin(base_a), np.zeros(6)], 1)
    offset = R_PLATE * np.stack([np.cos(plate_a), np.sin(plate_a), np.zeros(6)], 1)
    axis = offset + [0.0, 0.0, HEIGHT] - base
    lengths = np.linalg.norm(axis, axis=1)
    axis /= lengths[:, None]
    e1 = np.array([1.0, 0.0, 0.0])
    rotvec = np.array([np.cross(e1, a) / np.linalg.norm(np.cross(e1, a))
                       * np.arccos(np.clip(a[0], -1.0, 1.0)) for a in axis])
    return base, offset, rotvec, lengths


def robot(elements: int, solver: dict, strokes=None, times=None) -> dict:
    """The scene: legs ``leg0``..``leg5``, the plate, six welds, the force on the plate.
    Without ``strokes`` the legs are clamped at the base; with them each base node is a
    drive pushed along its leg's axis by ``strokes[j] * scale`` (m) at ``times`` (s),
    ``scale`` a smoothstep from 0 to 1 over the times."""
    base, offset, rotvec, lengths = geometry()
    stiffness, inertia = section()
    rods, constraints = [], []
    for j in range(6):
        rods.append({"name": f"leg{j}", "elements": elements,
                     "geometry": {"kind": "straight", "length": float(lengths[j])},
                     "base": {"position": base[j].tolist(), "rotation": rotvec[j].tolist()},
                     "stiffness": stiffness, "inertia": inertia,
                     "material": {"E": E, "nu": NU, "density": DENSITY,
                                  "mass_damping": DAMPING}})
        if strokes is None:
            constraints.append({"kind": "clamp", "rod": f"leg{j}", "node": 0})
        else:
            x = np.clip(np.asarray(times) / T_MOVE, 0.0, 1.0)
            scale = x * x * (3.0 - 2.0 * x)
            axis = lie_np.exp_so3(rotvec[j])[:, 0]
            constraints.append({"kind": "drive", "rod": f"leg{j}", "node": 0,
                                "times": list(map(float, times)),
                                "displacement": [(s * strokes[j] * axis).tolist()
                                                 for s in scale]})
    return {"name": "six_leg_parallel_robot", "solver": solver, "rods": rods,
            "constraints": constraints,
            "bodies": [{"name": "plate", "mass": PLATE_MASS, "position": [0.0, 0.0, HEIGHT],
                        "inertia": np.diag(PLATE_INERTIA).tolist()}],
            "joints": [{"kind": "weld", "a": {"rod": f"leg{j}", "node": -1},
                        "b": {"body": "plate", "offset": offset[j].tolist()}}
                       for j in range(6)],
            "loads": [{"kind": "force", "rod": "leg0", "node": -1, "vector": list(FORCE),
                       "frame": "world"}]}


def length_actuation(model):
    """``actuate(model, u)``: the six legs' lengths u (6,) (m). A leg of length ``u_j``
    has the stress-free twists ``d0`` and element lengths of the nominal leg scaled by
    ``u_j / L_j`` (straight legs: uniform stretch of the reference); other arrays kept."""
    import jax.numpy as jnp

    s = model.structure
    d0, length = model.d0, model.length
    leg = np.full(length.shape[0], -1)
    nominal = np.zeros(6)
    for j in range(6):
        info = s.rod(f"leg{j}")
        span = slice(info.first_element, info.first_element + info.elements)
        leg[span] = j
        nominal[j] = float(np.sum(np.asarray(length)[span]))
    if np.any(leg < 0):
        raise ValueError("model: expected only the six legs' elements")

    def actuate(model, u):
        scale = jnp.asarray(u)[leg] / nominal[leg]
        return model.replace(d0=d0 * scale[:, None], length=length * scale)

    actuate.size = 6
    return actuate


def follow(model, actuate, settings, start, start_lengths, lengths):
    """Static equilibrium at leg ``lengths`` (6,) (m) reached from the equilibrium
    ``start`` at ``start_lengths`` in equal length increments of at most ``LENGTH_STEP``,
    each solve starting from the previous equilibrium (a length change is no load, so the
    solver's load continuation does not divide it; one Newton solve from the straight legs
    fails once the lengths change by more than a few tenths of a millimetre, the plate
    having to move by several). Returns the last Equilibrium and the model that starts
    there."""
    steps = max(1, int(np.ceil(np.abs(lengths - start_lengths).max() / LENGTH_STEP)))
    eq = start
    for x in np.linspace(0.0, 1.0, steps + 1)[1:]:
        model = model.replace(R0=eq.R, p0=eq.p)
        eq = sj.solve_static(actuate(model, start_lengths + x * (lengths - start_lengths)),
                             settings)
        if not bool(eq.converged):
            break
    return eq, model.replace(R0=eq.R, p0=eq.p)


def plate_pose(model, eq):
    """Plate position (3,) and rotation (3,3) of a static Equilibrium."""
    node = dict(model.structure.bodies)["plate"]
    return np.asarray(eq.p)[node], np.asarray(eq.R)[node]


def rotation_angle(R) -> float:
    """Angle (rad) of a rotation matrix: atan2(|axial vector of (R - R^T)/2|, (tr R - 1)/2)
    (accurate also for small angles, unlike arccos of the trace)."""
    w = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]]) / 2.0
    return float(np.arctan2(np.linalg.norm(w), (np.trace(R) - 1.0) / 2.0))


def tip_gap(model, eq, offset) -> float:
    """Largest distance (m) between a leg's top node and its plate attachment point."""
    p, R = plate_pose(model, eq)
    tops = np.stack([np.asarray(eq.p)[model.structure.rod(f"leg{j}").first_node
                                      + model.structure.rod(f"leg{j}").nodes - 1]
                     for j in range(6)])
    return float(np.abs(tops - (p + offset @ R.T)).max())


def main():
    args = parse_args("six_leg_parallel_robot", __doc__)
    elements = 8 if args.fast else 24
    base, offset, rotvec, nominal = geometry()
    scene = sj.Scene.from_dict(robot(elements, {"kind": "static", "load_steps": 2}))
    model = sj.build_model(scene)
    settings = statics.settings_from_scene(scene.solver)
    actuate = length_actuation(model)
    lengths = nominal + np.asarray(DELTAS) * 1e-3

    home = sj.solve_static(actuate(model, nominal), settings)
    forward, _ = follow(model, actuate, settings, home, nominal, lengths)
    for eq, what in ((home, "home"), (forward, "forward kinematics")):
        if not bool(eq.converged):
            print(f"{what}: {eq.message()}")
            return 1
    p_home, R_home = plate_pose(model, home)
    p_fk, R_fk = plate_pose(model, forward)
    print(f"home (nominal lengths {np.round(nominal * 1e3, 3)} mm, force {FORCE} N): plate "
          f"at {np.round(p_home * 1e3, 4)} mm, tilted {np.degrees(rotation_angle(R_home)):.4f}"
          f" deg")
    print(f"forward kinematics, length changes {DELTAS} mm: plate at "
          f"{np.round(p_fk * 1e3, 4)} mm, turned {np.degrees(rotation_angle(R_fk)):.4f} deg")

    R_target = lie_np.exp_so3(np.radians(TARGET_ANGLE) * np.asarray(TARGET_AXIS)
                              / np.linalg.norm(TARGET_AXIS))
    p_target = np.array([0.0, 0.0, HEIGHT]) + np.asarray(TARGET_SHIFT)
    tops = p_target + offset @ R_target.T
    # start: the lengths of straight legs to the target (rigid-leg kinematics), the solves
    # starting from the equilibrium there
    guess = np.linalg.norm(tops - base, axis=1)
    near, warm = follow(model, actuate, settings, home, nominal, guess)
    if not bool(near.converged):
        print(f"inverse kinematics, start point: {near.message()}")
        return 1
    inverse = sj.solve_inverse(warm, actuate, [(f"leg{j}", -1) for j in range(6)], tops,
                               guess, tolerance=1e-9, settings=settings)
    u_ik = np.asarray(inverse.u[0])
    check = sj.solve_static(actuate(warm, u_ik), settings)
    p_ik, R_ik = plate_pose(model, check)
    ik_position_error = float(np.linalg.norm(p_ik - p_target))
    ik_angle_error = rotation_angle(R_target.T @ R_ik)
    print(f"inverse kinematics: {inverse.messages[0]}; length changes "
          f"{np.round((u_ik - nominal) * 1e3, 4)} mm (straight legs: "
          f"{np.round((guess - nominal) * 1e3, 4)} mm); the plate body of a forward solve at "
          f"them is {ik_position_error:.1e} m and {ik_angle_error:.1e} rad from the target "
          f"({inverse.iterations[0]} iterations, {inverse.seconds:.1f} s)")

    strokes = u_ik - nominal
    times = np.linspace(0.0, T_MOVE, 11)
    dt = 0.01 if args.fast else 0.005
    moving = sj.run(robot(elements, {"kind": "dynamic", "dt": dt, "t_end": T_END,
                                     "rho_inf": 0.8}, strokes, times))
    if not moving.converged:
        print(f"dynamics: {moving.message}")
        return 1
    t = np.asarray(moving.time)
    p_dyn, R_dyn = moving.body_pose("plate")
    # the static equilibrium with the clamps moved by the strokes (p0 of the base nodes)
    p0 = np.asarray(model.p0).copy()
    for j in range(6):
        p0[model.structure.rod(f"leg{j}").first_node] += strokes[j] * lie_np.exp_so3(
            rotvec[j])[:, 0]
    carriage = sj.solve_static(model.replace(p0=p0), settings)
    p_st, R_st = plate_pose(model, carriage)
    settle_position = float(np.linalg.norm(p_dyn[-1] - p_st))
    settle_angle = rotation_angle(R_st.T @ R_dyn[-1])
    carriage_to_target = float(np.linalg.norm(p_st - p_target))
    print(f"dynamics ({elements} elements per leg, dt = {dt * 1e3:g} ms): at t = {t[-1]:g} s "
          f"the plate is {settle_position:.1e} m and {settle_angle:.1e} rad from the static "
          f"equilibrium of the moved clamps, which is {carriage_to_target * 1e3:.3f} mm from "
          f"the target (pushed clamps, not inserted legs)")

    gaps = [tip_gap(model, eq, offset) for eq in (home, forward, check, carriage)]
    shapes = {what: [np.asarray(eq.p)[model.structure.rod(f"leg{j}").first_node:
                                      model.structure.rod(f"leg{j}").first_node
                                      + model.structure.rod(f"leg{j}").nodes].tolist()
                     for j in range(6)]
              for what, eq in (("home", home), ("forward", forward), ("inverse", check))}
    plot_shapes(args.out, shapes, {"home": (p_home, R_home), "forward": (p_fk, R_fk),
                                   "inverse": (p_ik, R_ik)}, offset)
    plot_move(args.out, t, p_dyn, R_dyn, p_st, R_st, p_target)
    write_summary(args.out, {
        "converged": True, "elements": elements, "dt_s": dt,
        "base_points_m": base.tolist(), "plate_offsets_m": offset.tolist(),
        "leg_rotation_vectors": rotvec.tolist(), "nominal_lengths_m": nominal.tolist(),
        "plate_height_m": HEIGHT, "stiffness": section()[0], "force_N": list(FORCE),
        "home": {"plate_position_m": p_home.tolist(), "plate_rotation": R_home.tolist()},
        "forward": {"lengths_m": lengths.tolist(), "plate_position_m": p_fk.tolist(),
                    "plate_rotation": R_fk.tolist()},
        "inverse": {"target_position_m": p_target.tolist(),
                    "target_rotation": R_target.tolist(), "lengths_m": u_ik.tolist(),
                    "reached": bool(inverse.reached[0]),
                    "relative_error": float(inverse.relative_error[0]),
                    "plate_position_error_m": ik_position_error,
                    "plate_angle_error_rad": ik_angle_error},
        "dynamic": {"strokes_m": strokes.tolist(), "time_s": t.tolist(),
                    "plate_position_m": p_dyn.tolist(),
                    "static_plate_position_m": p_st.tolist(),
                    "settle_position_error_m": settle_position,
                    "settle_angle_error_rad": settle_angle,
                    "static_to_target_m": carriage_to_target},
        "max_weld_gap_m": max(gaps), "shapes_m": shapes})
    return 0


def plot_shapes(out, shapes, poses, offset):
    import matplotlib.pyplot as plt

    fig = plt.figure(figsize=(10, 4.5), layout="constrained")
    ax = fig.add_subplot(1, 2, 1, projection="3d")
    top = fig.add_subplot(1, 2, 2)
    ring = np.r_[np.arange(6), 0]
    for c, (what, legs) in enumerate(shapes.items()):
        p, R = poses[what]
        corners = (p + offset @ R.T)[ring] * 1e3
        for j, leg in enumerate(legs):
            q = np.asarray(leg) * 1e3
            ax.plot(q[:, 0], q[:, 1], q[:, 2], "-", color=f"C{c}", lw=1,
                    label=what if j == 0 else None)
            top.plot(q[:, 0], q[:, 1], "-", color=f"C{c}", lw=1)
        ax.plot(corners[:, 0], corners[:, 1], corners[:, 2], "-", color=f"C{c}", lw=3)
        top.plot(corners[:, 0], corners[:, 1], "-", color=f"C{c}", lw=3,
                 label=f"{what}: plate at ({', '.join(f'{v:.1f}' for v in p * 1e3)}) mm")
    ax.set(xlabel="x (mm)", ylabel="y (mm)", zlabel="z (mm)", title="legs and plate")
    ax.legend(fontsize="small")
    top.set(xlabel="x (mm)", ylabel="y (mm)", aspect="equal", title="from above")
    top.legend(fontsize="small", loc="lower left")
    save(fig, out, "shapes.png")


def plot_move(out, t, p, R, p_static, R_static, p_target):
    import matplotlib.pyplot as plt

    fig, (ax, tilt) = plt.subplots(1, 2, figsize=(10, 3.5), layout="constrained")
    start = p[0]
    for k, name in enumerate("xyz"):
        ax.plot(t, (p[:, k] - start[k]) * 1e3, color=f"C{k}", label=f"plate {name}")
        ax.axhline((p_static[k] - start[k]) * 1e3, color=f"C{k}", ls="--", lw=0.8)
        ax.plot(t[-1], (p_target[k] - start[k]) * 1e3, "x", color=f"C{k}")
    ax.set(xlabel="t (s)", ylabel="displacement from the start (mm)",
           title="plate moved by the base drives (--: static end pose, x: target)")
    ax.legend(fontsize="small")
    angle = [np.degrees(rotation_angle(R[0].T @ Ri)) for Ri in R]
    tilt.plot(t, angle)
    tilt.axhline(np.degrees(rotation_angle(R[0].T @ R_static)), color="k", ls="--", lw=0.8)
    tilt.set(xlabel="t (s)", ylabel="rotation from the start (deg)", title="plate rotation")
    save(fig, out, "move.png")


if __name__ == "__main__":
    raise SystemExit(main())
