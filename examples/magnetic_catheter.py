"""A magnetic catheter steered by a rotating field: quasi-static steering (every field
direction solved at once, one batched solve) and the swing after the field is switched on.

    python examples/magnetic_catheter.py [--out out/magnetic_catheter] [--fast]

Set-up: a soft polymer catheter (E = 3 MPa, diameter 2 mm, length 100 mm) clamped at the
origin along x, with a magnetized tip segment (the last 10 mm, magnetization 1e5 A/m along
the axis: a moment of M A = 0.314 A m per metre of it). A uniform field of 20 mT turns in
the x-y plane, ``B = |B| (cos phi, sin phi, 0)``. The field makes the couple
``(R m) x B`` per unit length on the magnet (``[magnetic_field]`` and
``rods[].segments[].magnetization`` of the scene format) and the catheter bends until the
magnet's torque and the bending moment balance.

Reference: with no force anywhere, the bending moment obeys ``EI theta'' = -c(s)``, the
couple per unit length ``c = m B sin(phi - theta)`` on the magnet and 0 elsewhere, with
``theta(0) = 0`` at the clamp and ``theta'(L) = 0`` at the free tip; solved here by
shooting from the tip for every phi. Printed: the largest tip-position error against it.

Dynamics: the field at phi = 90 degrees is switched on over 0.1 s (a smoothstep); the
catheter, in blood (``[fluid]``: density 1060 kg/m^3, normal drag coefficient 1.2, added
mass coefficient 1) and with mass-proportional damping of 15 1/s standing for the vessel
around it, swings and settles on the static shape (its first bending mode: ~1.4 Hz).

Writes steering.png (shapes for each field direction, with the field arrows),
tip_angle.png (tip angle against field angle, model and reference), swing.png (the tip
coordinates of the dynamic run and the static answer) and summary.json.
"""
import dataclasses

import jax
import matplotlib.pyplot as plt
import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

import simsoft_jax as sj

from _common import parse_args, save, write_summary

LENGTH, MAGNET, DIAMETER, E = 0.1, 0.01, 2e-3, 3e6
MAGNETIZATION, FIELD = 1e5, 0.02                   # A/m, T
AREA = np.pi * DIAMETER ** 2 / 4
EI = E * np.pi * DIAMETER ** 4 / 64


