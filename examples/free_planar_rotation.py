"""Free planar rotation of a straight arm (the paper's Figs. 10-12, eqs. 92-108).

    python examples/free_planar_rotation.py [--out out/free_planar_rotation] [--fast]

A free-free arm (L = 1 m) spins about the world y axis at omega0 = pi, 2 pi, 3 pi rad/s in
the x-z plane, with no loads, for 1 s. The exact motion is a steady
rotation about the fixed mid-span point p_c with the arm stretched by the centrifugal
force: node B (s = L) moves on ``p_c + xi(L) (cos w t, 0, -sin w t)`` with
``xi(L) = tan(c0 w L/2) / (c0 w)``, ``c0 = sqrt(rho/E)``.

Choices (the paper's data are rho = 2.7e-3 kg/m^3, E = 6.9e7 Pa, section not given):
real aluminium rho = 2.7e3 kg/m^3, E = 6.9e10 Pa (nu 0.33),
which has the paper's c0 = 6.26e-6 s/m and so the same motion; a solid circle d = 20 mm
(the exact solution does not depend on the section); 10 helical elements (4 with --fast),
consistent inertia, dt = 0.01 s, rho_inf = 0.9 (0.5 s with --fast). The run starts from
the exact stretched state (positions, and the rigid spin about p_c as the initial
velocity), as in tests/test_dynamics_physics.py.

Error (Fig. 12): the paper's eq. (108) divides by x_e(t), z_e(t), which cross zero; we plot
``e(t) = |p_B(t) - p_B,exact(t)| / L * 100 %`` instead. The paper reports
errors < 0.1 %; the largest error here is printed and saved (summary.json).

Writes node_B_displacements.png (Fig. 11), errors.png (Fig. 12), snapshots.png, summary.json.
"""
import matplotlib.pyplot as plt
import numpy as np

import simsoft_jax as sj

from _common import parse_args, save, write_summary

L, DIAMETER = 1.0, 0.02
ALUMINIUM = {"name": "aluminium", "E": 6.9e10, "nu": 0.33, "density": 2.7e3}
OMEGAS = (np.pi, 2 * np.pi, 3 * np.pi)


def node_positions(omega, s):
    """Exact stretched steady state at t = 0: node positions (N, 3), and xi(s) (N,)
    (signed distance from the mid-span point p_c = (L/2, 0, 0))."""
    c0 = np.sqrt(ALUMINIUM["density"] / ALUMINIUM["E"])
    x = c0 * omega
    xi = np.sin(x * (s - L / 2)) / (x * np.cos(x * L / 2))
    return np.array([L / 2, 0.0, 0.0]) + xi[:, None] * np.array([1.0, 0.0, 0.0]), xi


def free_arm(elements, settings):
    """Model of the free-free arm, straight and at rest (built once: the three runs
    differ only in their start state, so they share one compilation)."""
    scene = sj.Scene.from_dict({
        "name": "free_planar_rotation",
        "solver": {"kind": "dynamic", "t_end": settings.dt * settings.steps, "dt": settings.dt,
                   "rho_inf": settings.rho_inf, "inertia": "consistent"},
        "materials": [ALUMINIUM],
        "rods": [{"name": "arm", "material": "aluminium",
                  "section": {"shape": "circle", "diameter": DIAMETER},
                  "elements": elements, "geometry": {"kind": "straight", "length": L}}],
    })
    return sj.build_model(scene)


def rollout(model, omega, settings):
    """The FE rollout from the exact stretched state: nodes at p_c + xi(s_i) e_x with
    identity frames, body velocities ``(0, 0, -w xi(s_i), 0, w, 0)``. Returns time (T,),
    positions (T, N, 3), the converged flag and xi(s_i) (N,)."""
    s = np.linspace(0.0, L, model.p0.shape[0])
    p0, xi = node_positions(omega, s)
    v0 = np.zeros((len(s), 6))
    v0[:, 2], v0[:, 4] = -omega * xi, omega
    traj = sj.simulate(model.replace(p0=p0, v0=v0), settings)
    return np.asarray(traj.time), np.asarray(traj.p), bool(traj.converged), xi


