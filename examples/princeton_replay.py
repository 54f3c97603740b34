"""Princeton beam replay (the paper's Figs. 15-18): the 25 load cases in one vmapped call.

    python examples/princeton_replay.py [--out DIR] [--fast] [--data CSV]

1. The paper's 25 cases (f0 = 4.448 N; root pitched by theta, vertical tip weight and
   gravity), deflections along the beam at r/L = 0.25, 0.5, 0.75, 1: Fig. 15 and a table.
   The measured Princeton data are not available here (simsoft_jax/data/princeton/README.md),
   so the paper's error figures cannot be recomputed against the experiment.
2. In their place, eq. (112) at the tip against the ANSYS solid-element (3-D elasticity)
   predictions of the same geometry (no gravity, 2 and 3 lbf dead tip loads at 0-90 deg),
   with the paper's section constants: Figs. 16-18 of that comparison. The ANSYS set-up
   (shear coefficients 1, a torsion stiffness factor) differs from the paper's section, so
   the errors measure the beam model against 3-D elasticity, not against the experiment.
"""
from pathlib import Path

import numpy as np

from _common import parse_args, write_summary

from simsoft_jax.apps import princeton as pr
from simsoft_jax.apps import princeton_figures as figs
from simsoft_jax.data_files import data_path

DATA = data_path("princeton", "model_predictions_tip.csv")


def main() -> int:
    args = parse_args("princeton_replay", __doc__, lambda parser: parser.add_argument(
        "--data", type=Path, default=DATA, help="model_predictions_tip.csv (default %(default)s)"))
    elements = 8 if args.fast else 16
    sim = pr.replay(elements=elements)
    pr.write_table(args.out / "princeton_replay.csv", sim)
    figs.deflections(sim, args.out / "princeton_fig15_deflections.png")
    print(f"replay: {len(sim.theta_deg)} cases, {elements} elements, all converged "
          f"{bool(sim.converged.all())}, Newton iterations per case {sim.iterations.min()}-"
          f"{sim.iterations.max()}")
    for th in np.unique(sim.theta_deg):
        sel = sim.theta_deg == th
        print(f"  theta {th:4g} deg: tip (y, z) at the largest load "
              f"{np.round(1e3 * sim.deflection[sel][-1, -1], 2)} mm")
    summary = {"elements": elements, "converged": bool(sim.converged.all()),
               "theta_deg": sim.theta_deg.tolist(), "load_N": sim.load_N.tolist(),
               "tip_deflection_m": sim.deflection[:, -1].tolist()}
    err = pr.errors(pr.read_published_tip(args.data), elements=elements, gravity=False)
    out = args.out / "vs_ansys_solid"
    out.mkdir(exist_ok=True)
    pr.write_table(out / "tip_errors.csv", err.replay, err)
    figs.station_errors(err, out / "fig16_errors.png")
    figs.summary(err, out / "fig17_mean_errors.png")
    figs.summary(err, out / "fig18_error_spread.png", spread=True)
    print(f"vs ANSYS solid (no gravity, 14 tip cases): eq. (112) tip error mean "
          f"{err.tip.mean():.3f} %, max {err.tip.max():.3f} %")
    summary["ansys_tip_error_percent"] = err.tip.tolist()
    write_summary(args.out, summary)
    return 0 if sim.converged.all() else 1


if __name__ == "__main__":
    raise SystemExit(main())
