"""The Magellan catheter of examples/magellan_catheter.py driven by tendons instead of
prescribed torques (the paper's Figs. 19-20), side by side with the torque version.

    python examples/magellan_tendons.py [--out out/magellan_tendons] [--fast]

Same catheter (spring steel tubes: guide 90 mm, d_e 3.48 / d_i 2.54 mm; leader 30 mm,
d_e 2.13 / d_i 1.00 mm; clamped at the origin along world x; dt = 0.01 s, consistent
inertia, rho_inf = 0.5; 12 + 4 elements, 3 + 1 with --fast). Instead of the torques
tau_2 (end of the guide) and tau_3 (tip), two tendons in the tube walls, both pulled with
tensions growing linearly in time (``profile = {kind = "linear", rate = 1}``):
* ``guide``: from the base to the guide's end (node 12 of 16) at +y, r_g = 1.505 mm
  (the middle of the guide's wall), tension T_g = 40 N m / r_g at t = 1 s;
* ``leader``: from the base to the tip at -y, r_l = 0.7825 mm (the middle of the
  leader's wall, kept through the guide), tension T_l = 15 N m / r_l at t = 1 s.
A tendon at a constant offset loads each section with its tension along the axis and the
moment ``T r`` about the section's z axis, so at t = 1 s the guide carries
``T_g r_g - T_l r_l = 25 N m`` and the leader ``-15 N m``: the z components of the
torque version's net moments (``tau_2 + tau_3`` on the guide, ``tau_3`` on the leader).
The differences: tendon moments turn with the sections (the torques are world-fixed
vectors whose x and y components also twist the catheter and bend it out of plane), and
tendons compress the tubes (``T / EA``: 3.5 % on the guide at these tensions, a
consequence of the example's N m units, see magellan_catheter.py).

Check: the catheter is light and stiff, so at t = 1 s it sits at the quasi-static
equilibrium of the current tensions, which with tendons at constant offsets is exact:
two arcs, of curvature ``M / EI`` per reference length and axial strain ``-N / EA`` on
each segment (N the sum of the tensions crossing it); the printed error is
``|tip(1 s) - tip_two_arcs| / L``.

Writes side_by_side.png (both catheters at t = 0.25, 0.5, 0.75, 1 s), summary.json.
"""
import json

import numpy as np

import simsoft_jax as sj
from simsoft_jax import plotting

from _common import SCENES, parse_args, save, write_summary

GUIDE_LENGTH, LEADER_LENGTH = 0.09, 0.03
R_GUIDE = (3.48e-3 + 2.54e-3) / 4          # m, middle of the guide tube's wall
R_LEADER = (2.13e-3 + 1.00e-3) / 4         # m, middle of the leader tube's wall
M_GUIDE_END, M_TIP = 40.0, 15.0            # N m at t = 1 s: T_g r_g and T_l r_l


def scenes(fast: bool):
    """The torque scene (as examples/magellan_catheter.py) and its tendon version."""
    torque = json.loads((SCENES / "magellan_catheter.json").read_text())
    rod = torque["rods"][0]
    if fast:
        rod["segments"][0]["elements"], rod["segments"][1]["elements"] = 3, 1
        rod["elements"] = 4
    guide_end = rod["segments"][0]["elements"]
    tendon = json.loads(json.dumps(torque))
    tendon["name"] = "magellan_tendons"
    tendon["loads"] = []
    linear = {"kind": "linear", "rate": 1.0}
    tendon["tendons"] = [
        {"name": "guide", "rod": "catheter", "from_node": 0, "to_node": guide_end,
         "offset": [R_GUIDE, 0.0], "tension": M_GUIDE_END / R_GUIDE, "profile": linear},
        {"name": "leader", "rod": "catheter", "from_node": 0, "to_node": -1,
         "offset": [-R_LEADER, 0.0], "tension": M_TIP / R_LEADER, "profile": linear}]
    return torque, tendon


