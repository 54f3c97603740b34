"""Nodal frames of a rod where a solve starts (plain NumPy, no JAX): the stress-free shape
placed by the rod's base, or its ``initial`` state (points, rotations, a restart).

Frames are ``(R, p)``: rotations (n+1, 3, 3) whose columns are the section axes (local x
the centreline tangent) and positions (n+1, 3) in metres, world coordinates
(:mod:`simsoft_jax.math.geometry` gives them in the base frame).
"""
from __future__ import annotations

import numpy as np

from ..math import geometry as geom


def world_frames(rod):
    """Stress-free frames of a RodSpec in world coordinates: (n+1,3,3), (n+1,3)."""
    R, p = geom.reference_frames(rod.geometry, rod.node_fractions())
    Rb, pb = np.asarray(rod.base_rotation, float), np.asarray(rod.base_position, float)
    return np.einsum("ij,njk->nik", Rb, R), pb + p @ Rb.T


def initial_frames(rod, R_ref, p_ref):
    """Start configuration: the stress-free shape ``R_ref, p_ref`` (world), or
    ``initial.points`` (base frame).

    As many points as nodes: the node positions exactly, turned by ``initial.rotations``
    (base frame) when given, else each stress-free frame turned by the smallest rotation
    onto the points' chord tangent (a straight rod stretched along itself keeps its
    reference rotations exactly). Any other count: a polyline, its nodes at the rod's
    node fractions of its arc length. Without ``initial.rotations`` these chord frames
    are out of moment balance; the model puts them in balance with the positions held
    (:func:`chord_started`, :mod:`simsoft_jax.model.start_balance`).
    """
    if rod.initial_points is None:
        return R_ref, p_ref
    Rb, pb = np.asarray(rod.base_rotation, float), np.asarray(rod.base_position, float)
    points = np.asarray(rod.initial_points, float)
    if len(points) == len(R_ref):
        if getattr(rod, "initial_rotations", None) is not None:
            R = np.einsum("ij,njk->nik", Rb, np.asarray(rod.initial_rotations, float))
        else:
            R = geom.aligned_frames(R_ref, geom.chord_tangents(points) @ Rb.T)
        return R, pb + points @ Rb.T
    R, p = geom.polyline_frames(points, rod.node_fractions(), start_rotation=Rb.T @ R_ref[0])
    return np.einsum("ij,njk->nik", Rb, R), pb + p @ Rb.T


def chord_started(rod) -> bool:
    """Whether the rod starts from ``initial.points`` without ``initial.rotations``: its
    start rotations are the chord frames of :func:`initial_frames`, which the model
    relaxes into moment balance with the positions held
    (:mod:`simsoft_jax.model.start_balance`)."""
    return (rod.initial_points is not None
            and getattr(rod, "initial_rotations", None) is None)
