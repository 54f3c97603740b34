"""Actuation maps ``actuate(model, u) -> Model``: how an array of actuation values u (P,)
acts on a :class:`~simsoft_jax.model.model.Model`, for the inverse problems
(:mod:`simsoft_jax.studies.inverse`, :mod:`simsoft_jax.studies.inverse_dynamics`).

Any differentiable function of that form will do; :func:`leaf_actuation` builds the common
one, where each actuator sets entries of a Model array (a nodal moment or force, a load
channel's pattern or time table, a drive table, a tendon tension or chamber pressure once
the model has such a leaf) to its value ``u[j]``, in that array's units.
"""
from __future__ import annotations

import dataclasses

from typing import Sequence

import jax
import numpy as np

from ..model.model import Model
from ..model.parts import WHAT



def _leaf(tree, path: str, label: str = "actuators"):
    for name in path.split("."):
        if not hasattr(tree, name):
            raise ValueError(f"actuators: the model has no array {path!r}")
        tree = getattr(tree, name)
        if tree is None:
            what = WHAT.get(name, name)
            raise ValueError(f"{label}: this model was built without {what} ({path!r} is "
                             f"None), so the solvers would not read it; build it from a "
                             f"scene that has {what} (a zero load of that kind will do)")
    if not isinstance(tree, (jax.Array, np.ndarray)):
        raise ValueError(f"actuators: {path!r} is not an array of the model")
    return tree


def _replace(tree, path: str, value):
    head, _, rest = path.partition(".")
    new = value if not rest else _replace(getattr(tree, head), rest, value)
    return dataclasses.replace(tree, **{head: new})


def leaf_actuation(model: Model, actuators: Sequence[tuple]):
    """An ``actuate(model, u)`` that writes ``u[j]`` into the entries
    ``<path_j>[index_j]`` of the model, for actuators ``[(path_j, index_j), ...]``.

    path: a Model array name, or ``"channels.<array>"`` for a load channel's arrays
    (e.g. ``"channels.table_scale"``). index: anything NumPy indexing accepts for that
    array (an int, a tuple, slices: every entry it selects is set to ``u[j]``). Examples:
    a follower moment about the local z axis at the last node, ``("nodal_follower", (-1,
    5))`` (N m); a world force along x at node 3, ``("nodal_dead", (3, 0))`` (N); the
    values of channel 0's time table, ``("channels.table_scale", (0, slice(1, 4)))``; the
    y position of a clamped node 0, ``("p0", (0, 1))`` (m: held nodes stay at their start
    frame in statics, and the implicit gradient carries its derivative).

    Raises ValueError naming ``actuators`` for an unknown array, an index outside it, an
    actuator selecting nothing, two actuators writing the same entry, or a part the
    model was built without (None, :mod:`simsoft_jax.model.parts`: build the scene with a zero
    load of that kind).
    """
    if not actuators:
        raise ValueError("actuators: name at least one actuator")
    written: dict = {}
    for j, entry in enumerate(actuators):
        if not (isinstance(entry, (tuple, list)) and len(entry) == 2):
            raise ValueError(f"actuators[{j}]: expected (path, index), got {entry!r}")
        path, index = entry
        shape = _leaf(model, path, f"actuators[{j}]").shape
        hits = np.zeros(shape, bool)
        try:
            hits[index] = True
        except IndexError as exc:
            raise ValueError(f"actuators[{j}]: index {index!r} is outside {path!r} of shape "
                             f"{shape}: {exc}") from None
        if not hits.any():
            raise ValueError(f"actuators[{j}]: index {index!r} selects no entry of {path!r}")
        if path in written and np.any(written[path] & hits):
            raise ValueError(f"actuators[{j}]: writes entries of {path!r} another actuator "
                             "already writes")
        written[path] = written.get(path, np.zeros(shape, bool)) | hits
    entries = tuple((path, index) for path, index in actuators)

    def actuate(m: Model, u) -> Model:
        for j, (path, index) in enumerate(entries):
            m = _replace(m, path, _leaf(m, path).at[index].set(u[j]))
        return m

    actuate.size = len(entries)
    return actuate