def main():
    args = parse_args("free_planar_rotation", __doc__)
    elements = 4 if args.fast else 10
    t_end = 0.5 if args.fast else 1.0
    settings = sj.DynamicSettings(dt=0.01, steps=int(round(t_end / 0.01)), rho_inf=0.9,
                                  tolerance=1e-12)
    fig_d, axes = plt.subplots(1, 2, figsize=(10.0, 4.4), sharey=True, layout="constrained")
    fig_e, ax_e = plt.subplots(figsize=(6.5, 4.0))
    fig_s, ax_s = plt.subplots(figsize=(5.0, 5.0))
    colors = ("tab:blue", "tab:orange", "tab:green")
    summary = {"elements": elements, "t_end_s": t_end, "dt_s": settings.dt,
               "rho_inf": settings.rho_inf, "material": ALUMINIUM, "diameter_m": DIAMETER,
               "omegas_rad_s": list(OMEGAS), "cases": []}
    converged = True
    model = free_arm(elements, settings)
    for omega, color in zip(OMEGAS, colors):
        t, p, ok, xi = rollout(model, omega, settings)
        converged &= ok
        direction = np.stack([np.cos(omega * t), 0.0 * t, -np.sin(omega * t)], axis=1)
        exact_B = xi[-1] * direction                        # node B relative to p_c
        fe_B = p[:, -1] - np.array([L / 2, 0.0, 0.0])
        error = np.linalg.norm(fe_B - exact_B, axis=1) / L * 100.0
        name = f"omega0 = {omega / np.pi:g} pi rad/s"
        for ax, k, comp in ((axes[0], 0, "x"), (axes[1], 2, "z")):
            ax.plot(t, exact_B[:, k], color=color, lw=1.5, label=f"{name} exact")
            ax.plot(t, fe_B[:, k], ":", color="k", lw=1.5)
            ax.set_title(f"node B: {comp}(t) - {comp}_c")
        ax_e.semilogy(t[1:], np.maximum(error[1:], 1e-16), color=color, label=name)
        for i in np.linspace(0, len(t) - 1, 9).round().astype(int):
            ax_s.plot(p[i, :, 0], p[i, :, 2], "-o", color=color, ms=2, lw=1, alpha=0.6)
        stretch = xi[-1] - L / 2
        summary["cases"].append({"omega_rad_s": omega, "converged": ok,
                                 "max_error_percent": float(error.max()),
                                 "final_error_percent": float(error[-1]),
                                 "node_B_final_m": p[-1, -1].tolist(),
                                 "exact_tip_stretch_m": float(stretch)})
        print(f"{name}: converged = {ok}, max |p_B - p_B,exact| / L = {error.max():.2e} %, "
              f"exact centrifugal stretch of each half {stretch:.2e} m")
    for ax in axes:
        ax.set_xlabel("time [s]")
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("displacement from mid-span [m]")
    axes[0].plot([], [], ":", color="k", label="simulation")
    fig_d.legend(*axes[0].get_legend_handles_labels(), loc="outside lower center", ncols=4,
                 fontsize="small")
    fig_d.suptitle(f"Free planar rotation, {elements} elements (the paper's Fig. 11)")
    save(fig_d, args.out, "node_B_displacements.png")
    ax_e.set_xlabel("time [s]")
    ax_e.set_ylabel("|p_B - p_B,exact| / L [%]")
    ax_e.grid(which="both", alpha=0.3)
    ax_e.legend(fontsize="small")
    ax_e.set_title("Errors of the free rotating arm (the paper's Fig. 12)")
    save(fig_e, args.out, "errors.png")
    ax_s.set_aspect("equal")
    ax_s.set_xlabel("x [m]")
    ax_s.set_ylabel("z [m]")
    ax_s.set_title("snapshots (x-z plane)")
    ax_s.grid(alpha=0.3)
    save(fig_s, args.out, "snapshots.png")
    summary["converged"] = converged
    summary["max_error_percent"] = max(c["max_error_percent"] for c in summary["cases"])
    print(f"largest error over all cases: {summary['max_error_percent']:.2e} % "
          "(the paper: < 0.1 %)")
    write_summary(args.out, summary)
    return 0 if converged else 1


if __name__ == "__main__":
    raise SystemExit(main())
