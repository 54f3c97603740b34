"""Inverse statics: the moments that bring a soft arm's middle and tip to targets.

    python examples/inverse_statics.py [--out out/inverse_statics] [--fast]

Robot: a silicone arm (``silicone`` material, solid circle of diameter 2 cm, 0.2 m long,
clamped at s = 0, 12 elements; 6 with --fast), with follower moments (N m, about the
section's own axes) at its middle node and at its tip:

* planar: moments about the local z axis at the middle and the tip (2 actuators);
* 3-D: moments about the local y and z axes at both nodes (4 actuators).

Targets: the middle and tip positions of forward static solves at random moments (so they
are reachable; 20 per robot, 5 with --fast), plus for the planar robot two unreachable
ones: a point beyond the arm's length, and a shape that needs a negative middle moment
while the bounds allow only non-negative ones. ``sj.solve_inverse`` solves each batch in
one vmapped program (one compilation per robot and batch size) with projected
Levenberg-Marquardt (default) and with optax L-BFGS; the Jacobian comes by forward mode
through the static solves' implicit-function derivative.

Printed: per robot and method, targets reached to 1e-6 of the length, the largest error,
iterations, and the time per target of a warm call (compiled program reused; the fastest
of two, the methods alternating) and of the first call (compilation included); for the unreachable targets, the solver's verdict.
Writes shapes.png (planar robot: reached shapes, targets) and summary.json.
"""
import os

import jax.numpy as jnp
import matplotlib.pyplot as plt
import numpy as np

import simsoft_jax as sj

from _common import parse_args, save, write_summary

LENGTH = 0.2                                  # m
SETTINGS = sj.StaticSettings(tolerance=1e-12)
METHODS = ("levenberg_marquardt", "lbfgs")


def arm(elements: int):
    return sj.build_model(sj.Scene.from_dict({
        "name": "inverse_statics", "solver": {"kind": "static"},
        "rods": [{"name": "arm", "material": "silicone",
                  "section": {"shape": "circle", "diameter": 0.02}, "elements": elements,
                  "geometry": {"kind": "straight", "length": LENGTH}}],
        "constraints": [{"kind": "clamp", "rod": "arm", "node": 0}],
        "loads": [{"kind": "moment", "rod": "arm", "node": -1, "vector": [0.0, 0.0, 0.0],
                   "frame": "local"}]}))


def shapes(model, actuate, U):
    """Node positions (B, N, 3) of forward solves at the moments U (B, P)."""
    return np.array([np.asarray(sj.solve_static(actuate(model, jnp.asarray(u)), SETTINGS).p)
                     for u in U])


def timed(model, actuate, nodes, targets, rounds=2):
    """Both methods on the same targets: a first call each (compilation included), then
    ``rounds`` warm calls alternating between the methods (the machine's load changes
    both alike); per method the last result, the first call's time and the fastest warm
    time (s)."""
    def call(method):
        return sj.solve_inverse(model, actuate, nodes, targets, np.zeros(actuate.size),
                                method=method, settings=SETTINGS, max_steps=100)

    out = {method: [None, call(method).seconds, np.inf] for method in METHODS}
    for _ in range(rounds):
        for method in METHODS:
            res = call(method)
            out[method][0] = res
            out[method][2] = min(out[method][2], res.seconds)
    return out


def main():
    args = parse_args("inverse_statics", __doc__)
    elements = 6 if args.fast else 12
    count = 5 if args.fast else 20
    model = arm(elements)
    mid, tip = elements // 2, elements
    EI = float(model.stiffness[0, 5])
    scale = 2.0 * EI / LENGTH                  # moments up to ~2 rad of bending
    robots = {
        "planar": sj.leaf_actuation(model, [("nodal_follower", (mid, 5)),
                                            ("nodal_follower", (tip, 5))]),
        "3d": sj.leaf_actuation(model, [("nodal_follower", (mid, 4)),
                                        ("nodal_follower", (mid, 5)),
                                        ("nodal_follower", (tip, 4)),
                                        ("nodal_follower", (tip, 5))]),
    }
    rng = np.random.default_rng(0)
    summary = {"load_average": os.getloadavg()[0], "elements": elements, "targets_per_robot": count, "length_m": LENGTH,
               "EI_Nm2": EI, "robots": {}}
    print(f"silicone arm, {LENGTH} m, {elements} elements, EI = {EI:.4g} N m^2; "
          f"{count} reachable targets per robot (middle and tip nodes)")
    for name, actuate in robots.items():
        U = rng.uniform(-0.5, 0.5, (count, actuate.size)) * scale
        targets = shapes(model, actuate, U)[:, [mid, tip]]
        summary["robots"][name] = {}
        for method, (res, first, warm) in timed(model, actuate, [mid, tip], targets).items():
            row = {"reached": int(res.reached.sum()),
                   "max_relative_error": float(res.relative_error.max()),
                   "max_actuation_error_Nm": float(np.abs(res.u - U).max()),
                   "iterations_mean": float(res.iterations.mean()),
                   "solves_mean": float(res.solves.mean()),
                   "seconds_per_target_warm": warm / count,
                   "seconds_per_target_first_call": first / count}
            summary["robots"][name][method] = row
            print(f"  {name:6s} {method:19s}: reached {row['reached']}/{count}, largest "
                  f"error {row['max_relative_error']:.2e} of the length, "
                  f"{row['iterations_mean']:.1f} iterations, "
                  f"{row['seconds_per_target_warm'] * 1e3:.0f} ms per target warm "
                  f"({row['seconds_per_target_first_call']:.2f} s with compilation)")

    # the planar robot: two unreachable targets, middle moment bounded below by 0
    actuate = robots["planar"]
    outside = shapes(model, actuate, [[-0.4 * scale, 0.3 * scale]])[:, [mid, tip]]
    beyond = np.array([[[0.6 * LENGTH, 0.1 * LENGTH, 0.0], [1.2 * LENGTH, 0.2 * LENGTH, 0.0]]])
    U = rng.uniform(0.05, 0.5, (2, 2)) * scale
    reachable = shapes(model, actuate, U)[:, [mid, tip]]
    targets = np.concatenate([reachable, outside, beyond])
    res = sj.solve_inverse(model, actuate, [mid, tip], targets, np.zeros(2),
                           lower=[0.0, -np.inf], upper=[np.inf, np.inf], settings=SETTINGS)
    print("planar, middle moment >= 0:")
    for label, message in zip(("reachable", "reachable", "needs a negative moment",
                               "beyond reach"), res.messages):
        print(f"  {label:24s} {message}")
    summary["bounded"] = {"messages": res.messages, "reached": res.reached.tolist(),
                          "unreachable": res.unreachable.tolist(),
                          "u_Nm": res.u.tolist(), "relative_error": res.relative_error.tolist()}

    fig, ax = plt.subplots(figsize=(6, 5))
    reached = shapes(model, actuate, res.u)
    for k, (p, tgt) in enumerate(zip(reached, targets)):
        line, = ax.plot(p[:, 0], p[:, 1], "-", lw=2)
        ax.plot(tgt[:, 0], tgt[:, 1], "x", ms=10, mew=2, color=line.get_color(),
                label=("reached" if res.reached[k] else "unreachable") + f" target {k}")
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title("planar arm: shapes found for the targets (x)")
    ax.legend(fontsize=8)
    save(fig, args.out, "shapes.png")
    write_summary(args.out, summary)


if __name__ == "__main__":
    main()
