"""Limits of what the solver can honour, checked when a scene is loaded (plain Python +
NumPy): element counts, the rotation a helical element can span, time steps, loads that
would vanish on held nodes, and time laws too sharp for the time step (a warning).
Errors name the key, as everywhere in :mod:`simsoft_jax.scene.scene`."""
from __future__ import annotations

import math
import warnings

import numpy as np

from .key_checks import fail, index, join
from ..math.geometry import element_chords, element_turns
from .scene_specs import GeometrySpec

MAX_STEPS = 1_000_000      # time steps a dynamic run may take unless solver.max_steps says more
MAX_STEPS_LIMIT = 100_000_000   # the largest solver.max_steps (and save_every) accepted
MAX_ITERATIONS = 10_000    # the largest solver.max_iterations (Newton passes of one solve)
MAX_LOAD_STEPS = 1_000_000  # the largest solver.load_steps (first increment 1e-6 of the loads)
MAX_ELEMENTS = 20_000      # elements in one scene (all rods)
MAX_ELEMENT_TURN_DEG = 90.0  # stress-free rotation of one element (helical element's range)
ROUND_OFF = 1e-9           # relative: a feature as long as dt up to round-off is not shorter


def _shorter_than(span: float, dt: float) -> bool:
    """``span < dt`` beyond round-off (samples spaced by exactly dt, as written in decimal
    or computed as ``k * dt``, do not count as shorter)."""
    return span < dt * (1.0 - ROUND_OFF)


def warn_short_features(loads: tuple, constraints: tuple, dt: float) -> None:
    """Warn (``UserWarning``, naming the key) about time laws with features shorter than
    the time step ``dt`` (s): a ramp or smoothstep with ``t1 - t0 < dt``, table or drive
    samples closer than ``dt``. The steps sample such a law only at their own times, so a
    pulse narrower than dt may be missed or its size misjudged."""
    for i, load in enumerate(loads):
        prof, path = load.profile, join(index("loads", i), "profile")
        if prof.kind in ("ramp", "smoothstep") and _shorter_than(prof.t1 - prof.t0, dt):
            warnings.warn(f"{path}: rises in t1 - t0 = {prof.t1 - prof.t0:g} s, less than "
                          f"solver.dt = {dt:g} s; the steps sample it coarsely (reduce dt)",
                          stacklevel=4)
        elif prof.kind == "table" and len(prof.t) > 1 and _shorter_than(np.diff(prof.t).min(), dt):
            warnings.warn(f"{path}.t: samples {np.diff(prof.t).min():g} s apart, less than "
                          f"solver.dt = {dt:g} s; a pulse narrower than dt may be missed "
                          "(reduce dt)", stacklevel=4)
    for i, c in enumerate(constraints):
        if c.kind == "drive" and len(c.times) > 1 and _shorter_than(np.diff(c.times).min(), dt):
            warnings.warn(f"{index('constraints', i)}.times: samples "
                          f"{np.diff(c.times).min():g} s apart, less than solver.dt = "
                          f"{dt:g} s; the steps sample the drive coarsely (reduce dt)",
                          stacklevel=4)


def check_loads_on_held_nodes(items: list, loads: tuple, constraints: tuple) -> None:
    """A point load placed by arc length ``s`` exactly on a node acts on that node; when
    the node's constraint holds every dof the load acts on (a force on a clamped, pinned,
    hinged or driven node; a moment on a clamped or driven one) the load would vanish
    without a trace: reject it, naming the load's ``s`` key. (Loads by ``s`` between
    nodes act on their element and are not rounded.)"""
    held = {(c.rod, c.node): c.kind for c in constraints
            if not (c.kind == "drive" and c.slides_along is not None)}
    for i, (item, load) in enumerate(zip(items, loads)):
        kind = held.get((load.rod, load.node))
        if ("s" not in item or kind is None
                or (load.kind == "moment" and kind not in ("clamp", "drive"))):
            continue
        fail(join(index("loads", i), "s"), f"s = {item['s']} is node "
             f"{load.node} of rod {load.rod!r}, which a {kind} holds: the {load.kind} "
             "would have no effect there; move it (or use more elements)")


def check_point_loads_in_elements(items: list, loads: tuple) -> None:
    """The model holds one point-load place per element: loads by ``s`` inside the same
    element must share it (``xi`` within 1e-12); else reject the second, naming its key."""
    places: dict[tuple[str, int], tuple[float, int]] = {}
    for i, load in enumerate(loads):
        if load.element is None:
            continue
        xi, first = places.setdefault((load.rod, load.element), (load.xi, i))
        if abs(xi - load.xi) > 1e-12:
            fail(join(index("loads", i), "s"), f"s = {items[i]['s']} lies in element "
                 f"{load.element} of rod {load.rod!r}, which loads[{first}] already loads "
                 "at another place; one point load place per element is supported: "
                 "use more elements or put the loads at the same s")


def check_elements(geometry: GeometrySpec, fractions, path: str) -> None:
    """Every element of the stress-free shape (nodes at ``fractions`` (n+1,) of the arc
    length) must turn by at most MAX_ELEMENT_TURN_DEG (a helical element cannot represent
    a rotation near pi, and is far too stiff well before that) and have a length; the error
    says how many elements would do. Polylines are checked for zero lengths first (a fold
    back onto itself)."""
    elements = len(fractions) - 1

    def check_length():
        lengths = element_chords(geometry, fractions)
        if lengths.min() <= 1e-9 * geometry.arc_length / elements:
            fail(path, f"element {int(np.argmin(lengths))} of {elements} has zero length "
                 "(its two nodes coincide in the stress-free shape: the shape folds back "
                 "onto itself, or its dimensions are too small to represent); use more "
                 "elements or check the dimensions")

    if geometry.kind == "polyline":
        check_length()
    turns = np.degrees(element_turns(geometry, fractions))
    worst = float(turns.max())
    if worst > MAX_ELEMENT_TURN_DEG * (1.0 + 1e-9):
        need = max(elements + 1, math.ceil(elements * worst / MAX_ELEMENT_TURN_DEG - 1e-9))
        advice = (f"use elements >= {need}" if geometry.kind != "polyline" else
                  "the polyline turns too sharply there: round its corners with more "
                  "points (a corner stays a corner however many elements)")
        first = int(np.argmax(turns >= worst * (1.0 - 1e-12)))   # ties up to round-off
        fail(path, f"element {first} of {elements} turns by {worst:.4g} "
             f"degrees in the stress-free shape, more than the limit "
             f"{MAX_ELEMENT_TURN_DEG:g} degrees per element; {advice}")
    check_length()
