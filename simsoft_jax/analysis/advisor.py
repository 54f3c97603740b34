"""Suggest a discretization (elements, time step) for a target error from work-precision
data, such as the tables written by ``benchmarks/statics_princeton.py`` and
``benchmarks/dynamics_helical.py``.

The errors of a refinement study are fitted by power laws in log-log space,
``e_space(n) = a n^-p`` (refining elements at a fixed dt) and ``e_time(dt) = b dt^q``
(refining dt at a fixed element count); to first order the two add, and the cost of a run
grows like ``n / dt`` (linear in elements, measured by benchmarks/scaling.py, and in the
number of steps). The suggestion is the cheapest ``(n, dt)`` on a grid whose predicted
error ``e_space(n) + e_time(dt)`` is at most the target. Extrapolation beyond the measured
range is flagged; data whose error does not fall with refinement (fitted order below 0.5)
is refused with a ValueError. Plain NumPy; no JAX.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np


class PowerLaw(NamedTuple):
    """``error(x) = coefficient * x**exponent``, fitted on ``x`` in [x_min, x_max]."""
    coefficient: float
    exponent: float
    x_min: float
    x_max: float

    def __call__(self, x):
        return self.coefficient * np.asarray(x, float) ** self.exponent


class Suggestion(NamedTuple):
    """elements, dt (s; None for statics), predicted error (same measure as the data),
    relative cost (n / dt, or n), extrapolated (outside the measured ranges)."""
    elements: int
    dt: float | None
    predicted_error: float
    relative_cost: float
    extrapolated: bool


def fit_power_law(x, error) -> PowerLaw:
    """Least-squares fit of ``log error = log a + k log x`` (at least two points with
    positive error)."""
    x, error = np.asarray(x, float), np.asarray(error, float)
    keep = (error > 0) & (x > 0)
    if keep.sum() < 2:
        raise ValueError("fit_power_law: need at least two points with positive error")
    k, log_a = np.polyfit(np.log(x[keep]), np.log(error[keep]), 1)
    return PowerLaw(float(np.exp(log_a)), float(k), float(x[keep].min()), float(x[keep].max()))


def _require_convergence(law: PowerLaw, what: str, sign: float):
    """Refuse data whose error does not fall at least like ``h^0.5`` with refinement
    (e.g. a reference that is not converged, or an oscillating error)."""
    if sign * law.exponent < 0.5:
        raise ValueError(f"{what}: the error does not fall with refinement in the measured "
                         f"range (fitted order {abs(law.exponent):.2f} < 0.5)")


def _element_grid(max_elements):
    return np.unique(np.round(np.geomspace(1, max_elements, 200)).astype(int))


def suggest_elements(elements, error, target: float, max_elements: int = 1000) -> Suggestion:
    """Fewest elements whose fitted error is at most ``target`` (statics)."""
    law = fit_power_law(elements, error)
    _require_convergence(law, "elements", -1.0)
    grid = _element_grid(max_elements)
    ok = grid[law(grid) <= target]
    n = int(ok[0]) if ok.size else int(grid[-1])
    return Suggestion(n, None, float(law(n)), float(n), not law.x_min <= n <= law.x_max)


def suggest_resolution(elements, element_error, dts, dt_error, target: float,
                       max_elements: int = 1000, dt_max: float | None = None) -> Suggestion:
    """Cheapest ``(elements, dt)`` with ``e_space(n) + e_time(dt) <= target`` (dynamics).

    ``elements, element_error``: a refinement in elements at one dt; ``dts, dt_error``: a
    refinement in dt at one element count. Time steps are searched from ``dt_max``
    (default: the largest measured) down by halving, 12 times. If no pair reaches the
    target, the most accurate pair is returned.
    """
    space, time = fit_power_law(elements, element_error), fit_power_law(dts, dt_error)
    _require_convergence(space, "elements", -1.0)
    _require_convergence(time, "dt", 1.0)
    grid_n = _element_grid(max_elements)
    grid_dt = (dt_max or time.x_max) / 2.0 ** np.arange(13)
    n, dt = np.meshgrid(grid_n, grid_dt, indexing="ij")
    predicted = space(n) + time(dt)
    cost = n / dt
    feasible = predicted <= target
    pick = (np.unravel_index(np.argmin(np.where(feasible, cost, np.inf)), cost.shape)
            if feasible.any() else np.unravel_index(np.argmin(predicted), cost.shape))
    n_best, dt_best = int(n[pick]), float(dt[pick])
    outside = not (space.x_min <= n_best <= space.x_max and time.x_min <= dt_best <= time.x_max)
    return Suggestion(n_best, dt_best, float(predicted[pick]), float(cost[pick]), outside)
