"""Scene bodies and joints -> the Model's body nodes, coupling nodes and joint tables
(plain NumPy, at build time; the mechanics is in :mod:`simsoft_jax.physics.terms.joints` and
:mod:`simsoft_jax.couplings.mechanisms`).

A rigid body is one more node after the rods' nodes (6 DOF, no element); its mass and
inertia become an attached mass at that node. A joint ties node a to node b; its tables
hold the joint point in both nodes' frames and, for a weld, the relative rotation
``R_a^T R_b``, all taken at the start configuration, so a joint holds the scene as it
starts.

Coupling nodes are solved in the small dense part of the Newton system, the other rod
nodes in block-tridiagonal chains (:mod:`simsoft_jax.couplings.mechanisms`). Each chain must be
nonsingular on its own and no joint may couple the rotations of two chain nodes, so the
coupling nodes are: every body; in each rod its own supports do not hold, its node of
its first joint (the rod is then held there in its chain); and one end of every weld
between two rod nodes that are both still in chains (end b, or a where b is held by a
constraint).
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..scene.scene_specs import MassSpec


class JointLayout(NamedTuple):
    """Body node frames (B,3,3)/(B,3); ``bodies`` (name, node) of the scene's bodies;
    ``coupling_nodes`` (bodies first); ``joints`` (kind, node a, node b);
    the joint tables offset_a, offset_b (J,3), rotation (J,3,3); ``masses``: MassSpec
    entries (model node indices) of the bodies with mass."""
    R: np.ndarray
    p: np.ndarray
    bodies: tuple
    coupling_nodes: tuple
    joints: tuple
    offset_a: np.ndarray
    offset_b: np.ndarray
    rotation: np.ndarray
    masses: tuple


def _coupling_rod_nodes(scene, rods, node_of, held_by_joints):
    """Rod nodes moved to the coupling set (see the module docstring)."""
    joints = getattr(scene, "joints", ())
    fully_held = {rods[c.rod].first_node + c.node for c in scene.constraints
                  if c.kind in ("clamp", "drive")}
    chosen = []
    for name in sorted(held_by_joints, key=lambda n: rods[n].first_node):
        first = next(end for j in joints for end in (j.a, j.b) if end.rod == name)
        chosen.append(node_of(first))
    for j in joints:
        a, b = node_of(j.a), node_of(j.b)
        if j.kind != "weld" or j.a.body is not None or j.b.body is not None:
            continue
        if a in chosen or b in chosen:
            continue
        chosen.append(a if b in fully_held else b)
    return tuple(dict.fromkeys(chosen))


def layout(scene, rods: dict, R0: np.ndarray, p0: np.ndarray,
           held_by_joints: set = frozenset()) -> JointLayout:
    """The :class:`JointLayout` of ``scene`` (its ``bodies`` and ``joints``), with the rods'
    node frames ``R0, p0`` (N,3,3)/(N,3), ``rods`` (name -> RodInfo) and the names of the
    rods that only their joints hold. The joint points coincide at the start, and no weld
    joins two nodes clamps or drives hold (:mod:`simsoft_jax.scene.scene_start`)."""
    bodies, joints = getattr(scene, "bodies", ()), getattr(scene, "joints", ())
    n = len(p0)
    R = np.reshape([b.rotation for b in bodies], (-1, 3, 3))
    p = np.reshape([b.position for b in bodies], (-1, 3))
    node_of_body = {b.name: n + k for k, b in enumerate(bodies)}

    def node_of(end):
        return node_of_body[end.body] if end.body is not None else \
            rods[end.rod].first_node + end.node

    def frame(node):
        return (R0[node], p0[node]) if node < n else (R[node - n], p[node - n])

    table, off_a, off_b, rot = [], [], [], []
    for j in joints:
        a, b = node_of(j.a), node_of(j.b)
        (Ra, pa), (Rb, pb) = frame(a), frame(b)
        point = pb + Rb @ np.asarray(j.b.offset, float)
        table.append((j.kind, a, b))
        off_a.append(Ra.T @ (point - pa))
        off_b.append(Rb.T @ (point - pb))
        rot.append(Ra.T @ Rb)
    body_nodes = tuple(range(n, n + len(bodies)))
    masses = tuple(MassSpec(rod="", node=n + k, mass=b.mass, offset=np.zeros(3),
                            inertia=np.asarray(b.inertia, float))
                   for k, b in enumerate(bodies) if b.mass > 0.0)
    return JointLayout(
        R=R, p=p, bodies=tuple((b.name, node_of_body[b.name]) for b in bodies),
        coupling_nodes=body_nodes + _coupling_rod_nodes(scene, rods, node_of, held_by_joints),
        joints=tuple(table), offset_a=np.reshape(off_a, (-1, 3)),
        offset_b=np.reshape(off_b, (-1, 3)), rotation=np.reshape(rot, (-1, 3, 3)),
        masses=masses)
