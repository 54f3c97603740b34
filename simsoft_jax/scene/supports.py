"""Which rigid motions a rod's supports leave free (plain NumPy, no JAX).

Without supports that hold every rigid motion, a rod's static tangent is singular where
nothing else holds it (Newton's step is not finite). The check is linear algebra on the
rigid motions of one rod, twists
``(v, w)`` (m/s, rad/s, world frame, about a reference point): node ``i`` at ``p_i`` moves
by ``u_i = v + w x p_i`` and turns by ``w``. Each support holds some components of these:

* clamp, drive (without ``slides_along``): ``R_i^T u_i`` and ``R_i^T w`` (all six);
* drive with ``slides_along`` e: ``u_i`` across e, and ``R_i^T w``;
* hinge about local axis a: ``R_i^T u_i`` and the two components of ``R_i^T w`` other
  than a;
* pin: ``R_i^T u_i``.

The rigid motions that no support holds are the null space of these rows; any left is
reported in words (a translation along a direction, or a rotation about a line). A
static solve holds such a rod by a regularization that vanishes at convergence
(:func:`simsoft_jax.solvers.statics.newton.settling_force`): contact, friction or the loads
may hold what the supports do not; where nothing does, the solve says which motion
was left free (status ``unrestrained``).
"""
from __future__ import annotations

import numpy as np

from ..math.geometry import frames_at
from ..math.lie_np import skew

AXES = ("x", "y", "z")


def _rows(constraint, R, p):
    """Rows (k, 6) of the rigid-motion components a support holds (scaled twist)."""
    move = np.hstack([np.eye(3), -skew(p)])          # u = v + w x p = [I, -p^] [v; w]
    turn = np.hstack([np.zeros((3, 3)), np.eye(3)])
    kind = constraint.kind
    if kind == "drive" and constraint.slides_along is not None:
        e = np.asarray(constraint.slides_along, float)
        across = np.linalg.svd(np.eye(3) - np.outer(e, e))[0][:, :2].T
        return np.vstack([across @ move, R.T @ turn])
    if kind == "pin":
        return R.T @ move
    if kind == "hinge":
        keep = [k for k in range(3) if AXES[k] != constraint.axis]
        return np.vstack([R.T @ move, (R.T @ turn)[keep]])
    return np.vstack([R.T @ move, R.T @ turn])        # clamp, drive


def free_motions(constraints, frames, length):
    """Rigid motions of one rod that no constraint holds: ``(basis, centre)``.

    constraints: the ConstraintSpecs of the rod; frames: ``{node: (R, p)}`` (world) for
    their nodes; length: the rod's length (m), which scales rotations against
    translations so the rank test is unit-free. ``basis`` (k, 6) holds unit twists
    ``(v, length * w)`` about the point ``centre`` (3,), the mean of the held nodes.
    """
    if not constraints:
        return np.eye(6), np.zeros(3)
    centre = np.mean([frames[c.node][1] for c in constraints], axis=0)
    A = np.vstack([_rows(c, frames[c.node][0], (frames[c.node][1] - centre) / length)
                   for c in constraints])
    _, sv, vt = np.linalg.svd(A)
    rank = int(np.sum(sv > 1e-8 * sv.max()))
    return vt[rank:], centre


def _vec(x):
    return "(" + ", ".join(f"{v:.4g}" for v in np.where(np.abs(x) < 1e-12, 0.0, x)) + ")"


def describe(twist, centre, length) -> str:
    """One free rigid motion in words: a translation along a direction, or a rotation
    about a line (through a point, along a direction; world frame, m)."""
    k = int(np.argmax(np.abs(twist)))
    twist = twist * np.sign(twist[k])     # the largest component positive
    v, w = twist[:3], twist[3:] / length
    if np.linalg.norm(twist[3:]) < 1e-6:
        return f"a translation along {_vec(v / np.linalg.norm(v))}"
    point = centre + np.cross(w, v) / np.dot(w, w)
    return (f"a rotation about the line through {_vec(point)} m along "
            f"{_vec(w / np.linalg.norm(w))}")


def free_words(constraints, frames, length) -> str | None:
    """``None`` when a rod's supports hold every rigid motion, else what they leave free
    in words ("no support", or "one rigid motion, a rotation about ...");
    arguments as :func:`free_motions`."""
    basis, centre = free_motions(constraints, frames, length)
    if not len(basis):
        return None
    if len(basis) == 6:
        return "no support"
    count = "one rigid motion," if len(basis) == 1 else f"{len(basis)} rigid motions, e.g."
    return f"{count} {describe(basis[0], centre, length)}"


def advice(words: str) -> str:
    """How to hold the free motions ``words`` of :func:`free_words` by supports."""
    if words == "no support":
        return "a clamp, or pins and hinges that hold every motion"
    if not words.startswith("one"):
        return "add supports: a clamp, or pins and hinges at more nodes"
    if "translation" in words:
        return ("hold the position of a node along that direction (a pin, a clamp, or a "
                "drive without slides_along)")
    return ("replace a pin by a hinge whose axis is not along that line (kind = \"hinge\", "
            "e.g. axis = \"y\" or \"z\" where the rod runs along local x), or by a clamp")


def stress_free_frames(rod, nodes):
    """World frames ``{node: (R, p)}`` of the given nodes of a RodSpec's stress-free
    shape (its geometry placed by its base)."""
    Rb, pb = np.asarray(rod.base_rotation, float), np.asarray(rod.base_position, float)
    return {i: (Rb @ R, pb + Rb @ p)
            for i, (R, p) in frames_at(rod.geometry, rod.node_fractions(), nodes).items()}
