"""Pazy wing (Technion) tip-mass sweep: the beam model built from the data files, its
predictions against the published UM/NAST beam model and the measurements, and a
command-line calibration of flap and torsional stiffness on half the tip masses with a
prediction of the other half.

Data: ``simsoft_jax/data/real/pazy_wing_technion`` (read its README for the set-up and caveats).
Model, from the files only:

* 15 elements on the reference axis (44 % chord, 0.5498 m), one per data element, with
  the data's unequal station spacing (13 of 38.25 mm, then 33.47 and 19.13 mm; segment
  ``length``) so that properties and masses sit where the data put them; its
  4x4 stiffness ``[extension, twist, flap, edgewise]`` (K11..K44 with couplings) becomes
  the 6x6 section matrix by :func:`simsoft_jax.scene.section_tables.read_stiffness_table` (as
  :func:`simsoft_jax.scene.sections.beam4_stiffness` maps it; shear-rigid data:
  its default GA = 100 EA keeps shear strains negligible, below 1e-8 here; the tip
  deflection moves by 4e-8 of itself from GA = 1e4 EA, while the static solves take 4x
  fewer Newton iterations). Frames: world = the Nastran frame of the
  data (X aft along the chord, Y spanwise, Z up); the rod's local x is +Y, local y = -X
  (towards the leading edge), local z = +Z, so flap bending is ``kappa_y`` and a positive
  rotation about local x lifts the leading edge (nose up, the data's positive twist).
* the 16 lumped masses of ``beam_inertia_skin*.csv`` as ``[[masses]]`` at the nodes with
  their centre-of-gravity offsets (:func:`simsoft_jax.scene.section_tables.read_mass_table`,
  frame map ``("-y", "x", "z")``) (their inertias do not enter statics); the rod's own
  rhoA is negligible (1e-9 kg/m);
* gravity 9.80665 m/s^2; the tip mass hangs at the mid-chord (6 % chord = 6 mm aft of the
  axis, chord 0.1 m) for the bending test, and 0.04 m (skin off) / 0.08 m (skin on) behind
  the trailing edge for the torsion test: a world force at an offset point (load
  ``offset``) that turns with the tip section;
* results relative to the unloaded (self-weight) state, as measured: deflection at the
  mid-chord point of the tip; twist as the test reads it from the heights of the leading
  and trailing edges: the change of the tip chord's angle above the horizontal
  (observation quantity ``tilt_y``; the chord is the section's y axis). The rotation about
  the tip section's own axis (``twist``) is larger by about ``1/cos`` of the tip slope: 15 %
  at the 2.8 kg torsion case, whose tip slope is 42 deg.

The script writes the scene files (TOML), an observation file (mid-chord deflections and
tip twists relative to the unloaded state, measurement std 0.5 mm / 0.1 deg, a guess:
the data give none; columns test, skin, tip_mass) and, per skin, runs ``simsoft-jax
calibrate --hold-out-by tip_mass --within test``: flap and torsion stiffness fitted on the
lighter half of each sweep's tip masses, the heavier half predicted (extrapolation).
"""
from __future__ import annotations

import csv
import json
import sys
from pathlib import Path

import numpy as np

from _common import parse_args, write_summary

import simsoft_jax as sj
from simsoft_jax.data_files import data_path
from simsoft_jax.studies import observation_splits as splits
from simsoft_jax.studies.calibration_groups import groups_from_dict, parse_groups, predict
from simsoft_jax.studies.calibration_report import metrics
from simsoft_jax.cli import main as cli
from simsoft_jax.studies.measurements import observation_set
from simsoft_jax.scene.section_tables import read_mass_table, read_stiffness_table

DATA = data_path("real", "pazy_wing_technion")
G = 9.80665
CHORD = 0.1
AXIS = 0.44          # reference axis, fraction of the chord from the leading edge
BEHIND_TE = {0: 0.04, 1: 0.08}
HEADER = "scene,rod,node,offset_x,offset_y,offset_z,quantity,value,std,reference,test,skin,tip_mass\n"


