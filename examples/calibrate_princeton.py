"""Calibrating section stiffness from positions: identifiability (a) and a held-out test (b).

    python examples/calibrate_princeton.py [--out DIR] [--fast] [--data CSV]

a) Identifiability: node positions of the Princeton beam (no gravity, seven load angles,
   four stations) simulated with EI_y, EI_z, GJ scaled by (1.2, 0.85, 1.1), plus noise of
   1 % of the rms deflection, are fitted from the paper's values by L-BFGS through the
   implicit-function gradients; the fitted factors are compared with the truth and the
   Gauss-Newton standard deviations.
b) The ANSYS solid-element predictions (3-D elasticity, simsoft_jax/data/princeton) used as
   measurements: EI_y, EI_z, GJ fitted on theta = 0, 30, 60, 90 deg (2 and 3 lbf), and
   the eq. (112)-style tip error on the held-out 15, 45, 75 deg cases before and after.
Figures: loss histories, and held-out errors before/after.
"""
from pathlib import Path

import jax.numpy as jnp
import matplotlib.pyplot as plt
import numpy as np

from _common import parse_args, save, write_summary

import simsoft_jax as sj
from simsoft_jax.studies import calibration as cal
from simsoft_jax.apps import princeton as pr
from simsoft_jax.data_files import data_path

DATA = data_path("princeton", "model_predictions_tip.csv")
NAMES = ("EIy", "EIz", "GJ")
TRUE = np.array([1.2, 0.85, 1.1])


def identifiability(beam, nodes):
    """3a: synthetic positions from known factors, 1 % noise; returns the Fit."""
    cases = [(0.0, 4.0), (15.0, 4.0), (30.0, 4.0), (45.0, 3.0), (60.0, 2.0), (75.0, 1.5), (90.0, 1.5)]
    models = [pr.case_model(beam, th, k * pr.F0) for th, k in cases]
    exact = [np.asarray(sj.solve_static(cal.apply_scales(m, NAMES, jnp.log(TRUE))).p[nodes])
             for m in models]
    sigma = 0.01 * np.sqrt(np.mean(np.concatenate([p - np.asarray(beam.p0[nodes]) for p in exact]) ** 2))
    rng = np.random.default_rng(0)
    targets = [cal.StaticTarget(m, nodes, p + sigma * rng.standard_normal(p.shape),
                                np.ones(p.shape, bool)) for m, p in zip(models, exact)]
    return cal.fit_static(targets, NAMES), sigma


def main() -> int:
    args = parse_args("calibrate_princeton", __doc__, lambda parser: parser.add_argument(
        "--data", type=Path, default=DATA, help="model_predictions_tip.csv (default %(default)s)"))
    elements = 8 if args.fast else 16
    beam = sj.build_model(pr.scene(elements, gravity=False))
    nodes = np.arange(1, 5) * elements // 4
    fit_a, sigma = identifiability(beam, nodes)
    print(f"3a) noise {1e3 * sigma:.3f} mm; fitted factors vs truth:")
    for name, s, sd, t in zip(NAMES, fit_a.scale, fit_a.std, TRUE):
        print(f"   {name:>3s}: {s:.4f} +- {sd:.4f} (truth {t}; |error| = {abs(s - t) / sd:.2f} sigma)")
    summary = {"elements": elements, "identifiability": {
        "true": TRUE.tolist(), "fitted": fit_a.scale.tolist(), "std": fit_a.std.tolist(),
        "iterations": fit_a.iterations, "rms_m": fit_a.rms, "noise_m": sigma}}
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.6))
    axes[0].semilogy(fit_a.loss_history, "o-")
    axes[0].set(title="3a) synthetic, 1 % noise", xlabel="L-BFGS step", ylabel="loss 0.5 |r|^2 [m^2]")

    measured = pr.read_published_tip(args.data)
    train_rows = np.isin(measured.theta_deg, (0, 30, 60, 90))
    pick = lambda rows: pr.Measurements(*(a[rows] for a in measured))  # noqa: E731
    train = pr.calibration_targets(pick(train_rows), beam)
    held = pr.calibration_targets(pick(~train_rows), beam)
    fit_b = cal.fit_static(train, NAMES)
    error = lambda scale: 100 * np.abs(cal.evaluate(held, NAMES, scale)).reshape(-1, 2).sum(1) / pr.LENGTH  # noqa: E731
    before, after = error(None), error(fit_b.scale)
    print("3b) fitted to ANSYS solid on 0/30/60/90 deg: "
          + ", ".join(f"{n} = {fit_b.values[n]:.4g} (x{s:.3f})" for n, s in zip(NAMES, fit_b.scale)))
    print(f"    held-out tip error (15/45/75 deg): mean {before.mean():.3f} % -> "
          f"{after.mean():.3f} %, max {before.max():.3f} % -> {after.max():.3f} %")
    summary["ansys_held_out"] = {"fitted_scale": fit_b.scale.tolist(), "values": fit_b.values,
                                 "error_before_percent": before.tolist(),
                                 "error_after_percent": after.tolist()}
    axes[1].semilogy(fit_b.loss_history, "o-", label="training loss")
    ax2 = axes[1].inset_axes([0.45, 0.45, 0.5, 0.5])
    x = np.arange(len(before))
    ax2.bar(x - 0.2, before, 0.4, label="before")
    ax2.bar(x + 0.2, after, 0.4, label="after")
    ax2.set_title("held-out tip error [%]", fontsize=8)
    ax2.legend(fontsize=7)
    axes[1].set(title="3b) ANSYS solid as measurements", xlabel="L-BFGS step", ylabel="loss [m^2]")
    save(fig, args.out, "calibration.png")
    write_summary(args.out, summary)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
