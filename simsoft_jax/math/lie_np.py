"""NumPy twins of the rotation maths of :mod:`simsoft_jax.math.lie`, for the host side
that reads scenes and builds models (plain NumPy: the scene layer imports no JAX)."""
from __future__ import annotations

import math

import numpy as np


def skew(w):
    """Skew matrices ``skew(w) @ y = w x y`` of the rows of ``w`` (..., 3) -> (..., 3, 3)
    (the paper's eq. 115, spec S1)."""
    w = np.asarray(w, float)
    z = np.zeros(w.shape[:-1])
    return np.stack([np.stack([z, -w[..., 2], w[..., 1]], -1),
                     np.stack([w[..., 2], z, -w[..., 0]], -1),
                     np.stack([-w[..., 1], w[..., 0], z], -1)], -2)


def exp_so3(rotvec) -> np.ndarray:
    """Rotation matrix (3,3) of a rotation vector (3,) (Rodrigues, spec S5):
    ``R = I + sin(a)/a K + (1 - cos a)/a^2 K^2`` with ``K = skew(rotvec)``, ``a = |rotvec|``;
    its series below 1e-8 rad."""
    rotvec = np.asarray(rotvec, dtype=float)
    angle = float(np.linalg.norm(rotvec))
    K = skew(rotvec)
    if angle < 1e-8:  # series: sin(a)/a -> 1, (1 - cos a)/a^2 -> 1/2
        return np.eye(3) + K + 0.5 * K @ K
    return np.eye(3) + math.sin(angle) / angle * K + (1.0 - math.cos(angle)) / angle**2 * K @ K
