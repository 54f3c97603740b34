"""What a calibration can tell: parameter uncertainty and identifiability from the
Gauss-Newton information matrix, and held-out errors per measured quantity.

For normalized residuals ``r = (predicted - value) / std`` (rows of the data, then the
prior rows) and log scales ``x``, the Gauss-Newton information matrix is ``F = J^T J``
(``J = dr/dx``, (n, P)) and the covariance of the fitted log scales ``C = s^2 F^-1``,
``s^2 = 1`` when the rows carry their measurement std, else the residual variance
``|r|^2 / (n - P)`` (Bates & Watts 1988, ch. 2). The standard deviation of a scale
``exp(x_j)`` is ``exp(x_j) sqrt(C_jj)`` (delta method), the correlations
``C_jk / sqrt(C_jj C_kk)``.

Identifiability is read from the eigen-decomposition of the scaled information matrix
``F_s = D^-1/2 F D^-1/2`` (``D = diag F``, unit diagonal, so that the test does not depend
on the parameters' units): an eigenvalue below :data:`SINGULAR` means that a combination of
the parameters (its eigenvector) changes no prediction: the groups with weight in it cannot
be told apart. A parameter whose log scale has a standard deviation above
:data:`LOOSE` (its factor uncertain by more than e^0.5 = 1.65x) is flagged as poorly
determined.
"""
from __future__ import annotations

from typing import NamedTuple, Sequence

import numpy as np

SINGULAR = 1e-10     # smallest eigenvalue of the scaled information matrix
LOOSE = 0.5          # standard deviation of a log scale above which a group is flagged


class Information(NamedTuple):
    """covariance (P,P) of the log scales; std_log (P,) (inf for an unidentifiable
    group); correlation (P,P); eigenvalues (P,) of the scaled information matrix
    (ascending); unidentified: labels of the groups the data cannot determine (singular
    or loose); message: why, in words ("" when every group is determined)."""
    covariance: np.ndarray
    std_log: np.ndarray
    correlation: np.ndarray
    eigenvalues: np.ndarray
    unidentified: tuple
    message: str


def information(J, variance: float, labels: Sequence[str]) -> Information:
    """The :class:`Information` of a fit from ``J`` (n, P) of its normalized residuals
    (data and prior rows) and the noise ``variance`` (module docstring)."""
    J = np.asarray(J, float)
    F = J.T @ J
    d = np.diag(F).copy()
    none = d <= 0.0
    scale = np.where(none, 1.0, np.sqrt(np.where(none, 1.0, d)))
    Fs = F / np.outer(scale, scale)
    Fs[none, :], Fs[:, none] = 0.0, 0.0
    w, V = np.linalg.eigh(Fs)
    singular = w < SINGULAR * max(w.max(), 1e-300)
    covariance = variance * np.linalg.pinv(Fs) / np.outer(scale, scale)
    sd = np.sqrt(np.maximum(np.diag(covariance), 0.0))
    correlation = covariance / np.maximum(np.outer(sd, sd), 1e-300)
    weight = np.abs(V[:, singular]).max(axis=1) if singular.any() else np.zeros(len(d))
    lost = none | (weight > 0.1)
    sd = np.where(lost, np.inf, sd)
    loose = ~lost & (sd > LOOSE)
    parts = []
    for k in np.flatnonzero(singular):
        members = [f"{v:+.2f} {labels[j]}" for j, v in enumerate(V[:, k]) if abs(v) > 0.1]
        parts.append("the data cannot identify " + (
            f"group {labels[int(np.argmax(np.abs(V[:, k])))]!r} (no prediction depends on it)"
            if len(members) == 1 else
            "the groups " + ", ".join(repr(labels[j]) for j in np.flatnonzero(np.abs(V[:, k]) > 0.1))
            + " separately: changing their log scales along (" + ", ".join(members)
            + ") changes no prediction")
            + f" (scaled information eigenvalue {w[k]:.2g})")
    if loose.any():
        parts.append("poorly determined: " + ", ".join(
            f"{labels[j]!r} (std of the log scale {sd[j]:.3g})" for j in np.flatnonzero(loose)))
    if parts:
        parts.append("fix or merge these groups, measure what separates them, or give a "
                     "prior (Group.prior, smoothness)")
    return Information(covariance, sd, correlation, w,
                       tuple(labels[j] for j in np.flatnonzero(lost | loose)), "; ".join(parts))


def determined(J, variance: float) -> tuple[np.ndarray, np.ndarray]:
    """``(Pi (P,P), V (P,k))``: the orthogonal projector onto the combinations of the log
    scales the data determine, and the k undetermined directions (unit columns). From the
    eigen-decomposition ``F = sum_k lam_k v_k v_k^T`` of the information ``F = J^T J``
    (log scales are dimensionless, so F needs no scaling): a direction is undetermined
    when its standard deviation ``sqrt(variance / lam_k)`` exceeds :data:`LOOSE` or
    ``lam_k`` is below :data:`SINGULAR` times the largest (the criteria of
    :func:`information`, per direction). The fit confines its steps to ``Pi``
    (:func:`simsoft_jax.studies.least_squares.least_squares`, ``subspace``)."""
    J = np.nan_to_num(np.asarray(J, float))
    w, V = np.linalg.eigh(J.T @ J)
    loose = (w < SINGULAR * max(w.max(), 1e-300)) | (variance > LOOSE ** 2 * np.maximum(w, 1e-300))
    keep = V[:, ~loose]
    return keep @ keep.T, V[:, loose]


def metrics(obs, predicted) -> dict:
    """Errors of ``predicted`` (n,) against the rows of ``obs`` per quantity:
    ``{quantity: {"n", "rms", "max_abs", "mean", "rms_over_std"}}`` in the quantity's unit
    (m or rad; rms_over_std dimensionless)."""
    err = np.asarray(predicted, float) - obs.value
    quantity = np.array([r.quantity for r in obs.rows])
    out = {}
    for q in dict.fromkeys(quantity):
        sel = quantity == q
        e = err[sel]
        out[str(q)] = {"n": int(sel.sum()), "rms": float(np.sqrt(np.mean(e ** 2))),
                       "max_abs": float(np.abs(e).max()), "mean": float(e.mean()),
                       "rms_over_std": float(np.sqrt(np.mean((e / obs.std[sel]) ** 2)))}
    return out
