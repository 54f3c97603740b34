"""The couplings beside the rods' chains, behind one door for the solvers.

A coupling adds unknowns beside the block-tridiagonal chains and borders their Newton
system: ``[[K, B], [C, D]]`` with the chains' tangent K, the coupling columns B (N,6,m),
rows C (m,N,6) and block D (m,m) (:class:`~simsoft_jax.couplings.mechanisms.Coupled`), solved by
:func:`simsoft_jax.math.linalg.solve_coupled` in O(N m + m^3). The kinds: joints and rigid
bodies (:mod:`simsoft_jax.couplings.mechanisms`: the coupling nodes' 6 dofs and the joint
multipliers), rod-rod contact (:mod:`simsoft_jax.couplings.rod_pairs`: the 6 dofs of each node
the contact pairs may couple, no multipliers) and displacement-controlled tendons
(:mod:`simsoft_jax.couplings.tendon_lengths`: their tensions, multipliers of their length
constraints). The statics and the dynamics border their systems here (:func:`couple`)
and split the solution here (:func:`split`); a scene holds any of them together.

Layouts: the border unknowns ``z = [joints' coupling set; contact node copies;
tensions]`` and the multipliers ``y = [joint multipliers; tensions]``
(:func:`border_sizes`). A sliding drive's reduction of the chains (``slide``,
:func:`simsoft_jax.couplings.drives.slide_maps`) reduces every border too
(:func:`~simsoft_jax.couplings.drives.restrict_border`).
"""
from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from . import mechanisms, rod_pairs, tendon_lengths
from .drives import restrict_border
from .mechanisms import Coupled

__all__ = ["Coupled", "border_sizes", "present", "with_multipliers", "couple",
           "coupled_residual", "split", "violation", "tension_index"]


def present(structure) -> bool:
    """Whether the structure has a coupling beside its chains (static)."""
    return bool(structure.joints or structure.self_contact
                or tendon_lengths.count(structure))


def _joint_sizes(structure) -> tuple[int, int]:
    """The joints' coupling set and multipliers (0, 0 without joints)."""
    if not structure.joints:
        return 0, 0
    return mechanisms.coupling_count(structure), mechanisms.multiplier_count(structure)


def _contact_size(structure) -> int:
    """The rod-rod contact's node copies (0 without it)."""
    return 6 * rod_pairs.coupled_nodes(structure) if structure.self_contact else 0


def border_sizes(structure) -> tuple[int, int]:
    """``(m, M)``: the coupling unknowns beside the chains and how many of them are
    multipliers, static: the joints' coupling set (their multipliers), the rod-rod
    contact's node copies, the displacement-controlled tendons' tensions (multipliers)."""
    m, multipliers = _joint_sizes(structure)
    k = tendon_lengths.count(structure)
    return m + _contact_size(structure) + k, multipliers + k


def tension_index(structure, k: int) -> int:
    """Where the tension of the k-th displacement-controlled tendon (in tendon order
    among them) sits in the multipliers y (M,) (module docstring)."""
    return _joint_sizes(structure)[1] + k


def with_multipliers(model, y):
    """``model`` with the multipliers ``y`` (M,) that are parameters of the rods' own
    terms set: the displacement-controlled tendons' tensions (their forces and geometric
    stiffness are then in the rods' residual and tangent). The rods' residual passed to
    :func:`couple` and :func:`coupled_residual` is that of this model."""
    if not tendon_lengths.count(model.structure):
        return model
    return tendon_lengths.with_tensions(model, y[_joint_sizes(model.structure)[1]:])


def couple(model, R, p, y, r, blocks, T=None, slide=None, pairs=None) -> Coupled:
    """The bordered Newton system at frames (R, p) and multipliers y (M,), from the chains'
    residual r (N,6) and tangent ``blocks`` (held dofs already identity rows; the rods'
    terms of :func:`with_multipliers`), the couplings' own forces not yet in r. ``T``
    (N,6,6): the maps ``T_SE3(w)`` when the unknowns are a time step's increments w (None
    in statics). ``slide``: the sliding drives' maps ``(C, B, mask)`` that reduced r and
    the blocks (:func:`simsoft_jax.couplings.drives.slide_maps`; None: none). ``pairs``:
    the rod-rod contact's candidate pairs (:func:`simsoft_jax.couplings.rod_pairs.residual`;
    None: found at R, p). Without couplings
    (:func:`present`) the border is empty, ``r_z`` is y and the frames are not read.
    The kinds concatenate their borders: the rod-rod contact's pair terms are added to
    the whole nodal system first, then the joints take their coupling nodes' rows and
    columns out of the chains, and the contact's and tendons' borders follow
    (:func:`_appended`)."""
    s = model.structure
    borders = []
    if s.self_contact:
        r, blocks, contact = rod_pairs.system(model, R, p, r, blocks, T, slide, pairs)
        borders.append((contact.B, contact.C, contact.D,
                        jnp.zeros(contact.D.shape[0], r.dtype)))
    if tendon_lengths.count(s):
        B, C, D, r_z = tendon_lengths.border(model, R, p, T)
        borders.append(restrict_border(s, slide, B, C) + (D, r_z))
    m_joints, multipliers = _joint_sizes(s)
    if s.joints:
        system = mechanisms.couple(model, R, p, y[:multipliers], r, blocks, T)
    else:
        n = r.shape[0]
        system = Coupled(r, blocks, jnp.zeros((n, 6, 0), r.dtype),
                         jnp.zeros((0, n, 6), r.dtype), jnp.zeros((0, 0), r.dtype),
                         y if not present(s) else y[:0])
    for border in borders:
        system = _appended(s, system, *border)
    return system


