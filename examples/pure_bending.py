"""Pure bending of a cantilever under five tip torques (the paper's Fig. 9, eqs. 83-91).

    python examples/pure_bending.py [--out out/pure_bending] [--fast]

Set-up (the paper's "Pure bending"): straight rod, L = 1 m, EI_y = 1 N m^2, clamped at s = 0
with its section frame equal to the world frame, tip moment tau e_y (world y = local y;
for bending about a principal axis a dead and a follower moment coincide) with
tau = 1, 2, 3, 4, 5 N m. The paper gives only EI_y and L; the other constants are the
synthetic arm's (EA = GA = 1e3 N, GJ = EI_z = 1 N m^2; they play no role because the
internal force is zero). Exact solution: constant curvature
kappa = tau / EI_y, p(s) = (sin(kappa s)/kappa, 0, -(1 - cos(kappa s))/kappa),
R(s) = R_y(kappa s): at tau = 2 pi the rod would close into a full circle.

The helical element reproduces constant strain exactly, so every node *and* the helical
interpolation between nodes (the paper's eq. 27) lie on the exact arc up to round-off, with any
number of elements whose relative rotation stays below pi (5 elements by default, 3 with
--fast). Printed and saved: the largest node-position error over all nodes and torques
relative to L, the largest rotation error, and the largest distance of the interpolated
curve from the exact arc.

Writes pure_bending.png (x-z plane, like Fig. 9), pure_bending_3d.png (3-D, ribbons
spanned by the local y axis) and summary.json.
"""
import matplotlib.pyplot as plt
import numpy as np

import simsoft_jax as sj
from simsoft_jax import plotting

from _common import parse_args, save, write_summary

L, EI = 1.0, 1.0
TORQUES = (1.0, 2.0, 3.0, 4.0, 5.0)   # N m, the paper's Fig. 9


def scene(torque: float, elements: int) -> dict:
    return {
        "name": "pure_bending",
        "solver": {"kind": "static"},
        "rods": [{"name": "arm",
                  "stiffness": {"EA": 1e3, "GAy": 1e3, "GAz": 1e3, "GJ": 1.0, "EIy": EI,
                                "EIz": 1.0},
                  "inertia": {"rhoA": 0.1, "rhoJ": 2.0, "rhoIy": 1.0, "rhoIz": 1.0},
                  "elements": elements, "geometry": {"kind": "straight", "length": L}}],
        "constraints": [{"kind": "clamp", "rod": "arm", "node": 0}],
        "loads": [{"kind": "moment", "rod": "arm", "node": -1, "vector": [0.0, torque, 0.0],
                   "frame": "world"}],
    }


def exact_arc(torque: float, s):
    """Exact frames of pure bending: positions (M, 3), rotations (M, 3, 3)."""
    k = torque / EI
    c, sn = np.cos(k * s), np.sin(k * s)
    p = np.stack([sn / k, 0.0 * s, -(1.0 - c) / k], axis=1)
    R = np.zeros((len(s), 3, 3))
    R[:, 0, 0], R[:, 0, 2], R[:, 1, 1], R[:, 2, 0], R[:, 2, 2] = c, sn, 1.0, -sn, c
    return p, R


def main():
    args = parse_args("pure_bending", __doc__)
    elements = 3 if args.fast else 5
    nodes_s = np.linspace(0.0, L, elements + 1)
    fine_s = np.linspace(0.0, L, 201)
    results = [sj.run(scene(tau, elements)) for tau in TORQUES]   # one compilation
    pos_err = rot_err = curve_err = 0.0
    shapes, frames, exact_curves, tips = [], [], [], []
    for tau, res in zip(TORQUES, results):
        p, R = res.positions("arm"), res.rotations("arm")
        p_ex, R_ex = exact_arc(tau, nodes_s)
        pos_err = max(pos_err, np.linalg.norm(p - p_ex, axis=1).max() / L)
        rot_err = max(rot_err, np.abs(R - R_ex).max())
        p_s, R_s = plotting.sample_result(res, "arm", 8)
        # the interpolated curve lies on the exact circle: |p - centre| = 1/kappa
        centre = np.array([0.0, 0.0, -EI / tau])
        radius_err = np.abs(np.linalg.norm(p_s - centre, axis=1) - EI / tau).max()
        curve_err = max(curve_err, radius_err / L)
        shapes.append(p_s)
        frames.append(R_s)
        exact_curves.append(exact_arc(tau, fine_s)[0])
        tips.append(p[-1].tolist())

    fig, ax = plt.subplots(figsize=(6.5, 5.0))
    colors = plt.colormaps["viridis"](np.linspace(0.0, 0.9, len(TORQUES)))
    for tau, res, shape, ex, color in zip(TORQUES, results, shapes, exact_curves, colors):
        ax.plot(ex[:, 0], ex[:, 2], "k--", lw=0.8)
        ax.plot(shape[:, 0], shape[:, 2], color=color, lw=2, label=f"tau = {tau:g} N m")
        ax.plot(*res.positions("arm")[:, [0, 2]].T, "o", color=color, ms=4)
    ax.plot([], [], "k--", lw=0.8, label="exact arc")
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("z [m]")
    ax.grid(alpha=0.3)
    ax.legend(fontsize="small")
    ax.set_title(f"Pure bending, {elements} helical elements (the paper's Fig. 9)")
    save(fig, args.out, "pure_bending.png")
    fig = plotting.plot_configurations(
        np.stack(shapes), np.stack(frames), labels=[f"tau = {t:g} N m" for t in TORQUES],
        references=np.stack(exact_curves), title="Pure bending: ribbons along local y")
    save(fig, args.out, "pure_bending_3d.png")

    converged = all(r.converged for r in results)
    print(f"pure bending, {elements} elements, EI_y = {EI} N m^2, L = {L} m: "
          f"converged = {converged}")
    for tau, tip in zip(TORQUES, tips):
        print(f"  tau = {tau:g} N m: tip = ({tip[0]:+.10f}, {tip[1]:+.1e}, {tip[2]:+.10f}) m")
    print(f"max node position error / L = {pos_err:.2e}; max rotation error = {rot_err:.2e}; "
          f"interpolated curve off the exact circle by <= {curve_err:.2e} L")
    write_summary(args.out, {
        "elements": elements, "length_m": L, "EI_y_Nm2": EI, "torques_Nm": list(TORQUES),
        "converged": converged, "tips_m": tips, "max_position_error_rel": pos_err,
        "max_rotation_error": rot_err, "max_interpolation_error_rel": curve_err})
    return 0 if converged else 1


if __name__ == "__main__":
    raise SystemExit(main())
