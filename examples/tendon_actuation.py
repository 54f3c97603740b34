"""Tendon and pressure-chamber actuation of a clamped soft arm (statics), against the
closed-form arcs.

    python examples/tendon_actuation.py [--out out/tendon_actuation] [--fast]

Set-up: a straight silicone-like arm, L = 0.2 m, EA = 50 N, EI = 2e-4 N m^2 (both
bending axes), clamped at s = 0, section frame = world frame. A tendon runs from the base
to the tip at the offset z = r = 5 mm and is pulled with T = 0.02 ... 0.1 N; separately,
a pressure chamber (area A = 20 mm^2) at z = -r is inflated to P = 1 ... 5 kPa. A
straight tendon or chamber loads every section with the same axial force and moment, so
the arm bends into an exact arc (curvature per reference length ``T r / EI`` with axial
strain ``-T / EA``; ``P A r / EI`` with strain ``+P A / EA`` for the chamber, which
pushes its side longer): the helical elements reproduce it to round-off with any number
of elements. A helical tendon (one turn over the arm) is also solved: it twists the arm
into a spatial curve that no arc describes. One compilation serves every tension (the
tension and routing are arrays of the model).

Printed and saved: the largest node error against the arc (relative to L) for every
tension and pressure, the tip positions, and the helical case's tip; figures
tendon_arcs.png (x-z plane) and summary.json.
"""
import matplotlib.pyplot as plt
import numpy as np

import simsoft_jax as sj

from _common import parse_args, save, write_summary

L, EA, EI, R = 0.2, 50.0, 2e-4, 0.005
TENSIONS = (0.02, 0.04, 0.06, 0.08, 0.1)      # N
PRESSURES = (1e3, 2e3, 3e3, 4e3, 5e3)          # Pa
AREA = 2e-5                                     # m^2


def scene(elements, tension=0.0, pressure=0.0, routing=(0.0, R)):
    """The arm with one tendon and one chamber (either may be zero): one structure."""
    return {
        "solver": {"kind": "static", "tolerance": 1e-12},
        "rods": [{"name": "arm", "elements": elements,
                  "geometry": {"kind": "straight", "length": L},
                  "stiffness": {"EA": EA, "GAy": 20.0, "GAz": 20.0, "GJ": 1.5e-4,
                                "EIy": EI, "EIz": EI},
                  "inertia": {"rhoA": 0.03, "rhoJ": 2e-7, "rhoIy": 1e-7, "rhoIz": 1e-7}}],
        "constraints": [{"kind": "clamp", "rod": "arm", "node": 0}],
        "tendons": [{"name": "t1", "rod": "arm", "from_node": 0, "to_node": -1,
                     "offset": routing if isinstance(routing, dict) else list(routing),
                     "tension": tension}],
        "chambers": [{"name": "c1", "rod": "arm", "area": AREA, "offset": [0.0, -R],
                      "pressure": pressure}],
    }


def arc(kappa, eps, s):
    """Arc towards +z of curvature ``kappa`` per reference length, axial strain ``eps``."""
    return (1.0 + eps) * np.stack([np.sin(kappa * s) / kappa, 0.0 * s,
                                   (1.0 - np.cos(kappa * s)) / kappa], axis=1)


def main():
    args = parse_args("tendon_actuation", __doc__)
    elements = 4 if args.fast else 10
    s = np.linspace(0.0, L, elements + 1)
    cases = ([("tendon", T, sj.run(scene(elements, tension=T)), T * R / EI, -T / EA)
              for T in TENSIONS]
             + [("chamber", P, sj.run(scene(elements, pressure=P)), P * AREA * R / EI,
                 P * AREA / EA) for P in PRESSURES])
    helix = sj.run(scene(elements, tension=TENSIONS[-1],
                         routing={"kind": "helix", "radius": R, "pitch": L}))
    converged = helix.converged and all(case[2].converged for case in cases)
    errors, tips = [], []
    fig, ax = plt.subplots(figsize=(6.5, 5.0))
    colors = plt.colormaps["viridis"](np.linspace(0.0, 0.9, len(TENSIONS)))
    fine = np.linspace(0.0, L, 101)
    for i, (kind, value, res, kappa, eps) in enumerate(cases):
        p = res.positions("arm")
        errors.append(float(np.linalg.norm(p - arc(kappa, eps, s), axis=1).max() / L))
        tips.append(p[-1].tolist())
        color, style = colors[i % len(TENSIONS)], "-" if kind == "tendon" else ":"
        exact = arc(kappa, eps, fine)
        ax.plot(exact[:, 0], exact[:, 2], "k--", lw=0.6)
        label = (f"tendon T = {value:g} N" if kind == "tendon"
                 else f"chamber P = {value / 1e3:g} kPa")
        ax.plot(p[:, 0], p[:, 2], style, marker="o", ms=3, color=color, label=label)
    ph = helix.positions("arm")
    ax.plot(ph[:, 0], ph[:, 2], "r-", marker="s", ms=3, label="helical tendon (x-z view)")
    ax.plot([], [], "k--", lw=0.6, label="closed-form arc")
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("z [m]")
    ax.grid(alpha=0.3)
    ax.legend(fontsize="x-small", ncol=2)
    ax.set_title(f"Tendon and chamber actuation, {elements} helical elements")
    save(fig, args.out, "tendon_arcs.png")

    print(f"tendon/chamber arm, {elements} elements, L = {L} m, EI = {EI} N m^2, "
          f"r = {R} m: converged = {converged}")
    for (kind, value, *_), tip, err in zip(cases, tips, errors):
        unit = "N" if kind == "tendon" else "Pa"
        print(f"  {kind} {value:g} {unit}: tip = ({tip[0]:+.8f}, {tip[1]:+.1e}, "
              f"{tip[2]:+.8f}) m, max node error vs arc = {err:.1e} L")
    print(f"  helical tendon, T = {TENSIONS[-1]} N, one turn: tip = "
          f"({ph[-1, 0]:+.6f}, {ph[-1, 1]:+.6f}, {ph[-1, 2]:+.6f}) m, tension reported "
          f"{helix.tendon_tension('t1'):g} N")
    write_summary(args.out, {
        "elements": elements, "length_m": L, "EA_N": EA, "EI_Nm2": EI, "offset_m": R,
        "area_m2": AREA, "tensions_N": list(TENSIONS), "pressures_Pa": list(PRESSURES),
        "converged": converged, "tips_m": tips, "max_error_rel": max(errors),
        "helix_tip_m": ph[-1].tolist()})
    return 0 if converged else 1


if __name__ == "__main__":
    raise SystemExit(main())