def _appended(structure, first: Coupled, B2, C2, D2, r_z2) -> Coupled:
    """The bordered system ``first`` with another coupling's border appended: its columns
    B2 (N,6,m2) (forces on the nodes per unknown), rows C2 (m2,N,6) (reading the nodal
    increments), block D2 (m2,m2) and residual r_z2 (m2,). The nodal increments are the
    chains' x on chain nodes and the joints' first ``6 n_c`` border unknowns on their
    n_c coupling nodes, whose forces sit in the same places: so B2's and C2's coupling
    node rows and columns move into the D block between ``first``'s border and this one
    (none without joints)."""
    nodes = np.asarray(structure.coupling_nodes, dtype=int)
    chain = jnp.asarray(mechanisms.chain_mask(structure))
    m1, m2 = first.D.shape[0], D2.shape[0]
    dtype = first.r.dtype
    B_nodes = jnp.zeros((m1, m2), dtype).at[:6 * nodes.size].set(
        B2[nodes].reshape(-1, m2))
    C_nodes = jnp.zeros((m2, m1), dtype).at[:, :6 * nodes.size].set(
        C2[:, nodes].reshape(m2, -1))
    B = jnp.concatenate([first.B, B2 * chain[:, None, None]], axis=-1)
    C = jnp.concatenate([first.C, C2 * chain[None, :, None]], axis=0)
    D = jnp.block([[first.D, B_nodes], [C_nodes, D2]])
    return Coupled(first.r, first.blocks, B, C, D, jnp.concatenate([first.r_z, r_z2]))


def coupled_residual(model, R, p, y, r, slide=None, pairs=None):
    """``(r, r_z)`` of :func:`couple` without the matrix: the couplings' forces added to r
    (N,6) and their own residuals r_z (zero rows for rod-rod contact, whose border rows
    hold exactly in every solve; the tendons' length mismatches); ``pairs`` as in
    :func:`couple`."""
    s = model.structure
    if not present(s):
        return r, y
    if s.self_contact:
        r = r + rod_pairs.residual(model, R, p, slide, pairs)
    _, multipliers = _joint_sizes(s)
    if s.joints:
        r, r_z = mechanisms.residual(model, R, p, y[:multipliers], r)
    else:
        r_z = y[:0]
    parts = [r_z, jnp.zeros(_contact_size(s), r.dtype)]
    if tendon_lengths.count(s):
        parts.append(tendon_lengths.mismatch(model, R, p))
    return r, jnp.concatenate(parts)


def violation(model, r_z):
    """The couplings' own residual sizes ``(forces (N), gaps)``: the coupling nodes' forces
    and moments / char_length, and the joints' gaps / char_length and rotations (rad)
    (:func:`simsoft_jax.couplings.mechanisms.violation_norm`) with the tendons' length
    mismatches / char_length; None where the couplings have no residual of their own
    (rod-rod contact, none)."""
    s = model.structure
    k = tendon_lengths.count(s)
    if not (s.joints or k):
        return None
    m_joints, _ = _joint_sizes(s)
    forces = gaps = jnp.zeros((), r_z.dtype)
    if s.joints:
        forces, gaps = mechanisms.violation_norm(model, r_z[:m_joints])
    if k:
        gaps = jnp.sqrt(gaps ** 2 + jnp.sum((r_z[r_z.shape[0] - k:] / model.char_length) ** 2))
    return forces, gaps


def split(structure, x, z):
    """Nodal increments (N,6) and multipliers (M,) from the bordered solution: the chain
    part x (N,6) and the coupling part z (m,) (module docstring: the rod-rod contact's
    node copies are not unknowns of the solution)."""
    if not present(structure):
        return x, z
    m_joints, _ = _joint_sizes(structure)
    y = z[:0]
    if structure.joints:
        x, y = mechanisms.split(structure, x, z[:m_joints])
    k = tendon_lengths.count(structure)
    return x, jnp.concatenate([y, z[z.shape[0] - k:]])
