"""Magellan 10Fr robotic catheter, guide + leader actuated by end torques (the paper's Figs. 19-20).

    python examples/magellan_catheter.py [--out out/magellan_catheter] [--fast]

Scene: examples/scenes/magellan_catheter.json. One rod with two segments (the paper: "two
consecutive elements, 1-2 the guide and 2-3 the leader"), spring steel (rho 7850 kg/m^3,
E 210 GPa, nu 0.3), tube sections: guide d_e = 3.48 mm, d_i = 2.54 mm (EI = 1.083 N m^2,
GJ = 0.833 N m^2); leader d_e = 2.13 mm, d_i = 1.00 mm (EI = 0.202 N m^2, GJ = 0.155 N m^2).
Torques for 0 <= t <= 1 s: at the end of the guide (point 2) tau_2 = (0.4, 4, 40) t and at
the tip (point 3) tau_3 = (-0.15, -1.5, -15) t.

Choices (the paper gives no lengths):
* **Units: N m, as printed.** Read as N mm (a realistic tendon torque) they would bend
  these steel tubes by less than 0.01 rad, nothing like the paper's snapshots; in N m
  the catheter curls visibly, as in Fig. 20.
* **Lengths: guide 90 mm, leader 30 mm** (a short "minimal extension" of the leader,
  consistent with the figure's proportions). At t = 1 s the net moment bends the guide by
  about (40 - 15) * 0.09 / 1.083 = 2.1 rad about z and the leader back by
  15 * 0.03 / 0.202 = 2.2 rad; the x and y components add torsion and out-of-plane bending.
* The catheter starts straight along world x, clamped at the origin with its section frame
  equal to the world frame; the torques are dead (world-frame) vectors; no gravity.
* Mesh: the paper uses one element per segment; a segment turning by more than ~pi needs
  more: 12 + 4 elements of 7.5 mm (3 + 1 with --fast). dt = 0.01 s,
  consistent inertia, rho_inf = 0.5: the bending modes of this light steel catheter
  have periods of a few ms, below the step, and stronger numerical damping of them lets
  Newton converge in ~5 iterations per step (with rho_inf = 0.9 nearly every step is
  sub-stepped, at ~20 iterations per step; the tip at 1 s differs by < 1e-4 L).

Check: the catheter is light and stiff (first bending period ~ 5 ms), so it follows the
quasi-static equilibrium of the current torques. With end moments only, the internal
force is zero and the internal moment is known in world coordinates on each segment
(tau_2 + tau_3 on the guide, tau_3 on the leader), so the continuum rod solves an
initial-value problem, R' = R (C^-1 R^T m)^, p' = R e_1, integrated here with RK4; the
printed error is |tip(1 s) - tip_quasi-static| / L.

Writes snapshots.png (Fig. 20 a-d: t = 0.25, 0.5, 0.75, 1 s, ribbons along local y show
the torsion), tip_displacements.png, catheter.gif (not with --fast) and summary.json.
"""
import json

import numpy as np

import simsoft_jax as sj
from simsoft_jax import plotting

from _common import SCENES, parse_args, save, write_summary

GUIDE_LENGTH, LEADER_LENGTH = 0.09, 0.03


def hat(w):
    return np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])


def quasi_static_tip(pieces, steps=400):
    """Tip position of the clamped continuum rod (along x at the origin) under end moments
    only: ``pieces`` = [(length, (GJ, EI_y, EI_z), world moment m), ...] from the base.
    RK4 on R' = R hat(C^-1 R^T m), p' = R e_1 (no force: no shear, no stretch)."""
    R, p = np.eye(3), np.zeros(3)
    for length, compliance_diag, m in pieces:
        c = 1.0 / np.asarray(compliance_diag, float)
        h = length / steps

        def rate(Rk):
            return Rk @ hat(c * (Rk.T @ m)), Rk[:, 0]

        for _ in range(steps):
            k1 = rate(R)
            k2 = rate(R + 0.5 * h * k1[0])
            k3 = rate(R + 0.5 * h * k2[0])
            k4 = rate(R + h * k3[0])
            p = p + h / 6 * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1])
            R = R + h / 6 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0])
            u, _, vt = np.linalg.svd(R)       # back onto SO(3)
            R = u @ vt
    return p