def read_csv(name):
    with open(DATA / name, newline="") as handle:
        return list(csv.DictReader(handle))


def wing_scene(skin: int, test: str, mass: float) -> dict:
    """Scene dictionary of the wing with ``mass`` kg hung for ``test``."""
    # the 4x4 data's strain axes are the section's (identity frame map)
    stiffness = read_stiffness_table(DATA / f"beam_stiffness_skin{skin}.csv")
    # Nastran (X aft, Y span, Z up) -> section frame (x = Y, y = -X, z = Z)
    masses = read_mass_table(DATA / f"beam_inertia_skin{skin}.csv", frame=("-y", "x", "z"))
    axis = read_csv("beam_reference_axis_nodes.csv")
    stations = np.array([float(r["y_m_spanwise"]) for r in axis])
    span = float(stations[-1])
    segments = [{"elements": 1, "length": float(length), "stiffness": {"matrix": K.tolist()},
                 "inertia": {"rhoA": 1e-9, "rhoJ": 0.0, "rhoIy": 0.0, "rhoIz": 0.0}}
                for K, length in zip(stiffness, np.diff(stations))]
    aft = (0.5 - AXIS) * CHORD if test == "bending" else (
        (1.0 - AXIS) * CHORD + BEHIND_TE[skin])
    return {
        "name": f"{test}_skin{skin}_{mass:.1f}kg",
        "solver": {"kind": "static", "tolerance": 1e-10},
        "gravity": {"vector": [0.0, 0.0, -G]},
        "rods": [{"name": "wing", "geometry": {"kind": "straight", "length": span},
                  "base": {"rotation": [0.0, 0.0, np.pi / 2]}, "segments": segments}],
        "constraints": [{"kind": "clamp", "rod": "wing", "node": 0}],
        "masses": masses.scene_masses("wing"),
        "loads": [{"kind": "force", "rod": "wing", "node": -1, "vector": [0.0, 0.0, -G * mass],
                   "offset": [0.0, -aft, 0.0]}],
    }


def observation_rows(cases, value=None):
    """Rows: mid-chord tip deflection (uz) and tip twist, relative to the 0 kg case, with
    the columns test, skin and tip_mass (kg) for splits."""
    mid = -(0.5 - AXIS) * CHORD
    rows = []
    for test, skin, mass, uz, twist in cases:
        ref = f"{test}_skin{skin}_0.0kg"
        name = f"{test}_skin{skin}_{mass:.1f}kg"
        tags = f"{test},{skin},{mass!r}"
        rows.append(f"{name},wing,-1,0,{mid},0,uz,{uz!r},0.0005,{ref},{tags}")
        if twist is not None:
            rows.append(f"{name},wing,-1,,,,tilt_y,{float(np.radians(twist))!r},"
                        f"{float(np.radians(0.1))!r},{ref},{tags}")
    return rows