def scene(elements: int, kind: str = "static", t_end: float = 1.5) -> dict:
    body = elements - max(1, elements // 10)
    solver = ({"kind": "static"} if kind == "static" else
              {"kind": "dynamic", "t_end": t_end, "dt": 5e-3, "save_every": 4})
    return {
        "name": "magnetic_catheter",
        "solver": solver,
        "magnetic_field": {"vector": [0.0, FIELD, 0.0],
                           **({} if kind == "static" else
                              {"profile": {"kind": "smoothstep", "t0": 0.0, "t1": 0.1}})},
        "materials": [{"name": "polymer", "E": E, "nu": 0.45, "density": 1100.0,
                       "mass_damping": 15.0}],
        **({} if kind == "static" else
           {"fluid": {"density": 1060.0, "drag_normal": 1.2, "added_mass": 1.0}}),
        "rods": [{"name": "catheter", "material": "polymer",
                  "geometry": {"kind": "straight", "length": LENGTH},
                  "segments": [
                      {"elements": body, "length": LENGTH - MAGNET,
                       "section": {"shape": "circle", "diameter": DIAMETER}},
                      {"elements": elements - body, "length": MAGNET,
                       "section": {"shape": "circle", "diameter": DIAMETER},
                       "magnetization": [MAGNETIZATION, 0.0, 0.0]}]}],
        "constraints": [{"kind": "clamp", "rod": "catheter", "node": 0}],
    }


def reference_tip(phi: float) -> np.ndarray:
    """Tip (x, y) of the planar elastica with the magnet's couple, by shooting from the
    free tip (module docstring)."""
    m = MAGNETIZATION * AREA

    def rhs(s, y):
        couple = m * FIELD * np.sin(phi - y[0]) if s > LENGTH - MAGNET else 0.0
        return [y[1], -couple / EI, np.cos(y[0]), np.sin(y[0])]

    def from_tip(theta_tip):
        sol = solve_ivp(rhs, [LENGTH, 0.0], [theta_tip, 0.0, 0.0, 0.0], rtol=1e-11,
                        atol=1e-13, max_step=MAGNET / 20)
        return sol.y[:, -1]

    theta_tip = brentq(lambda a: from_tip(a)[0], 0.0, phi, xtol=1e-13)
    end = from_tip(theta_tip)
    return np.array([-end[2], -end[3]])


def main():
    args = parse_args("magnetic_catheter", __doc__)
    elements = 20 if args.fast else 40
    angles = np.radians(np.linspace(15.0, 150.0, 4 if args.fast else 10))
    model = sj.build_model(sj.Scene.from_dict(scene(elements)))
    fields = FIELD * np.stack([np.cos(angles), np.sin(angles), 0 * angles], axis=1)

    @jax.jit
    def steer(field):
        part = dataclasses.replace(model.magnetic, field=field)
        return sj.solve_static(model.replace(magnetic=part))

    eqs = jax.vmap(steer)(fields)              # every field direction in one batched solve
    converged = np.asarray(eqs.converged)
    p = np.asarray(eqs.p)                      # (angles, nodes, 3)
    reference = np.array([reference_tip(phi) for phi in angles])
    tip_error = np.linalg.norm(p[:, -1, :2] - reference, axis=1)
    tangent = np.asarray(eqs.R)[:, -1, :, 0]
    tip_angle = np.degrees(np.arctan2(tangent[:, 1], tangent[:, 0]))
    for phi, angle, err, ok in zip(np.degrees(angles), tip_angle, tip_error, converged):
        print(f"field at {phi:5.1f} deg: tip at {angle:6.1f} deg, tip error "
              f"{err * 1e3:.3f} mm against the shooting reference"
              + ("" if ok else " (NOT converged)"))

    fig, ax = plt.subplots(figsize=(6.0, 5.0), layout="constrained")
    colors = plt.cm.viridis(np.linspace(0, 1, len(angles)))
    for shape, phi, color in zip(p, angles, colors):
        ax.plot(shape[:, 0] * 1e3, shape[:, 1] * 1e3, color=color, lw=2.5,
                label=f"field at {np.degrees(phi):.0f}°")
        start = shape[-1, :2] * 1e3
        end = start + 10.0 * np.array([np.cos(phi), np.sin(phi)])
        ax.annotate("", xy=end, xytext=start,
                    arrowprops=dict(arrowstyle="->", color=color, lw=1.2))
        ax.plot(*end, alpha=0.0)             # keeps the arrow inside the axes
    ax.plot(reference[:, 0] * 1e3, reference[:, 1] * 1e3, "kx", label="tip, shooting reference")
    ax.set(xlabel="x [mm]", ylabel="y [mm]", aspect="equal",
           title=f"Catheter steered by a {FIELD * 1e3:.0f} mT field (arrows: field direction)")
    ax.legend(fontsize=7, loc="lower left")
    save(fig, args.out, "steering.png")

    fig, ax = plt.subplots(figsize=(5.0, 3.8), layout="constrained")
    ref_angle = []
    for phi in angles:                       # tip angle of the reference from its slope
        ref_angle.append(np.degrees(brentq(lambda a: _tip_residual(a, phi), 0.0, phi)))
    ax.plot(np.degrees(angles), tip_angle, "o-", label="simsoft_jax")
    ax.plot(np.degrees(angles), ref_angle, "k--", label="shooting reference")
    ax.plot(np.degrees(angles), np.degrees(angles), ":", color="gray", label="tip along the field")
    ax.set(xlabel="field angle [deg]", ylabel="tip angle [deg]")
    ax.legend()
    save(fig, args.out, "tip_angle.png")

    dynamic = sj.run(sj.Scene.from_dict(scene(elements, "dynamic", 0.8 if args.fast else 1.5)))
    tip = dynamic.positions("catheter")[:, -1]
    static_90 = steer(np.array([0.0, FIELD, 0.0])).p[-1]
    settle = float(np.linalg.norm(tip[-1] - np.asarray(static_90)))
    print(f"dynamic run ({dynamic.status}): tip {settle * 1e3:.3f} mm from the static "
          f"shape at t = {dynamic.time[-1]:.2f} s")
    fig, ax = plt.subplots(figsize=(5.5, 3.8), layout="constrained")
    time = np.asarray(dynamic.time)
    for k, (name, color) in enumerate((("x", "C0"), ("y", "C1"))):
        ax.plot(time, tip[:, k] * 1e3, color=color, label=f"tip {name} (dynamics)")
        ax.axhline(float(static_90[k]) * 1e3, color=color, ls="--", lw=1,
                   label=f"tip {name}, static shape")
    ax.set(xlabel="time [s]", ylabel="tip position [mm]",
           title="Field switched on at 90° (0.1 s ramp): the tip swings and settles")
    ax.legend(fontsize=8)
    save(fig, args.out, "swing.png")

    write_summary(args.out, {
        "field_angles_deg": np.degrees(angles).tolist(), "tip_angles_deg": tip_angle.tolist(),
        "converged": converged.tolist(),
        "max_tip_error_m": float(tip_error.max()), "dynamic_status": dynamic.status,
        "dynamic_final_distance_to_static_m": settle})


def _tip_residual(theta_tip, phi):
    """theta(0) of the reference shot from a tip angle (zero at the reference's tip angle)."""
    m = MAGNETIZATION * AREA
    sol = solve_ivp(lambda s, y: [y[1], -(m * FIELD * np.sin(phi - y[0])
                                          if s > LENGTH - MAGNET else 0.0) / EI],
                    [LENGTH, 0.0], [theta_tip, 0.0], rtol=1e-11, atol=1e-13,
                    max_step=MAGNET / 20)
    return sol.y[0, -1]


if __name__ == "__main__":
    main()