def main():
    args = parse_args("magellan_catheter", __doc__)
    scene = json.loads((SCENES / "magellan_catheter.json").read_text())
    rod = scene["rods"][0]
    if args.fast:
        rod["segments"][0]["elements"], rod["segments"][1]["elements"] = 3, 1
        rod["elements"] = 4
    result = sj.run(scene)
    p = result.positions("catheter")
    time = result.time
    junction = rod["segments"][0]["elements"]
    tau2 = np.asarray(scene["loads"][0]["vector"]) * time[-1]
    tau3 = np.asarray(scene["loads"][1]["vector"]) * time[-1]
    K = np.asarray(result.model.stiffness)
    guide_c, leader_c = K[0, 3:], K[-1, 3:]
    reference = quasi_static_tip([(GUIDE_LENGTH, guide_c, tau2 + tau3),
                                  (LEADER_LENGTH, leader_c, tau3)])
    length = GUIDE_LENGTH + LEADER_LENGTH
    error = float(np.linalg.norm(p[-1, -1] - reference) / length)
    R = result.rotations("catheter")
    # rotation angles at t = 1 s: of the guide's end relative to the base and of the tip
    # relative to the guide's end
    angle = lambda Q: float(np.arccos(np.clip((np.trace(Q) - 1.0) / 2.0, -1.0, 1.0)))  # noqa: E731
    guide_turn = angle(R[-1, junction])
    leader_turn = angle(R[-1, junction].T @ R[-1, -1])

    idx = [int(np.argmin(np.abs(time - t))) for t in (0.25, 0.5, 0.75, 1.0)]
    ps, Rs = plotting.sample_result(result, "catheter")
    fig = plotting.plot_configurations(
        ps[idx], Rs[idx], labels=[f"t = {time[i]:.2f} s" for i in idx],
        title="Magellan catheter: guide 90 mm + leader 30 mm (the paper's Fig. 20)")
    ax = fig.axes[0]
    ax.scatter(*p[idx][:, junction].T, color="k", s=12, label="guide end (2)")
    ax.legend(fontsize="small", loc="upper left")
    save(fig, args.out, "snapshots.png")
    save(plotting.plot_result_tip(result, "catheter", title="catheter tip (point 3)"),
         args.out, "tip_displacements.png")
    if not args.fast:
        print(f"wrote {plotting.animate_result(result, 'catheter', args.out / 'catheter.gif')}")

    print(f"Magellan catheter (units N m, guide {GUIDE_LENGTH * 1e3:g} mm + leader "
          f"{LEADER_LENGTH * 1e3:g} mm, {rod['elements']} elements): converged = "
          f"{result.converged}, {result.newton_iterations} Newton iterations")
    print(f"t = 1 s: guide end at {np.round(p[-1, junction], 5)} m turned by "
          f"{guide_turn:.3f} rad; tip at {np.round(p[-1, -1], 5)} m, leader turned by "
          f"{leader_turn:.3f} rad relative to the guide end")
    print(f"quasi-static continuum tip {np.round(reference, 5)} m: |tip - ref| / L = {error:.2e}")
    write_summary(args.out, {
        "units": "N m", "guide_length_m": GUIDE_LENGTH, "leader_length_m": LEADER_LENGTH,
        "elements": [rod["segments"][0]["elements"], rod["segments"][1]["elements"]],
        "converged": result.converged, "t_end_s": float(time[-1]),
        "tau2_final_Nm": tau2.tolist(), "tau3_final_Nm": tau3.tolist(),
        "tip_final_m": p[-1, -1].tolist(), "junction_final_m": p[-1, junction].tolist(),
        "quasi_static_tip_m": reference.tolist(), "quasi_static_error_rel": error,
        "guide_turn_rad": guide_turn, "leader_turn_rad": leader_turn})
    return 0 if result.converged else 1


if __name__ == "__main__":
    raise SystemExit(main())
