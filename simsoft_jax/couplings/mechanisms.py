"""Rods, rigid bodies and joints in one Newton system (DESIGN "Linear algebra for
mechanisms"): the rods' nodes form block-tridiagonal chains; the coupling nodes' 6 DOF
(the rigid bodies and a few rod nodes of joints, :mod:`simsoft_jax.model.joint_layout`) and
the joint multipliers form a small coupling set ``z``; the bordered system

    [[K, B], [C, D]] [dx; dz] = -[r; r_z]

is solved by :func:`simsoft_jax.math.linalg.solve_coupled` (block cyclic reduction on the chains, a dense
Schur complement on the couplings): O(N m + m^3) for m coupling unknowns.

The joint terms (:mod:`simsoft_jax.physics.terms.joints`) are, per joint, the vector
``phi(x_a, x_b, mu) = [d(mu.g)/dx_a; d(mu.g)/dx_b; g]`` (12 + k) and its exact Jacobian by
``jax.jacfwd`` (symmetric: the Hessian of the Lagrangian ``mu . g``). Every weld has a
coupling node on one side, and a ball joint's ``g`` is a sum of a function of node a and
one of node b, so no entry of a joint's Jacobian joins two chain nodes: the chains stay
chains. Coupling nodes have rows in the nodal arrays like the others (bodies: their
attached-mass weight, :mod:`simsoft_jax.physics.terms.masses`); their rows and the blocks that
join them to their chain neighbours are moved into the coupling set here, which holds
each chain at them (every chain is then nonsingular on its own).

Coupling vector ``z = [coupling-node twists (6 each, in coupling_nodes order);
multipliers]``.
"""
from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from ..math import lie
from ..physics.terms import joints as joint_terms


class Coupled(NamedTuple):
    """The bordered Newton system: r (N,6) and blocks (chains, coupling-node rows replaced
    by identity), B (N,6,m), C (m,N,6), D (m,m), r_z (m,) (coupling-node residuals, then the joint
    constraints g)."""
    r: jax.Array
    blocks: tuple
    B: jax.Array
    C: jax.Array
    D: jax.Array
    r_z: jax.Array


def multiplier_count(structure) -> int:
    """Number of joint multipliers (3 per ball, 6 per weld)."""
    return sum(joint_terms.SIZES[kind] for kind, _, _ in structure.joints)


def coupling_count(structure) -> int:
    """Size m of the coupling set: 6 per coupling node plus the multipliers."""
    return 6 * len(structure.coupling_nodes) + multiplier_count(structure)


def _groups(structure):
    """Joints grouped by kind (static): per kind ``(kind, joints, k, is_rod, node, dof, z)``
    with ``joints`` the joint indices and, per joint and local unknown of
    ``[x_a; x_b; mu]`` (12 + k), where it lives: ``is_rod`` a rod node's dof (node,
    dof), else the coupling index z (NumPy int arrays (J_kind, 12 + k))."""
    coupled = {node: k for k, node in enumerate(structure.coupling_nodes)}
    starts = np.cumsum([0] + [joint_terms.SIZES[kind] for kind, _, _ in structure.joints])
    out = []
    for kind in joint_terms.SIZES:
        members = [j for j, (kd, _, _) in enumerate(structure.joints) if kd == kind]
        if not members:
            continue
        k = joint_terms.SIZES[kind]
        rows = []
        for j in members:
            _, a, b = structure.joints[j]
            ends = [(end, d) for end in (a, b) for d in range(6)]
            is_rod = [end not in coupled for end, _ in ends] + [False] * k
            node = [end if end not in coupled else 0 for end, _ in ends] + [0] * k
            dof = [d for _, d in ends] + [0] * k
            z = [0 if end not in coupled else 6 * coupled[end] + d for end, d in ends]
            z += list(6 * len(coupled) + starts[j] + np.arange(k))
            rows.append((is_rod, node, dof, z))
        out.append((kind, np.asarray(members), k) + tuple(np.asarray(v) for v in zip(*rows)))
    return out