def main():
    args = parse_args("real_pazy_wing", __doc__)
    measured = [r for r in read_csv("tip_mass_sweep_measured.csv")]
    model_rows = {(r["test"], int(r["skin"]), round(float(r["tip_mass_kg"]), 3)): r
                  for r in read_csv("tip_mass_sweep_UMNAST_model_NOT_MEASURED.csv")}
    cases = []
    for r in measured:
        mass = float(r["tip_mass_kg"])
        if mass == 0.0:
            continue
        if args.fast and not (int(r["skin"]) == 0 and mass in (1.0, 2.0)):
            continue
        twist = float(r["tip_twist_deg"]) if r["tip_twist_deg"] else None
        cases.append((r["test"], int(r["skin"]), mass, float(r["tip_uz_m"]), twist))
    names = {(t, s, m) for t, s, m, *_ in cases} | {(t, s, 0.0) for t, s, *_ in cases}
    scenes = [sj.Scene.from_dict(wing_scene(s, t, m)) for t, s, m in sorted(names)]
    paths = []
    for scene in scenes:
        paths.append(str(args.out / f"{scene.name}.toml"))
        sj.save_scene(scene, paths[-1])
    rows = observation_rows(cases)
    obs_path = args.out / "observations.csv"
    obs_path.write_text(HEADER + "\n".join(rows) + "\n")

    # forward model: the files' properties, no fit
    obs = observation_set(obs_path, scenes)
    pred = predict(obs, parse_groups("EIy"))
    table, vs_model, vs_test = [], [], []
    for row, p in zip(obs.rows, pred):
        test, skin, mass = row.scene.split("_")[0], int(row.scene[-7]), float(row.scene.split("_")[2][:-2])
        ref = model_rows.get((test, skin, round(mass, 3)))
        col = "tip_uz_m" if row.quantity == "uz" else "tip_twist_deg"
        published = None
        if ref is not None and ref[col]:
            published = float(ref[col]) if row.quantity == "uz" else np.radians(float(ref[col]))
            vs_model.append((row.quantity, (p - published) / abs(published)))
        vs_test.append((row.quantity, p - row.value))
        table.append((row.scene, row.quantity, p, published, row.value))
    print(f"{'case':>22s} {'qty':>5s} {'simsoft':>10s} {'UM/NAST':>10s} {'measured':>10s}")
    for name, q, p, pub, m in table:
        f = (lambda v: f"{v:10.5f}") if q == "uz" else (lambda v: f"{np.degrees(v):10.3f}")
        print(f"{name:>22s} {q:>5s} {f(p)} {f(pub) if pub is not None else ' ' * 10} {f(m)}")
    rel = {q: max(abs(e) for qq, e in vs_model if qq == q) for q in ("uz", "tilt_y")
           if any(qq == q for qq, _ in vs_model)}
    err = {q: float(np.sqrt(np.mean([e**2 for qq, e in vs_test if qq == q])))
           for q in ("uz", "tilt_y") if any(qq == q for qq, _ in vs_test)}
    print("largest relative difference to the UM/NAST model: "
          + ", ".join(f"{q} {100 * v:.2f} %" for q, v in rel.items()))
    print("rms error against the measurements: "
          + ", ".join(f"{q} {v * (1e3 if q == 'uz' else np.degrees(1)):.3g} "
                      f"{'mm' if q == 'uz' else 'deg'}" for q, v in err.items()))

    # the command line alone, per skin: calibrate flap and torsion stiffness on the lighter
    # half of the tip masses (per test) and predict the heavier half
    extrapolation, status = {}, 0
    for skin in sorted({c[1] for c in cases}):
        mine = [s for s in scenes if s.name.split("_")[1] == f"skin{skin}"]
        skin_paths = [str(args.out / f"{s.name}.toml") for s in mine]
        obs_skin = args.out / f"observations_skin{skin}.csv"
        obs_skin.write_text(HEADER + "\n".join(observation_rows(
            [c for c in cases if c[1] == skin])) + "\n")
        fitted = args.out / f"fitted_skin{skin}.json"
        cal = ["calibrate", "--scenes", *skin_paths, "--measurements", str(obs_skin),
               "--params", "EIy,GJ=0.5:2", "--hold-out-by", "tip_mass", "--within", "test",
               "-o", str(fitted)]
        print("simsoft-jax " + " ".join(cal[:1] + ["--scenes", "...",
                                                     *cal[2 + len(skin_paths):]]))
        status = status or cli(cal)
        groups, scale = groups_from_dict(json.loads(fitted.read_text()))
        obs = observation_set(obs_skin, mine)
        upper = splits.lower_upper(obs, "tip_mass", within="test")[1]
        if upper.any():
            held = obs.subset(upper)
            extrapolation[f"skin{skin}"] = {
                "scale": scale.tolist(),
                "held_out": metrics(held, predict(held, groups, scale))}
    write_summary(args.out, {"max_relative_difference_to_UMNAST": rel,
                             "rms_error_vs_measured": err, "lighter_to_heavier": extrapolation,
                             "cli_status": status})
    return status


if __name__ == "__main__":
    sys.exit(main())
