"""Checks of the state a scene starts in, run while the scene is read (plain NumPy, no
JAX), so that ``simsoft-jax validate`` refuses what a solve would refuse:

* every start frame is finite (``initial.points`` must not fold back on themselves);
* the two joint points of a joint coincide, and a weld does not join two nodes that
  clamps or drives already hold;
* a tendon crossing a weld has its routing points on both sides at the same place;
* with contact, every rod has a contact radius.

Positions are compared to ``1e-9`` of the larger of 1 m and the distance of the points
from the origin (the rounding of the start positions).
"""
from __future__ import annotations

import numpy as np

from .key_checks import fail, index, join
from .scene_contact import check_contact_radius
from .start_frames import initial_frames, world_frames
from .supports import free_words, stress_free_frames

GAP_TOLERANCE = 1e-9   # relative to max(1 m, |point|)


def unheld_rods(rods, constraints, frames_of) -> dict:
    """``{rod name: words}`` of the rods (RodSpecs, scene order) that their own
    constraints do not hold against every rigid motion, with the motions they leave
    free in words (:func:`~simsoft_jax.scene.supports.free_words`); ``frames_of(rod,
    nodes)`` gives the start frames ``{node: (R, p)}`` (world) of a rod's nodes. A static
    solve holds them by a regularization that vanishes at convergence, and says which
    motion nothing held (:mod:`simsoft_jax.solvers.statics`)."""
    out = {}
    for rod in rods:
        held = [c for c in constraints if c.rod == rod.name]
        words = free_words(held, frames_of(rod, {c.node for c in held}),
                           rod.geometry.arc_length)
        if words:
            out[rod.name] = words
    return out


def _started_frames(rods) -> dict:
    """``{rod name: (R, p)}``: the full start frames (world) of the rods (RodSpecs, scene
    order) that start from ``initial`` points; initial points whose polyline folds back
    on itself (no tangent at a node: its frame would not be finite) are refused."""
    out = {}
    for i, rod in enumerate(rods):
        if rod.initial_points is None:
            continue
        with np.errstate(invalid="ignore", divide="ignore"):   # reported below
            R, p = initial_frames(rod, *world_frames(rod))
        bad = np.flatnonzero(~np.isfinite(R).all(axis=(1, 2)))
        if len(bad):
            fail(join(index("rods", i), "initial.points"), f"fold back on themselves: node "
                 f"{bad[0]} of rod {rod.name!r} has no tangent (the points before and "
                 "after it along the rod coincide); give points that do not turn back, or "
                 "initial.rotations with one point per node")
        out[rod.name] = (R, p)
    return out


def _apart(a: np.ndarray, b: np.ndarray) -> float:
    """Distance (m) of two points when it exceeds the rounding tolerance, else 0."""
    gap = float(np.linalg.norm(a - b))
    scale = max(1.0, float(np.abs(a).max()), float(np.abs(b).max()))
    return gap if gap > GAP_TOLERANCE * scale else 0.0


def _check_joints(rods: dict, bodies, joints, constraints, frames_of) -> None:
    """Joint points together at the start; no weld between two fully held rod nodes."""
    held = {(c.rod, c.node) for c in constraints if c.kind in ("clamp", "drive")}
    body = {b.name: (np.asarray(b.rotation, float), np.asarray(b.position, float))
            for b in bodies}

    def point(end):
        R, p = body[end.body] if end.body is not None else \
            frames_of(rods[end.rod], {end.node})[end.node]
        return p + R @ np.asarray(end.offset, float)

    for i, j in enumerate(joints):
        if (j.kind == "weld" and j.a.body is None and j.b.body is None
                and (j.a.rod, j.a.node) in held and (j.b.rod, j.b.node) in held):
            fail(index("joints", i), "both ends are held by clamps or drives; the weld "
                 "would add nothing")
        gap = _apart(point(j.a), point(j.b))
        if gap:
            fail(index("joints", i), f"the joint points of ends a and b are {gap:.3g} m "
                 "apart at the start; place them together (a's offset, b's offset)")


def _check_crossings(rods: dict, tendons, frames_of) -> None:
    """A tendon crossing a weld: its routing points on the two sides must meet at the
    start (the weld then keeps them together, and the tendon's bridge across the weld has
    zero length at every solution; :mod:`simsoft_jax.physics.terms.tendons` sums the parts inside
    the rods only)."""
    def point(part, node):
        rod = rods[part.rod]
        offset, _ = part.routing.offsets_at(np.array(rod.node_arc()[node]))
        R, p = frames_of(rod, {node})[node]
        return p + R @ np.array([0.0, *offset])

    for m, t in enumerate(tendons):
        for before, after, (joint, node_a, node_b) in zip(t.parts, t.parts[1:], t.crossings):
            gap = _apart(point(before, node_a), point(after, node_b))
            if gap:
                fail(index("tendons", m), f"tendon {t.name!r} crosses the weld "
                     f"joints[{joint}] from rod {before.rod!r} (node {node_a}) to rod "
                     f"{after.rod!r} (node {node_b}), but its routing points there are "
                     f"{gap:.3g} m apart at the start; they must meet (offset, "
                     "rod_offsets), the weld then holds them together")


def check_start(scene) -> None:
    """Run every check of the module docstring, and the contact radius check
    (:func:`~simsoft_jax.scene.scene_contact.check_contact_radius`), on a parsed Scene; the
    first failure raises the one ValueError. Scene reading runs it, and
    :func:`~simsoft_jax.model.model.build_model` again (``Scene.replace`` does not validate)."""
    rods = {rod.name: rod for rod in scene.rods}
    constraints, joints = scene.constraints, getattr(scene, "joints", ())
    check_contact_radius(scene.rods, getattr(scene, "contact", None),
                         bool(getattr(scene, "obstacles", ())))
    started = _started_frames(scene.rods)

    def frames_of(rod, nodes):
        if rod.name not in started:   # the stress-free shape: those nodes only
            return stress_free_frames(rod, nodes)
        R, p = started[rod.name]
        return {k: (R[k], p[k]) for k in nodes}

    _check_joints(rods, getattr(scene, "bodies", ()), joints, constraints, frames_of)
    _check_crossings(rods, getattr(scene, "tendons", ()), frames_of)