def _joint_values_and_jacobians(model, R, p, mu, kind, members, k, z, T=None):
    """``phi`` (J,12+k) and its Jacobians (J,12+k,12+k) in ``[x_a; x_b; mu]`` (module
    docstring) of the joints ``members`` of one kind, vmapped; ``z`` their index table
    (the multipliers sit at its last k columns). With ``T`` (N,6,6) the frames are
    ``q_n exp(w)`` of a time step and the unknowns its increments ``w``: the columns of
    ``x_a, x_b`` are multiplied by ``T_SE3(w)`` of their node (the chain rule of S61)."""
    s = model.structure
    idx = jnp.asarray(members)
    a = jnp.asarray([s.joints[j][1] for j in members])
    b = jnp.asarray([s.joints[j][2] for j in members])

    def one(Ra, pa, Rb, pb, mu_j, offset_a, offset_b, rotation):
        def phi(y):
            def lagrangian(x):
                # exact to second order at x = 0: all the Newton matrix needs
                Ra1, pa1 = lie.compose_exp_quadratic(Ra, pa, x[:6])
                Rb1, pb1 = lie.compose_exp_quadratic(Rb, pb, x[6:])
                g = joint_terms.constraint(kind, Ra1, pa1, Rb1, pb1, offset_a, offset_b,
                                           rotation)
                return jnp.dot(y[12:], g), g
            force, g = jax.grad(lagrangian, has_aux=True)(y[:12])
            value = jnp.concatenate([force, g])
            return value, value

        jac, value = jax.jacfwd(phi, has_aux=True)(
            jnp.concatenate([jnp.zeros(12, pa.dtype), mu_j]))
        return value, jac

    mu_of = mu[jnp.asarray(z[:, 12:]) - 6 * len(s.coupling_nodes)]
    value, jac = jax.vmap(one)(R[a], p[a], R[b], p[b], mu_of, model.joint_offset_a[idx],
                               model.joint_offset_b[idx], model.joint_rotation[idx])
    if T is not None:
        jac = jnp.concatenate([jac[:, :, :6] @ T[a], jac[:, :, 6:12] @ T[b], jac[:, :, 12:]],
                              axis=2)
    return value, jac


def chain_mask(structure) -> np.ndarray:
    """(N,) 1 on the nodes solved in the chains, 0 on the coupling nodes (static)."""
    chain = np.ones(structure.n_nodes)
    chain[list(structure.coupling_nodes)] = 0.0
    return chain


def _residuals(model, r, joint_values):
    """The chain residual (N,6) and the coupling residual ``r_z`` (m,) from the rods'
    residual ``r`` (N,6, masked): the coupling nodes' rows move into ``r_z``, and each
    joint group's values ``phi`` (``joint_values``, in :func:`_groups` order) are added
    where they live; held dofs of coupling nodes get no residual."""
    s = model.structure
    mask = s.free_mask()
    nodes = jnp.asarray(s.coupling_nodes, dtype=int)
    nb = len(s.coupling_nodes)
    r_z = jnp.concatenate([r[nodes].reshape(-1),
                           jnp.zeros(coupling_count(s) - 6 * nb, r.dtype)])
    r = r * jnp.asarray(chain_mask(s))[:, None]
    for value, (_, _, _, is_rod, node, dof, z) in zip(joint_values, _groups(s)):
        rod = jnp.asarray(is_rod, r.dtype)                  # (J, 12 + k)
        r = r.at[node, dof].add(value * mask[node, dof] * rod)
        r_z = r_z.at[z].add(value * (1.0 - rod))
    return r, r_z * _coupling_mask(s, mask)


def couple(model, R, p, mu, r, blocks, T=None) -> Coupled:
    """The bordered system at frames (R, p) (N,...) and multipliers ``mu`` (M,), from the
    rods' residual ``r`` (N,6) and tangent ``blocks`` (held dofs already identity rows).
    ``T`` (N,6,6): the nodes' ``T_SE3(w)`` when the unknowns are the increments ``w`` of a
    time step (the blocks then already carry it, spec S61); None in statics."""
    s = model.structure
    mask = s.free_mask()
    m = coupling_count(s)
    diag, upper, lower = blocks
    B = jnp.zeros(r.shape + (m,), p.dtype)
    C = jnp.zeros((m,) + r.shape, p.dtype)
    D = jnp.zeros((m, m), p.dtype)
    n = s.n_nodes
    # a coupling node's rows, and the element blocks joining it to its chain neighbours,
    # leave the chain (scatter-adds and masks only: reverse mode transposes them)
    in_chain = chain_mask(s)
    link = in_chain[:-1] * in_chain[1:]          # element blocks that stay in a chain
    column = {i: slice(6 * k, 6 * k + 6) for k, i in enumerate(s.coupling_nodes)}
    for i, cols in column.items():
        D = D.at[cols, cols].add(diag[i])
        if i > 0:           # the blocks with node i-1 (zero blocks across rods)
            B = B.at[i - 1, :, cols].add(upper[i - 1] * in_chain[i - 1])
            C = C.at[cols, i - 1].add(lower[i - 1] * in_chain[i - 1])
        if i < n - 1:
            B = B.at[i + 1, :, cols].add(lower[i] * in_chain[i + 1])
            C = C.at[cols, i + 1].add(upper[i] * in_chain[i + 1])
        if i + 1 in column:                      # two coupling nodes side by side
            D = D.at[cols, column[i + 1]].add(upper[i])
            D = D.at[column[i + 1], cols].add(lower[i])
    keep_rows = jnp.asarray(in_chain)[:, None, None]
    diag = diag * keep_rows + (1.0 - keep_rows) * jnp.eye(6, dtype=p.dtype)
    upper, lower = upper * link[:, None, None], lower * link[:, None, None]
    values = []
    for kind, members, k, is_rod, node, dof, z in _groups(s):
        value, jac = _joint_values_and_jacobians(model, R, p, mu, kind, members, k, z, T)
        values.append(value)
        rod = jnp.asarray(is_rod, p.dtype)                  # (J, 12 + k)
        free = mask[node, dof] * rod
        coupling = 1.0 - rod
        same = node[:, :, None] == node[:, None, :]
        both = free[:, :, None] * free[:, None, :] * same
        diag = diag.at[node[:, :, None], dof[:, :, None], dof[:, None, :]].add(jac * both)
        B = B.at[node[:, :, None], dof[:, :, None], z[:, None, :]].add(
            jac * free[:, :, None] * coupling[:, None, :])
        C = C.at[z[:, :, None], node[:, None, :], dof[:, None, :]].add(
            jac * coupling[:, :, None] * free[:, None, :])
        D = D.at[z[:, :, None], z[:, None, :]].add(
            jac * coupling[:, :, None] * coupling[:, None, :])
    r, r_z = _residuals(model, r, values)
    keep = _coupling_mask(s, mask)          # held dofs of coupling nodes stay put
    D = keep[:, None] * D * keep[None, :] + jnp.diag(1.0 - keep)
    return Coupled(r, (diag, upper, lower), B * keep, C * keep[:, None, None], D, r_z)


