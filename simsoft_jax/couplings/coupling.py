"""The couplings beside the rods' chains, behind one door for the solvers.

A coupling adds unknowns beside the block-tridiagonal chains and borders their Newton
system: ``[[K, B], [C, D]]`` with the chains' tangent K, the coupling columns B (N,6,m),
rows C (m,N,6) and block D (m,m) (:class:`~simsoft_jax.couplings.mechanisms.Coupled`), solved by
:func:`simsoft_jax.math.linalg.solve_coupled` in O(N m + m^3). The kinds: joints and rigid
bodies (:mod:`simsoft_jax.couplings.mechanisms`: the coupling nodes' 6 dofs and the joint
multipliers), and rod-rod contact (:mod:`simsoft_jax.couplings.rod_pairs`: the 6 dofs of each node
the contact pairs may couple, no multipliers). The statics and the dynamics border their
systems here (:func:`couple`) and split the solution here (:func:`split`); a scene holds
any of them together (:func:`couple`).
"""
from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from . import mechanisms, rod_pairs
from .mechanisms import Coupled

__all__ = ["Coupled", "border_sizes", "present", "couple", "coupled_residual", "split", "violation"]


def present(structure) -> bool:
    """Whether the structure has a coupling beside its chains (static)."""
    return bool(structure.joints or structure.self_contact)


def border_sizes(structure) -> tuple[int, int]:
    """``(m, M)``: the coupling unknowns beside the chains and how many of them are
    multipliers (joints), static: the joints' coupling set, then the rod-rod contact's
    node copies."""
    m, multipliers = 0, 0
    if structure.joints:
        m, multipliers = mechanisms.coupling_count(structure), mechanisms.multiplier_count(
            structure)
    if structure.self_contact:
        m += 6 * rod_pairs.coupled_nodes(structure)
    return m, multipliers


def couple(model, R, p, y, r, blocks, T=None) -> Coupled:
    """The bordered Newton system at frames (R, p) and multipliers y (M,), from the chains'
    residual r (N,6) and tangent ``blocks`` (held dofs already identity rows), the
    couplings' forces not yet in r. ``T`` (N,6,6): the maps ``T_SE3(w)`` when the
    unknowns are a time step's increments w (None in statics). Without couplings
    (:func:`present`) the border is empty, ``r_z`` is y and the frames are not read.
    Several kinds concatenate their borders: the rod-rod contact's pair terms are added
    to the whole nodal system first, then the joints take their coupling nodes' rows and
    columns out of the chains (:func:`_with_contact`)."""
    s = model.structure
    contact = None
    if s.self_contact:
        r, blocks, contact = rod_pairs.system(model, R, p, r, blocks, T)
    if s.joints:
        system = mechanisms.couple(model, R, p, y, r, blocks, T)
        return system if contact is None else _with_contact(s, system, contact)
    if contact is not None:
        return Coupled(r, blocks, contact.B, contact.C, contact.D,
                       jnp.zeros(contact.D.shape[0], r.dtype))
    n = r.shape[0]
    return Coupled(r, blocks, jnp.zeros((n, 6, 0), r.dtype), jnp.zeros((0, n, 6), r.dtype),
                   jnp.zeros((0, 0), r.dtype), y)


def _with_contact(structure, joints: Coupled, contact) -> Coupled:
    """The joints' bordered system with the rod-rod contact's border appended: the contact
    unknowns ``y = W U^T X`` read the nodal increments X, which are the chains' x on
    chain nodes and the joint border's first ``6 n_c`` unknowns on the n_c coupling
    nodes; their forces ``U y`` land in the same places. So U's and ``W U^T``'s coupling
    node rows and columns move into the D block between the two borders."""
    nodes = np.asarray(structure.coupling_nodes, dtype=int)
    chain = jnp.asarray(mechanisms.chain_mask(structure))
    m1, m2 = joints.D.shape[0], contact.D.shape[0]
    U, W = contact.B, contact.C                               # (N,6,m2), (m2,N,6)
    dtype = joints.r.dtype
    U_nodes = jnp.zeros((m1, m2), dtype).at[:6 * nodes.size].set(
        U[nodes].reshape(-1, m2))
    W_nodes = jnp.zeros((m2, m1), dtype).at[:, :6 * nodes.size].set(
        W[:, nodes].reshape(m2, -1))
    B = jnp.concatenate([joints.B, U * chain[:, None, None]], axis=-1)
    C = jnp.concatenate([joints.C, W * chain[None, :, None]], axis=0)
    D = jnp.block([[joints.D, U_nodes], [W_nodes, contact.D]])
    return Coupled(joints.r, joints.blocks, B, C, D,
                   jnp.concatenate([joints.r_z, jnp.zeros(m2, dtype)]))


def coupled_residual(model, R, p, y, r):
    """``(r, r_z)`` of :func:`couple` without the matrix: the couplings' forces added to r
    (N,6) and their own residuals r_z (zero rows for rod-rod contact, whose border rows
    hold exactly in every solve)."""
    s = model.structure
    extra = 0
    if s.self_contact:
        r = r + rod_pairs.residual(model, R, p)
        extra = 6 * rod_pairs.coupled_nodes(s)      # the contact's node copies
    if s.joints:
        r, r_z = mechanisms.residual(model, R, p, y, r)
    else:
        r_z = y[:0] if s.self_contact else y
    return r, jnp.concatenate([r_z, jnp.zeros(extra, r.dtype)])


def violation(model, r_z):
    """The couplings' own residual sizes ``(forces (N), gaps)``: the coupling nodes' forces
    and moments / char_length, and the joints' gaps / char_length and rotations (rad)
    (:func:`simsoft_jax.couplings.mechanisms.violation_norm`); None where the couplings have no
    residual of their own (rod-rod contact, none)."""
    s = model.structure
    if not s.joints:
        return None
    return mechanisms.violation_norm(model, r_z[:mechanisms.coupling_count(s)])


def split(structure, x, z):
    """Nodal increments (N,6) and multipliers (M,) from the bordered solution: the chain
    part x (N,6) and the coupling part z (m,) (the joints' part first; the rod-rod
    contact's node copies are not unknowns of the solution)."""
    if structure.joints:
        return mechanisms.split(structure, x, z[:mechanisms.coupling_count(structure)])
    return (x, z[:0]) if structure.self_contact else (x, z)
