"""The couplings beside the rods' chains, behind one door for the solvers.

A coupling adds unknowns beside the block-tridiagonal chains and borders their Newton
system: ``[[K, B], [C, D]]`` with the chains' tangent K, the coupling columns B (N,6,m),
rows C (m,N,6) and block D (m,m) (:class:`~simsoft_jax.mechanisms.Coupled`), solved by
:func:`simsoft_jax.linalg.solve_coupled` in O(N m + m^3). The kinds: joints and rigid
bodies (:mod:`simsoft_jax.mechanisms`: the coupling nodes' 6 dofs and the joint
multipliers), and rod-rod contact (:mod:`simsoft_jax.rod_pairs`: the 6 dofs of each node
the contact pairs may couple, no multipliers). The statics and the dynamics border their
systems here (:func:`couple`) and split the solution here (:func:`split`); a scene holds
at most one kind today (the scene reader refuses the others' combinations).
"""
from __future__ import annotations

import jax.numpy as jnp

from . import mechanisms, rod_pairs
from .mechanisms import Coupled

__all__ = ["Coupled", "border_sizes", "present", "couple", "coupled_residual", "split", "violation"]


def present(structure) -> bool:
    """Whether the structure has a coupling beside its chains (static)."""
    return bool(structure.joints or structure.self_contact)


def border_sizes(structure) -> tuple[int, int]:
    """``(m, M)``: the coupling unknowns beside the chains and how many of them are
    multipliers (joints), static."""
    if structure.joints:
        return mechanisms.coupling_count(structure), mechanisms.multiplier_count(structure)
    if structure.self_contact:
        return 6 * rod_pairs.coupled_nodes(structure), 0
    return 0, 0


def couple(model, R, p, y, r, blocks, T=None) -> Coupled:
    """The bordered Newton system at frames (R, p) and multipliers y (M,), from the chains'
    residual r (N,6) and tangent ``blocks`` (held dofs already identity rows), the
    couplings' forces not yet in r. ``T`` (N,6,6): the maps ``T_SE3(w)`` when the
    unknowns are a time step's increments w (None in statics). Without couplings
    (:func:`present`) the border is empty, ``r_z`` is y and the frames are not read."""
    s = model.structure
    if s.joints:
        return mechanisms.couple(model, R, p, y, r, blocks, T)
    if s.self_contact:
        r, blocks, pairs = rod_pairs.system(model, R, p, r, blocks, T)
        return Coupled(r, blocks, pairs.B, pairs.C, pairs.D,
                       jnp.zeros(pairs.D.shape[0], r.dtype))
    n = r.shape[0]
    return Coupled(r, blocks, jnp.zeros((n, 6, 0), r.dtype), jnp.zeros((0, n, 6), r.dtype),
                   jnp.zeros((0, 0), r.dtype), y)


def coupled_residual(model, R, p, y, r):
    """``(r, r_z)`` of :func:`couple` without the matrix: the couplings' forces added to r
    (N,6) and their own residuals r_z (zero rows for rod-rod contact, whose border rows
    hold exactly in every solve)."""
    s = model.structure
    if s.joints:
        return mechanisms.residual(model, R, p, y, r)
    if s.self_contact:
        return r + rod_pairs.residual(model, R, p), jnp.zeros(border_sizes(s)[0], r.dtype)
    return r, y


def violation(model, r_z):
    """The couplings' own residual sizes ``(forces (N), gaps)``: the coupling nodes' forces
    and moments / char_length, and the joints' gaps / char_length and rotations (rad)
    (:func:`simsoft_jax.mechanisms.violation_norm`); None where the couplings have no
    residual of their own (rod-rod contact, none)."""
    return mechanisms.violation_norm(model, r_z) if model.structure.joints else None


def split(structure, x, z):
    """Nodal increments (N,6) and multipliers (M,) from the bordered solution: the chain
    part x (N,6) and the coupling part z (m,)."""
    if structure.joints:
        return mechanisms.split(structure, x, z)
    return (x, z[:0]) if structure.self_contact else (x, z)
