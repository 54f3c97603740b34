"""Held-out splits of observation rows by a column, for calibration and validation.

A split sorts the distinct values of a column (e.g. ``tip_mass``, a column of the
observation file, see :meth:`simsoft_jax.studies.measurements.ObservationSet.column`) and assigns
whole values, so that every row of one load case lands on the same side. ``within``
names columns that define independent series (e.g. ``("test", "skin")``): each series
is split on its own values. Every function returns boolean masks (n,) over the rows, to
pass to :meth:`~simsoft_jax.studies.measurements.ObservationSet.subset`.
"""
from __future__ import annotations

from typing import Sequence

import numpy as np


def _series(obs, by: str, within: Sequence[str] | str):
    """``(values (n,), [(rows of one series, its sorted distinct values)])``."""
    within = (within,) if isinstance(within, str) else tuple(within or ())
    values = obs.column(by)
    keys = [tuple(str(v) for v in row) for row in zip(*(obs.column(c) for c in within))] \
        if within else [()] * len(values)
    out = []
    for key in dict.fromkeys(keys):
        rows = np.array([k == key for k in keys])
        out.append((rows, np.unique(values[rows])))
    return values, out


def lower_upper(obs, by: str, within: Sequence[str] | str = ()) -> tuple[np.ndarray, np.ndarray]:
    """``(lower, upper)`` masks: the rows whose ``by`` value is in the lower half of the
    series' sorted distinct values (the middle one of an odd count goes to the lower
    half), and the others. E.g. calibrate on the lighter tip masses, predict the heavier."""
    values, series = _series(obs, by, within)
    lower = np.zeros(len(values), bool)
    for rows, distinct in series:
        cut = distinct[(len(distinct) - 1) // 2]
        lower |= rows & (values <= cut)
    return lower, ~lower


def alternate(obs, by: str, within: Sequence[str] | str = ()) -> tuple[np.ndarray, np.ndarray]:
    """``(kept, held)``: every other distinct value of each series held out (the 2nd, 4th,
    ... in sorted order), an interpolation test."""
    values, series = _series(obs, by, within)
    held = np.zeros(len(values), bool)
    for rows, distinct in series:
        held |= rows & np.isin(values, distinct[1::2])
    return ~held, held


def k_fold(obs, by: str, k: int, within: Sequence[str] | str = ()) -> list[tuple[np.ndarray, np.ndarray]]:
    """``k`` pairs ``(train, test)``: the distinct values of each series dealt in sorted
    order to the folds (value i to fold ``i % k``); fold f tests its values and trains on
    the rest."""
    if not isinstance(k, (int, np.integer)) or k < 2:
        raise ValueError(f"k: must be an integer >= 2, got {k!r}")
    values, series = _series(obs, by, within)
    fold = np.full(len(values), -1)
    for rows, distinct in series:
        for i, v in enumerate(distinct):
            fold[rows & (values == v)] = i % k
    if len(np.unique(fold)) < k:
        raise ValueError(f"k: {k} folds need at least {k} distinct values of {by!r} "
                         f"in a series")
    return [(fold != f, fold == f) for f in range(k)]
