"""Shared plumbing of the example scripts: command line, output folder, summary file, and
the work-energy balance of a dynamic run with dead nodal loads.

Every example takes ``--out DIR`` (default ``out/<name>``) and ``--fast`` (small meshes or
short runs, used by the tests), writes its figures as PNG into DIR and a ``summary.json``
with the numbers it prints.
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import numpy as np  # noqa: E402

HERE = Path(__file__).resolve().parent
SCENES = HERE / "scenes"


def parse_args(name: str, doc: str, extra=None):
    """``--out`` (Path, created) and ``--fast`` (bool) of example ``name``; ``extra(parser)``
    may add the example's own options. Says what the example does and that its first
    solves compile (so that a long first wait is not a silent one)."""
    parser = argparse.ArgumentParser(description=doc.strip().splitlines()[0])
    parser.add_argument("--out", default=f"out/{name}", help="output folder (default %(default)s)")
    parser.add_argument("--fast", action="store_true", help="small mesh / short run (tests)")
    if extra is not None:
        extra(parser)
    args = parser.parse_args()
    args.out = Path(args.out)
    args.out.mkdir(parents=True, exist_ok=True)
    print(f"{name}: {parser.description}\n  writing to {args.out}; the first solve of each "
          "model structure compiles its program first (tens of seconds)", flush=True)
    return args


def save(fig, out: Path, name: str) -> Path:
    """Save a Figure as ``out/name`` (PNG, 120 dpi), close it and say so."""
    import matplotlib.pyplot as plt

    path = out / name
    fig.savefig(path, dpi=120, bbox_inches="tight")
    plt.close(fig)
    print(f"wrote {path}")
    return path


# The soft arm of the closed-loop control examples (mpc_tendon_tracking, learn_policy):
# length m, axial stiffness N, bending stiffness N m^2, tendon offset m.
ARM_LENGTH, ARM_EA, ARM_EI, ARM_OFFSET = 0.2, 50.0, 2e-4, 0.005


def tendon_arm(elements: int) -> dict:
    """The control examples' arm as a ``[[rods]]`` table: a straight 0.2 m rod named
    "arm" (bending stiffness 2e-4 N m^2, mass-proportional damping 10 1/s)."""
    return {"name": "arm", "elements": elements,
            "geometry": {"kind": "straight", "length": ARM_LENGTH},
            "material": {"E": 1e6, "nu": 0.5, "density": 1000.0, "mass_damping": 10.0},
            "stiffness": {"EA": ARM_EA, "GAy": 20.0, "GAz": 20.0, "GJ": 1.5e-4,
                          "EIy": ARM_EI, "EIz": ARM_EI},
            "inertia": {"rhoA": 0.03, "rhoJ": 1e-4, "rhoIy": 1e-4, "rhoIz": 1e-4}}


def write_summary(out: Path, summary: dict) -> Path:
    """Write ``summary.json`` (plain JSON types) into ``out``."""
    path = out / "summary.json"
    path.write_text(json.dumps(summary, indent=1))
    print(f"wrote {path}")
    return path


def profile_value(profile: dict, t):
    """Scale of a scene load's time law at times ``t`` (s), written out from the
    scene-format contract for the laws the examples use: constant 1, linear ``rate t``
    and smoothstep (``3x^2 - 2x^3`` of ``x = (t - t0)/(t1 - t0)`` clipped to [0, 1])."""
    t = np.asarray(t, float)
    kind = profile.get("kind", "constant")
    if kind == "constant":
        return np.ones_like(t)
    if kind == "linear":
        return profile["rate"] * t
    if kind == "smoothstep":
        x = np.clip((t - profile["t0"]) / (profile["t1"] - profile["t0"]), 0.0, 1.0)
        return x * x * (3.0 - 2.0 * x)
    raise ValueError(f"profile.kind: {kind!r} not handled by the examples")


def element_twists(result, rod: str):
    """Relative twists ``d_e = log(H_e^-1 H_e+1)`` (the paper's eq. 28) of every element of
    ``rod`` at every saved time of a dynamic Result, (T, E, 6)."""
    import jax

    from simsoft_jax.analysis import kinematics

    twists = jax.jit(jax.vmap(kinematics.element_twists))
    return np.asarray(twists(result.rotations(rod), result.positions(rod)))


def straight_element_mass(length: float, inertia) -> np.ndarray:
    """Frozen consistent mass (12, 12) of a straight element:
    ``M_AA = L/3 M - L/24 (A^T M + M A) + L/120 A^T M A``, ``M_AB = L/6 M + L/24 (M A -
    A^T M) - L/120 A^T M A``, ``M_BB = L/3 M + L/24 (A^T M + M A) + L/120 A^T M A`` with
    ``M = diag(inertia)`` (or ``inertia`` itself, a (6,6) section inertia) and
    ``A = ad([L e1; 0])``."""
    M = np.asarray(inertia) if np.ndim(inertia) == 2 else np.diag(inertia)
    A = np.zeros((6, 6))
    A[1, 5], A[2, 4] = -length, length          # ad_h = [[w^, U^], [0, w^]], U = L e1
    AtM, MA, AtMA = A.T @ M, M @ A, A.T @ M @ A
    MAA = length / 3 * M - length / 24 * (AtM + MA) + length / 120 * AtMA
    MAB = length / 6 * M + length / 24 * (MA - AtM) - length / 120 * AtMA
    MBB = length / 3 * M + length / 24 * (AtM + MA) + length / 120 * AtMA
    return np.block([[MAA, MAB], [MAB.T, MBB]])


def work_energy_balance(result, scene: dict, rod: str, twists=None):
    """Work done by the dead (world-frame) nodal forces and moments of ``scene`` on the
    single straight ``rod`` of a dynamic Result, and its mechanical energy gain, both (T,) J.

    Power of a dead load at node i: ``F(t) . pdot_i + M(t) . omega_i`` with world
    velocities ``R_i v_lin`` and ``R_i omega`` from the saved body velocities; the work is
    its trapezoid integral. Energy, computed here from the saved states: kinetic
    ``1/2 v_e^T M_e v_e`` with the consistent element masses (:func:`straight_element_mass`)
    plus strain ``sum (L/2) eps^T K eps``, ``eps = (d - d0)/L`` (the paper's eqs. 29, 48).
    Without damping and with exact time integration the two are equal; generalized-alpha
    with rho_inf < 1 dissipates a little of the fast modes. ``twists``: the (T, E, 6)
    element twists if already computed (:func:`element_twists`).
    """
    time = result.time
    R = result.rotations(rod)
    v = result.velocities(rod)
    power = np.zeros_like(time)
    for load in scene["loads"]:
        if load["rod"] != rod or load.get("frame", "world") != "world":
            raise ValueError("loads: the balance handles dead nodal loads on the rod only")
        node = load["node"]
        vec = np.asarray(load["vector"], float)
        scale = profile_value(load.get("profile", {"kind": "constant"}), time)
        col = slice(0, 3) if load["kind"] == "force" else slice(3, 6)
        world_rate = np.einsum("tij,tj->ti", R[:, node], v[:, node, col])
        power += scale * (world_rate @ vec)
    work = np.concatenate([[0.0], np.cumsum(0.5 * (power[1:] + power[:-1]) * np.diff(time))])

    model = result.model
    lengths, inertia = np.asarray(model.length), np.asarray(model.inertia)
    masses = np.stack([straight_element_mass(Le, m) for Le, m in zip(lengths, inertia)])
    ve = np.concatenate([v[:, :-1], v[:, 1:]], axis=2)                    # (T, E, 12)
    kinetic = 0.5 * np.einsum("tei,eij,tej->t", ve, masses, ve)
    twists = element_twists(result, rod) if twists is None else twists
    eps = (twists - np.asarray(model.d0)) / lengths[:, None]
    strain = 0.5 * np.einsum("e,tei,ei,tei->t", lengths, eps, np.asarray(model.stiffness), eps)
    energy = kinetic + strain
    return work, energy - energy[0]


def helical_example(name: str, scene_name: str, doc: str, snapshot: bool = False,
                    animation: bool = False, fast_elements: int = 4) -> int:
    """Run one of the paper's helical-motion scenes (Figs. 5-8) and write its figures.

    Always: tip_displacements.png (tip x, y, z vs time), snapshots.png (the rod at 7
    instants, coloured by time), summary.json. ``snapshot``: snapshot_t3.png (the final
    state with ribbons and frame triads, Fig. 5); ``animation``: ``<name>.gif``. With
    ``--fast`` the rod gets ``fast_elements`` elements (same 3 s, dt 0.01 s). Returns the
    exit code (0 when every step converged)."""
    import simsoft_jax as sj
    from simsoft_jax import plotting

    args = parse_args(name, doc)
    scene = json.loads((SCENES / f"{scene_name}.json").read_text())
    if args.fast:
        scene["rods"][0]["elements"] = fast_elements
    result = sj.run(scene)
    rod = scene["rods"][0]["name"]
    length = float(np.sum(np.asarray(result.model.length)))
    tip = result.positions(rod)[:, -1]
    # arc length of each helical element = |d_U| of its relative twist (the paper's eq. 27)
    twists = element_twists(result, rod)
    arc = np.linalg.norm(twists[:, :, :3], axis=2).sum(axis=1)
    stretch = float(np.abs(arc / length - 1.0).max())
    work, energy = work_energy_balance(result, scene, rod, twists)
    balance = float(np.abs(work - energy).max() / np.abs(work).max())

    title = f"{scene_name} ({scene['rods'][0]['elements']} elements)"
    save(plotting.plot_result_tip(result, rod, title=f"tip displacements: {title}"),
         args.out, "tip_displacements.png")
    save(plotting.plot_result_snapshots(result, rod, 7, title=f"snapshots: {title}"),
         args.out, "snapshots.png")
    if snapshot:
        save(plotting.plot_result(result, rod, triads=True,
                                  title=f"t = {result.time[-1]:.1f} s: {title}"),
             args.out, "snapshot_t3.png")
    if animation:
        path = plotting.animate_result(result, rod, args.out / f"{name}.gif",
                                       max_frames=15 if args.fast else 61)
        print(f"wrote {path}")

    print(f"{title}: converged = {result.converged}, {result.newton_iterations} Newton "
          f"iterations, solve {result.wall_time_s:.2f} s (compile {result.compile_time_s:.1f} s)")
    print(f"tip at t = {result.time[-1]:g} s: {np.round(tip[-1], 5)} m; "
          f"largest |tip| components {np.round(np.abs(tip).max(axis=0), 5)} m")
    print(f"arm length within {stretch:.2e} of L = {length:g} m; work-energy balance: "
          f"max |W - E| / max |W| = {balance:.2e} (W(3 s) = {work[-1]:.4g} J)")
    write_summary(args.out, {
        "scene": scene_name, "elements": scene["rods"][0]["elements"],
        "converged": result.converged, "t_end_s": float(result.time[-1]),
        "dt_s": scene["solver"]["dt"], "length_m": length,
        "tip_final_m": tip[-1].tolist(), "tip_max_abs_m": np.abs(tip).max(axis=0).tolist(),
        "tip_finite": bool(np.all(np.isfinite(tip))), "max_length_change_rel": stretch,
        "work_final_J": float(work[-1]), "energy_final_J": float(energy[-1]),
        "energy_balance_rel": balance, "newton_iterations": result.newton_iterations})
    return 0 if result.converged else 1
