"""Figures of the Princeton replay in the layout of the paper's Figs. 15-18 (matplotlib).

* Fig. 15: deflections y (flapwise) and z (edgewise) along the beam, one panel per angle,
  simulated lines and measured markers;
* Fig. 16: errors e_i (eq. 112) at each station, one panel per angle, one line per load;
* Fig. 17: per angle, the mean over loads of e_mu and of the tip error;
* Fig. 18: per angle, the standard deviation over loads of the same two errors.
Imported lazily by the CLI; the solvers never import matplotlib.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .princeton import Errors, Replay


def _pyplot():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def _panels(plt, angles):
    cols = min(4, len(angles))
    rows = int(np.ceil(len(angles) / cols))
    fig, axes = plt.subplots(rows, cols, figsize=(3.4 * cols, 2.9 * rows), squeeze=False)
    for ax in axes.ravel()[len(angles):]:
        ax.set_visible(False)
    return fig, axes.ravel()


def deflections(replay: Replay, path, measured: np.ndarray | None = None):
    """Fig. 15: ``replay`` deflections (mm) vs station (m); ``measured`` (C, S, 2) optional."""
    plt = _pyplot()
    angles = np.unique(replay.theta_deg)
    fig, axes = _panels(plt, angles)
    stations = np.concatenate([[0.0], replay.stations_m])
    for ax, th in zip(axes, angles):
        for c in np.flatnonzero(replay.theta_deg == th):
            color = None
            for k, style in ((0, "-"), (1, "--")):
                curve = np.concatenate([[0.0], 1e3 * replay.deflection[c, :, k]])
                line, = ax.plot(stations, curve, style, lw=1.2, color=color,
                                label=f"{replay.load_N[c]:.3g} N" if k == 0 else None)
                color = line.get_color()
                if measured is not None:
                    ax.plot(replay.stations_m, 1e3 * measured[c, :, k], "o" if k == 0 else "s",
                            ms=4, mfc="none", color=color)
        ax.set_title(f"theta = {th:g} deg")
        ax.set_xlabel("r [m]")
        ax.set_ylabel("deflection [mm]")
        ax.legend(fontsize=7)
    fig.suptitle("Princeton beam: y (solid) and z (dashed) deflections; tip loads in N"
                 + ("; markers: measured" if measured is not None else ""))
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return Path(path)


def station_errors(errors: Errors, path):
    """Fig. 16: per load case the mean error e_mu (%) with e_sigma as error bar, grouped
    by loading angle (:func:`simsoft_jax.plotting.plot_error_bars`)."""
    from ..plotting import plot_error_bars
    plt = _pyplot()
    angles = np.unique(errors.theta_deg)
    rows = [np.flatnonzero(errors.theta_deg == th) for th in angles]
    longest = max(rows, key=len)
    labels = [f"load {k + 1}" for k in range(len(longest))]
    fig = plot_error_bars([f"{th:g}" for th in angles], [errors.e_mu[r] for r in rows],
                          [errors.e_sigma[r] for r in rows], case_labels=labels,
                          title="Princeton beam: eq. (112) errors per load case (increasing load)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return Path(path)


def summary(errors: Errors, path, spread: bool = False):
    """Fig. 17 (``spread=False``: means) or Fig. 18 (``spread=True``: standard deviations)
    of e_mu and of the tip error per angle."""
    plt = _pyplot()
    angles = sorted(errors.by_angle)
    stats = np.array([errors.by_angle[a] for a in angles])
    mean_col, tip_col = (1, 3) if spread else (0, 2)
    x = np.arange(len(angles))
    fig, ax = plt.subplots(figsize=(6, 3.5))
    ax.bar(x - 0.2, stats[:, mean_col], 0.4, label="mean error e_mu")
    ax.bar(x + 0.2, stats[:, tip_col], 0.4, label="tip error e_4")
    ax.set_xticks(x, [f"{a:g}" for a in angles])
    ax.set_xlabel("theta [deg]")
    ax.set_ylabel(("std of " if spread else "") + "error [%]")
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return Path(path)


def all_figures(replay: Replay, out, errors: Errors | None = None) -> list[Path]:
    """Write Fig. 15 (and Figs. 16-18 when ``errors`` is given) into folder ``out``."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    if errors is None:
        return [deflections(replay, out / "princeton_fig15_deflections.png")]
    return [deflections(errors.replay, out / "princeton_fig15_deflections.png", errors.measured),
            station_errors(errors, out / "princeton_fig16_errors.png"),
            summary(errors, out / "princeton_fig17_mean_errors.png"),
            summary(errors, out / "princeton_fig18_error_spread.png", spread=True)]