def two_arcs(pieces):
    """Tip of a clamped rod along x made of planar arcs in the x-y plane:
    ``pieces`` = [(length, curvature per reference length, axial strain), ...]."""
    p, angle = np.zeros(2), 0.0
    for length, kappa, eps in pieces:
        chord = np.array([np.sin(kappa * length), 1.0 - np.cos(kappa * length)]) / kappa
        c, s = np.cos(angle), np.sin(angle)
        p = p + (1.0 + eps) * np.array([[c, -s], [s, c]]) @ chord
        angle += kappa * length
    return np.array([p[0], p[1], 0.0])


def main():
    args = parse_args("magellan_tendons", __doc__)
    torque_scene, tendon_scene = scenes(args.fast)
    torque, tendons = sj.run(torque_scene), sj.run(tendon_scene)
    K = np.asarray(tendons.model.stiffness)
    (EA_g, EI_g), (EA_l, EI_l) = (K[0, 0], K[0, 5]), (K[-1, 0], K[-1, 5])
    T_g, T_l = M_GUIDE_END / R_GUIDE, M_TIP / R_LEADER
    reference = two_arcs([(GUIDE_LENGTH, (T_g * R_GUIDE - T_l * R_LEADER) / EI_g,
                           -(T_g + T_l) / EA_g),
                          (LEADER_LENGTH, -T_l * R_LEADER / EI_l, -T_l / EA_l)])
    length = GUIDE_LENGTH + LEADER_LENGTH
    tip_t, tip_m = tendons.positions("catheter")[-1, -1], torque.positions("catheter")[-1, -1]
    error = float(np.linalg.norm(tip_t - reference) / length)
    print(f"tendons at t = 1 s: T_guide = {tendons.tendon_tension('guide')[-1]:.0f} N, "
          f"T_leader = {tendons.tendon_tension('leader')[-1]:.0f} N: the tensions that "
          f"give the torque version's {M_GUIDE_END:g} and {M_TIP:g} N m at "
          f"{1e3 * R_GUIDE:.2f} and {1e3 * R_LEADER:.2f} mm from the axis, far beyond a real "
          "catheter's, as those torques are (see magellan_catheter.py); "
          f"converged {tendons.converged}, {tendons.newton_iterations} Newton iterations")
    print(f"t = 1 s tip: tendons {np.round(tip_t, 5)} m (two arcs {np.round(reference, 5)} m, "
          f"|tip - ref| / L = {error:.1e}); torques {np.round(tip_m, 5)} m")

    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, 2, figsize=(9, 3.6), sharex=True, sharey=True)
    for ax, result, title in ((axes[0], torque, "prescribed torques (the paper)"),
                              (axes[1], tendons, "tendons")):
        time, (p, _) = result.time, plotting.sample_result(result, "catheter")
        for t in (0.25, 0.5, 0.75, 1.0):     # the helical interpolation between nodes
            i = int(np.argmin(np.abs(time - t)))
            ax.plot(p[i, :, 0] * 1e3, p[i, :, 1] * 1e3, "-", label=f"t = {time[i]:.2f} s")
        ax.set(title=title, xlabel="x (mm)", aspect="equal")
    axes[0].set_ylabel("y (mm)")
    axes[1].legend(fontsize="small")
    save(fig, args.out, "side_by_side.png")
    write_summary(args.out, {
        "converged": bool(torque.converged and tendons.converged),
        "tension_guide_N": T_g, "tension_leader_N": T_l, "offset_guide_m": R_GUIDE,
        "offset_leader_m": R_LEADER, "tip_tendons_m": tip_t.tolist(),
        "tip_two_arcs_m": reference.tolist(), "tip_torques_m": tip_m.tolist(),
        "quasi_static_error_rel": error})
    return 0 if torque.converged and tendons.converged else 1


if __name__ == "__main__":
    raise SystemExit(main())
