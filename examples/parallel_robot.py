"""A planar parallel continuum robot: two nylon rods clamped to the floor, welded at the
top to a rigid plate (bodies and joints, statics and dynamics).

    python examples/parallel_robot.py [--out out/parallel_robot] [--fast]

Rods: length 0.3 m, diameter 4 mm, E = 2 GPa, density 1150 kg/m^3, 0.1 m apart, 24
elements each (8 with --fast); plate: 50 g, welded to both rod tips; no gravity (the
robot lies on a table). Each rod is a column clamped at the floor whose top the plate
keeps from turning, so for a small side force F at the top the plate sways by
``u = F L^3 / (24 EI)`` (two fixed-guided columns, each of stiffness 12 EI / L^3). The
elements' constant strains approximate the columns' linear curvature, so the sway
converges at second order in the element length (about ``(L_e / L)^2`` short).

1. Statics: side forces of 0.05, 0.1 and 0.2 N on the left rod's top node.
2. Dynamics: a 20 ms side push (a smoothstep up and down), then free sway for 2 s (1 s
   with --fast) at dt = 5 ms, rho_inf = 0.95. The period is compared with Rayleigh's
   estimate ``T = 2 pi sqrt((m_plate + 2 (13/35) rho A L) / (24 EI / L^3))`` (the static
   sway shape of a fixed-guided column: its effective mass is 13/35 of its own).

Prints and writes into summary.json the swayed positions with their closed form, the
period with Rayleigh's value, and the largest joint gap; writes shapes.png (static
shapes) and sway.png (the plate's sway against time).
"""
import numpy as np

import simsoft_jax as sj
from simsoft_jax import plotting

from _common import parse_args, save, write_summary

L, D, E, RHO, SPACING, PLATE = 0.3, 0.004, 2.0e9, 1150.0, 0.1, 0.05
FORCES = (0.05, 0.1, 0.2)
UP = {"axis": [0, 1, 0], "angle_deg": -90.0}          # rods along world z


def robot(elements: int, solver: dict, loads: list) -> dict:
    """The scene: two rods ``l`` (x = 0) and ``r`` (x = SPACING), the plate, two welds."""
    def rod(name, x):
        return {"name": name, "material": {"name": "nylon", "E": E, "nu": 0.4,
                                            "density": RHO},
                "section": {"shape": "circle", "diameter": D}, "elements": elements,
                "geometry": {"kind": "straight", "length": L},
                "base": {"position": [x, 0.0, 0.0], "rotation": UP}}

    half = SPACING / 2
    return {"name": "parallel_robot", "solver": solver,
            "rods": [rod("l", 0.0), rod("r", SPACING)],
            "constraints": [{"kind": "clamp", "rod": "l", "node": 0},
                            {"kind": "clamp", "rod": "r", "node": 0}],
            "bodies": [{"name": "plate", "mass": PLATE, "position": [half, 0.0, L],
                        "inertia": np.diag([2e-5, 6e-5, 6e-5]).tolist()}],
            "joints": [{"kind": "weld", "a": {"rod": "l", "node": -1},
                        "b": {"body": "plate", "offset": [-half, 0.0, 0.0]}},
                       {"kind": "weld", "a": {"rod": "r", "node": -1},
                        "b": {"body": "plate", "offset": [half, 0.0, 0.0]}}],
            "loads": loads}


def side_force(value: float, profile=None) -> dict:
    load = {"kind": "force", "rod": "l", "node": -1, "vector": [value, 0.0, 0.0],
            "frame": "world"}
    if profile is not None:
        load["profile"] = profile
    return load


def main():
    args = parse_args("parallel_robot", __doc__)
    elements = 8 if args.fast else 24
    EI = E * np.pi * D**4 / 64
    rho_A = RHO * np.pi * D**2 / 4
    stiffness = 24 * EI / L**3

    statics = [sj.run(robot(elements, {"kind": "static"}, [side_force(F)])) for F in FORCES]
    sway = [float(r.body_pose("plate")[0][0] - SPACING / 2) for r in statics]
    closed = [F / stiffness for F in FORCES]
    for F, u, c in zip(FORCES, sway, closed):
        print(f"F = {F:.2f} N: plate sway {u * 1e3:.4f} mm (closed form {c * 1e3:.4f} mm, "
              f"{u / c - 1:+.2%})")

    t_end = 1.0 if args.fast else 2.0
    push = {"kind": "table", "t": [0.0, 0.01, 0.02], "scale": [0.0, 1.0, 0.0]}
    moving = sj.run(robot(elements, {"kind": "dynamic", "dt": 0.005, "t_end": t_end,
                                     "rho_inf": 0.95}, [side_force(0.5, push)]))
    p, R = moving.body_pose("plate")
    t = np.asarray(moving.time)
    x = p[:, 0] - SPACING / 2
    after = t > 0.03
    i = np.nonzero(after[:-1] & (np.sign(x[:-1]) != np.sign(x[1:])))[0]
    crossings = t[i] - x[i] * (t[i + 1] - t[i]) / (x[i + 1] - x[i])
    period = float(2 * np.mean(np.diff(crossings)))
    rayleigh = float(2 * np.pi * np.sqrt((PLATE + 2 * 13 / 35 * rho_A * L) / stiffness))
    tips = moving.positions("l")[:, -1]
    gap = float(np.abs(tips - (p + np.einsum("tij,j->ti", R, [-SPACING / 2, 0, 0]))).max())
    print(f"dynamics: {'converged' if moving.converged else moving.message}; sway period {period:.4f} s (Rayleigh "
          f"{rayleigh:.4f} s, {period / rayleigh - 1:+.2%}); largest weld gap {gap:.1e} m")

    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(4.5, 4.5))
    for F, result in zip(FORCES, statics):
        for rod in ("l", "r"):
            q = plotting.sample_result(result, rod)[0]
            ax.plot(q[:, 0] * 1e3, q[:, 2] * 1e3, "-", color=f"C{FORCES.index(F)}",
                    label=f"F = {F} N" if rod == "l" else None)
        plate = result.body_pose("plate")[0]
        ax.plot([(plate[0] - SPACING / 2) * 1e3, (plate[0] + SPACING / 2) * 1e3],
                [plate[2] * 1e3] * 2, "-", lw=4, color=f"C{FORCES.index(F)}")
    ax.set(xlabel="x (mm)", ylabel="z (mm)", title="static shapes (side force at the top)",
           aspect="equal")
    ax.legend(fontsize="small")
    save(fig, args.out, "shapes.png")
    fig, ax = plt.subplots(figsize=(6, 3))
    ax.plot(t, x * 1e3)
    ax.set(xlabel="t (s)", ylabel="plate sway (mm)",
           title=f"free sway: period {period:.3f} s (Rayleigh {rayleigh:.3f} s)")
    save(fig, args.out, "sway.png")
    write_summary(args.out, {
        "converged": bool(all(r.converged for r in statics) and moving.converged),
        "elements": elements, "EI_Nm2": EI, "length_m": L, "rho_A_kg_m": rho_A, "plate_kg": PLATE,
        "forces_N": list(FORCES), "sway_m": sway, "period_s": period,
        "rayleigh_period_s": rayleigh, "max_weld_gap_m": gap})
    return 0 if all(r.converged for r in statics) and moving.converged else 1


if __name__ == "__main__":
    raise SystemExit(main())
