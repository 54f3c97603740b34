"""Quadrature rules on [0, 1] (plain NumPy; evaluated once when a Model is built)."""
from __future__ import annotations

import numpy as np


def gauss_rule(q: int):
    """Gauss-Legendre points and weights (q,) on [0, 1]: exact for polynomials of degree
    ``2 q - 1`` (points ``(1 + x_i) / 2`` and weights ``w_i / 2`` of the rule on [-1, 1])."""
    x, w = np.polynomial.legendre.leggauss(q)
    return 0.5 * (1.0 + x), 0.5 * w
