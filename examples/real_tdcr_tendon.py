"""Measured tendon-driven continuum robot (ISIR / PoliTo, low trust): tip height against
tendon pull, replayed with displacement-controlled tendons (statics).

    python examples/real_tdcr_tendon.py [--out out/real_tdcr_tendon] [--fast]

Data: simsoft_jax/data/real/tdcr_isir_nouredeen/tip_z_vs_tendon_pull_measured.csv (read its
README). A Nitinol tube backbone (free length 0.25 m, OD 1.220 mm, ID 0.954 mm,
E = 83 GPa "preliminary measured", nu = 0.33, rho = 6450 kg/m^3), upright (base at the
origin, backbone along +z, gravity -9.81 m/s^2 along -z), three tendons at 6 mm from the
backbone at 0, 120 and 240 degrees, one pulled at a time by 5 or 10 mm. The measured
quantity is the tip's height only (250 mm unloaded).

Model choices and caveats (stated by the data's README, kept here):
* the pull is commanded at the motor, not measured: tendon stretch, friction and slack
  are not modelled; the pull is applied as the pulled tendon's exact length change
  (``displacement``), the tension being the unknown; the two other tendons are loose
  (tension 0);
* the tendons run continuously at 6 mm (the model value; the disk holes measure
  7.0-7.2 mm); between the 11 spacer disks a real tendon runs straight, here it follows
  the backbone's curve;
* the disks' weight is unknown and left out (the backbone's own weight is in);
* one manual measurement per point: the README calls this a coarse (+-20 mm) check.

Printed: for every measured row, the measured tip height, the author's own model
(labelled NOT_MEASURED in the file), this model's, and the solved tension; the three
tendons give the same height by the robot's symmetry. Writes tip_heights.png,
summary.json and one scene file per row, ``tdcr_<t1>_<t2>_<t3>mm.toml`` (pulls in mm), the
names the shipped table map ``tdcr-tip-height`` reads the data's table into
(``simsoft-jax calibrate --table-map tdcr-tip-height``).
"""
import csv

import numpy as np

import simsoft_jax as sj
from simsoft_jax.data_files import data_path

from _common import parse_args, save, write_summary

DATA = data_path("real", "tdcr_isir_nouredeen", "tip_z_vs_tendon_pull_measured.csv")
LENGTH, OFFSET = 0.25, 6e-3
ANGLES_DEG = (0.0, 120.0, 240.0)


def measured_rows(path=DATA):
    """The CSV rows: pulls (3,) m, measured tip height m, the author's model (m)."""
    with open(path, newline="", encoding="utf-8") as fh:
        for row in csv.DictReader(fh):
            pulls = np.array([float(row[f"pull_t{k}_m"]) for k in (1, 2, 3)])
            yield (pulls, float(row["z_tip_measured_m"]),
                   float(row["z_tip_author_model_mm_NOT_MEASURED"]) * 1e-3)


def _tendon(k, pull):
    """Tendon k: displacement-controlled when pulled; a tendon left alone is loose, so it
    carries no tension (holding its length would make it take up the bending)."""
    angle = np.radians(ANGLES_DEG[k])
    control = {"displacement": -float(pull)} if pull > 0 else {"tension": 0.0}
    return {"name": f"t{k + 1}", "rod": "backbone", "from_node": 0, "to_node": -1,
            "offset": [OFFSET * np.cos(angle), OFFSET * np.sin(angle)], **control}


def scene_name(pulls):
    """``tdcr_<t1>_<t2>_<t3>mm``, the pulls (3,) m in whole millimetres: the scene names
    the shipped table map ``tdcr-tip-height`` gives the data's rows."""
    return "tdcr_" + "_".join(f"{1e3 * p:.0f}" for p in pulls) + "mm"


def scene(pulls, elements):
    """The upright robot with the three tendons pulled by ``pulls`` (3,) m."""
    return {
        "name": scene_name(pulls),
        "solver": {"kind": "static", "load_steps": 20},
        "gravity": {"vector": [0.0, 0.0, -9.81]},
        "materials": [{"name": "nitinol", "E": 83e9, "nu": 0.33, "density": 6450.0}],
        "rods": [{"name": "backbone", "material": "nitinol", "elements": elements,
                  "section": {"shape": "tube", "outer_diameter": 1.22e-3,
                              "inner_diameter": 0.954e-3},
                  "geometry": {"kind": "straight", "length": LENGTH},
                  # section frame: local x (the backbone) along world +z
                  "base": {"position": [0.0, 0.0, 0.0],
                           "rotation": {"axis": [0.0, 1.0, 0.0], "angle_deg": -90.0}}}],
        "constraints": [{"kind": "clamp", "rod": "backbone", "node": 0}],
        "tendons": [_tendon(k, pulls[k]) for k in range(3)],
    }


def main():
    args = parse_args("real_tdcr_tendon", __doc__)
    elements = 8 if args.fast else 24
    rows = list(measured_rows())
    table = []
    for pulls, z_measured, z_author in rows:
        robot = sj.Scene.from_dict(scene(pulls, elements))
        sj.save_scene(robot, args.out / f"{robot.name}.toml")
        result = sj.run(robot, stability=False)
        tip = result.positions("backbone")[-1]
        tensions = [result.tendon_tension(f"t{k}") for k in (1, 2, 3)]
        table.append({"pull_m": pulls.tolist(), "z_measured_m": z_measured,
                      "z_author_model_m": z_author, "z_model_m": float(tip[2]),
                      "tip_m": tip.tolist(), "tensions_N": tensions,
                      "converged": result.converged, "slack": list(result.slack_tendons)})
        print(f"pull {np.round(pulls * 1e3, 1)} mm: tip z measured {z_measured * 1e3:5.0f} mm,"
              f" author's model {z_author * 1e3:6.1f} mm, this model {tip[2] * 1e3:6.1f} mm, "
              f"tensions {np.round(tensions, 3)} N, converged {result.converged}")
    pulled = [r for r in table if max(r["pull_m"]) > 0]
    misfit = [r["z_model_m"] - r["z_measured_m"] for r in pulled]
    print(f"model - measured over the {len(pulled)} pulled rows: mean {np.mean(misfit) * 1e3:.1f}"
          f" mm, largest {np.max(np.abs(misfit)) * 1e3:.1f} mm (the data's README: +-20 mm)")

    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(5, 3.5))
    pull = [max(r["pull_m"]) * 1e3 for r in table]
    ax.plot(pull, [r["z_measured_m"] * 1e3 for r in table], "ko", label="measured")
    ax.plot(pull, [r["z_author_model_m"] * 1e3 for r in table], "s", mfc="none",
            label="author's model (not measured)")
    ax.plot(pull, [r["z_model_m"] * 1e3 for r in table], "x", label="simsoft_jax")
    ax.set(xlabel="tendon pull (mm)", ylabel="tip height (mm)",
           title="TDCR (ISIR): tip height vs pull")
    ax.legend(fontsize="small")
    save(fig, args.out, "tip_heights.png")
    write_summary(args.out, {"elements": elements, "rows": table,
                             "converged": all(r["converged"] for r in table),
                             "misfit_mean_m": float(np.mean(misfit)),
                             "misfit_max_m": float(np.max(np.abs(misfit)))})
    return 0 if all(r["converged"] for r in table) else 1


if __name__ == "__main__":
    raise SystemExit(main())