def _coupling_mask(structure, mask):
    """(m,) 1 where a coupling unknown is free: the free dofs of the coupling nodes, and
    every multiplier."""
    nodes = jnp.asarray(structure.coupling_nodes, dtype=int)
    return jnp.concatenate([mask[nodes].reshape(-1),
                            jnp.ones(multiplier_count(structure), mask.dtype)])


def residual(model, R, p, mu, r):
    """Residuals of the bordered system without its matrix: the rods' residual ``r``
    (N,6, masked) plus the joint forces, and ``r_z`` (m,)."""
    values = [_joint_values_and_jacobians(model, R, p, mu, kind, members, k, z)[0]
              for kind, members, k, _, _, _, z in _groups(model.structure)]
    return _residuals(model, r, values)


def split(structure, x, z):
    """Chain solution ``x`` (N,6) and coupling solution ``z`` (m,) -> the nodal increments
    (N,6) (coupling-node rows from z) and the multiplier increments (M,)."""
    nb = len(structure.coupling_nodes)
    nodes = jnp.asarray(structure.coupling_nodes, dtype=int)
    return (x * chain_mask(structure)[:, None]
            + jnp.zeros_like(x).at[nodes].add(z[:6 * nb].reshape(nb, 6)), z[6 * nb:])


def violation_norm(model, r_z):
    """Weighted size of the coupling residuals: coupling-node forces (N) and moments / char_length
    like :func:`simsoft_jax.solvers.statics.weighted_norm`, joint gaps / char_length and joint
    rotations (rad), as a pair (forces, gaps)."""
    structure = model.structure
    nb = len(structure.coupling_nodes)
    body = r_z[:6 * nb].reshape(nb, 6)
    forces = jnp.sqrt(jnp.sum(body[:, :3] ** 2) + jnp.sum((body[:, 3:] / model.char_length) ** 2))
    gaps = jnp.zeros((), r_z.dtype)
    start = 6 * nb
    for kind, _, _ in structure.joints:
        g = r_z[start:start + joint_terms.SIZES[kind]]
        gaps = gaps + jnp.sum((g[:3] / model.char_length) ** 2) + jnp.sum(g[3:] ** 2)
        start += joint_terms.SIZES[kind]
    return forces, jnp.sqrt(gaps)


def constraint_curvature(model, R, p, v):
    """``d^2/dt^2 g(q exp(t v))`` at ``t = 0`` (M,), in joint order: the velocity part of the
    joints' acceleration constraint ``G vdot + g''[v, v] = 0`` (``G`` the constraint
    Jacobian in the right perturbations), for consistent start accelerations; v (N,6) the
    nodal body velocities. Uses :func:`simsoft_jax.math.lie.compose_exp_quadratic`, exact to
    second order."""
    s = model.structure
    out = []
    for j, (kind, a, b) in enumerate(s.joints):
        def along(t, kind=kind, a=a, b=b, j=j):
            Ra, pa = lie.compose_exp_quadratic(R[a], p[a], t * v[a])
            Rb, pb = lie.compose_exp_quadratic(R[b], p[b], t * v[b])
            return joint_terms.constraint(kind, Ra, pa, Rb, pb, model.joint_offset_a[j],
                                          model.joint_offset_b[j], model.joint_rotation[j])

        def slope(t, along=along):
            return jax.jvp(along, (t,), (jnp.ones_like(t),))[1]

        t0 = jnp.zeros((), p.dtype)
        out.append(jax.jvp(slope, (t0,), (jnp.ones_like(t0),))[1])
    return jnp.concatenate(out) if out else jnp.zeros(0, p.dtype)
