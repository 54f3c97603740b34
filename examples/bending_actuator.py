"""Silicone bending actuator for rehabilitation under a growing torque (the paper's Figs. 21-22).

    python examples/bending_actuator.py [--out out/bending_actuator] [--fast]

Scene: examples/scenes/bending_actuator.json. Cantilever, L = 0.15 m, solid semicircle
section r = 1 cm, silicone (rho 1080 kg/m^3, E 110 kPa, nu 0.5, G = E/3); tip torque
tau(t) = 0.002 t N m "about y" for 0 <= t <= 1 s (the paper).

Choices:
* **Bending axis: local y = the centroidal axis parallel to the flat side** (the
  section's diameter lies along local y, its flat side faces -z). This is the compliant
  axis, I_y = (pi/8 - 8/(9 pi)) r^4 = 1.098e-9 m^4, EI_y = 1.207e-4 N m^2: the quasi-static
  curl at t = 1 s is tau L / EI_y = 2.48 rad, and the actuator curls towards its flat side
  (tip to -z), like a soft actuator with a strain-limiting flat layer. (About the symmetry
  axis z it would be 0.69 rad.) The reference line is the centroid.
* The torque is a dead world-frame moment along y (world = local at the clamp; for
  planar bending about a principal axis dead and follower moments coincide).
* **No gravity** (not stated; the body's weight would sag it by ~0.9 m in small-deflection
  theory, so the motion is taken in a horizontal plane), no material damping.
* 10 helical elements (4 with --fast), consistent inertia, dt = 0.01 s, rho_inf = 0.9.

The first bending period (~1.5 s) is longer than the loading, so the motion is dynamic:
the actuator first lags behind the quasi-static arc of curvature tau(t)/EI_y (dashed in
the snapshots), then overshoots it (tip rotation ~2.86 rad at 1 s).
Printed checks: convergence, the motion stays in the x-z plane, tip rotation at 1 s
against the quasi-static 2.48 rad, and the work-energy balance.

Writes snapshots.png (Fig. 22 a-d, x-z plane), snapshots_3d.png (ribbons along local y),
tip_displacements.png, bending_actuator.gif (not with --fast) and summary.json.
"""
import json

import matplotlib.pyplot as plt
import numpy as np

import simsoft_jax as sj
from simsoft_jax import plotting

from _common import SCENES, parse_args, save, work_energy_balance, write_summary


def main():
    args = parse_args("bending_actuator", __doc__)
    scene = json.loads((SCENES / "bending_actuator.json").read_text())
    if args.fast:
        scene["rods"][0]["elements"] = 4
    result = sj.run(scene)
    rod = "actuator"
    time, p, R = result.time, result.positions(rod), result.rotations(rod)
    length = scene["rods"][0]["geometry"]["length"]
    rate = scene["loads"][0]["vector"][1] * scene["loads"][0]["profile"]["rate"]
    EI = float(result.model.stiffness[0, 4])
    tip_angle = np.unwrap(np.arctan2(R[:, -1, 0, 2], R[:, -1, 0, 0]))   # rotation about y
    quasi_static_final = rate * time[-1] * length / EI
    out_of_plane = float(np.abs(p[:, :, 1]).max() / length)
    twist = float(np.abs(R[:, :, 1, 1] - 1.0).max())   # local y stays along world y
    work, energy = work_energy_balance(result, scene, rod)
    balance = float(np.abs(work - energy).max() / np.abs(work).max())

    idx = [int(np.argmin(np.abs(time - t))) for t in (0.25, 0.5, 0.75, 1.0)]
    ps, Rs = plotting.sample_result(result, rod)
    s = np.linspace(0.0, length, 101)
    fig, ax = plt.subplots(figsize=(6.0, 5.0))
    colors = plt.colormaps["viridis"](np.linspace(0.0, 0.9, len(idx)))
    for i, color in zip(idx, colors):
        kappa = rate * time[i] / EI
        ax.plot(np.sin(kappa * s) / kappa, -(1.0 - np.cos(kappa * s)) / kappa, "--",
                color=color, lw=0.9)
        ax.plot(ps[i, :, 0], ps[i, :, 2], color=color, lw=2.5, label=f"t = {time[i]:.2f} s")
    ax.plot([], [], "k--", lw=0.9, label="quasi-static arc tau(t)/EI_y")
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("z [m]")
    ax.grid(alpha=0.3)
    ax.legend(fontsize="small")
    ax.set_title("Silicone bending actuator, tau = 0.002 t N m about y (the paper's Fig. 22)")
    save(fig, args.out, "snapshots.png")
    save(plotting.plot_configurations(ps[idx], Rs[idx],
                                      labels=[f"t = {time[i]:.2f} s" for i in idx],
                                      title="bending actuator: ribbons along local y"),
         args.out, "snapshots_3d.png")
    save(plotting.plot_result_tip(result, rod, title="actuator tip"),
         args.out, "tip_displacements.png")
    if not args.fast:
        print(f"wrote {plotting.animate_result(result, rod, args.out / 'bending_actuator.gif')}")

    elements = scene["rods"][0]["elements"]
    print(f"bending actuator ({elements} elements, EI_y = {EI:.4e} N m^2): converged = "
          f"{result.converged}, {result.newton_iterations} Newton iterations")
    print(f"t = 1 s: tip at {np.round(p[-1, -1], 5)} m, tip rotation about y "
          f"{tip_angle[-1]:.3f} rad (quasi-static {quasi_static_final:.3f} rad)")
    print(f"out of the x-z plane <= {out_of_plane:.1e} L, twist <= {twist:.1e}; work-energy "
          f"balance max |W - E| / max |W| = {balance:.2e} (W(1 s) = {work[-1]:.3e} J)")
    write_summary(args.out, {
        "elements": elements, "bending_axis": "local y (parallel to the flat side)",
        "EI_y_Nm2": EI, "length_m": length, "converged": result.converged,
        "t_end_s": float(time[-1]), "tip_final_m": p[-1, -1].tolist(),
        "tip_angle_final_rad": float(tip_angle[-1]),
        "quasi_static_angle_final_rad": quasi_static_final,
        "max_out_of_plane_rel": out_of_plane, "max_twist": twist,
        "work_final_J": float(work[-1]), "energy_balance_rel": balance})
    return 0 if result.converged else 1


if __name__ == "__main__":
    raise SystemExit(main())
