"""Driven nodes of dynamic scenes (spec 4.5): prescribed frames from the drive tables, the
prescribed step increments of held dofs, and the reduction of nodes that slide along a
direction (``slides_along``) to their slide unknown. The drive tables are arrays of the
:class:`~simsoft_jax.model.model.Model`, the driven nodes part of its structure; ``state`` is a
:class:`~simsoft_jax.solvers.dynamics.State`.
"""
from __future__ import annotations

import jax
import jax.numpy as jnp

from ..math import lie


def drive_poses(model, t):
    """Prescribed frames (D,3,3), (D,3) of the driven nodes at time ``t``."""
    interp = jax.vmap(lambda tt, vals: jax.vmap(lambda col: jnp.interp(t, tt, col),
                                                in_axes=1)(vals))
    disp = interp(model.drive_times, model.drive_displacement)
    rot = interp(model.drive_times, model.drive_rotation)
    idx = jnp.asarray(model.structure.drive_nodes, int)
    R = jnp.einsum("dij,djk->dik", jax.vmap(lie.exp_so3)(rot), model.R0[idx])
    return R, model.p0[idx] + disp


def drive_turn(model, t0, t1):
    """Largest change (rad) over the drives of their tables' rotation vectors from ``t0``
    to ``t1`` (s): the angle a driven node turns in that time for a drive about a fixed
    axis. A step whose drives turn by pi or more cannot be told from a shorter turn (the
    increment ``log(H_n^-1 H_c(t1))`` of :func:`held_increments` wraps); the dynamics
    refuse steps that turn a node by pi/2 or more (status ``OFF_BRANCH``)."""
    interp = jax.vmap(lambda tt, vals, t: jax.vmap(lambda col: jnp.interp(t, tt, col),
                                                   in_axes=1)(vals), in_axes=(0, 0, None))
    change = (interp(model.drive_times, model.drive_rotation, t1)
              - interp(model.drive_times, model.drive_rotation, t0))
    return jnp.max(jnp.linalg.norm(change, axis=1))


def slide_maps(model, R_n, w):
    """Reduction of the sliding drive nodes to one unknown each, the slide ``ds`` along the
    world direction e. With the rotation increment fixed, ``p_{n+1} = p_n + R_n T_SO3^T w_U``
    is linear in ``w_U``, so ``w += B ds`` with ``B[:, 0] = [T_SO3^-T R_n^T e; 0]`` moves the
    node by ``ds e``. Its equation is the force along e at the new state: ``C r`` with
    ``C[0] = [R_{n+1}^T e; 0]`` (both exact and constant during a step's Newton iterations).
    Returns ``(C, B, mask)``: (N,6,6) row and column maps (identity elsewhere) and the free
    mask with the slide dof (row/column 0) of those nodes free."""
    s = model.structure
    n = s.n_nodes
    sl = jnp.asarray(s.slide_drives, int)
    idx = jnp.asarray(s.drive_nodes, int)[sl]
    e = model.drive_slide[sl]
    Rn, wr = R_n[idx], w[idx, 3:]
    body = jnp.einsum("kji,kj->ki", Rn, e)                              # R_n^T e
    b = jnp.einsum("kji,kj->ki", jax.vmap(lie.tangent_so3_inv)(wr), body)  # T^-T R_n^T e
    c = jnp.einsum("kji,kj->ki", jax.vmap(lie.exp_so3)(wr), body)       # R_{n+1}^T e
    zeros = jnp.zeros((len(s.slide_drives), 6, 6))
    Cn = zeros.at[:, 0, :3].set(c)
    Bn = zeros.at[:, :3, 0].set(b)
    eye = jnp.broadcast_to(jnp.eye(6), (n, 6, 6))
    mask = s.free_mask().at[idx].set(jnp.eye(6)[0])
    return eye.at[idx].set(Cn), eye.at[idx].set(Bn), mask


def reduce(C, B, r, blocks):
    """``r_i -> C_i r_i``, ``K_ij -> C_i K_ij B_j`` on the block-tridiagonal matrix."""
    diag, upper, lower = blocks
    diag = C @ diag @ B
    upper = C[:-1] @ upper @ B[1:]
    lower = C[1:] @ lower @ B[:-1]
    return jnp.einsum("nij,nj->ni", C, r), (diag, upper, lower)


def restrict(structure, slide, r, blocks=None):
    """Terms added to the chains' reduced system: the residual ``r`` (N,6) and the
    block-tridiagonal ``blocks`` reduced by the sliding drives' maps ``slide = (C, B,
    mask)`` (:func:`slide_maps`; None: none) as :func:`reduce` does, then their held rows
    and columns zeroed (``mask``, else ``structure.free_mask()``; no identity rows: the
    chains' own system holds them). Returns r, or ``(r, blocks)`` when blocks are given."""
    mask = structure.free_mask()
    if slide is not None:
        C, B, mask = slide
        if blocks is None:
            r = jnp.einsum("nij,nj->ni", C, r)
        else:
            r, blocks = reduce(C, B, r, blocks)
    if blocks is None:
        return r * mask
    diag, upper, lower = blocks
    return r * mask, (mask[:, :, None] * diag * mask[:, None, :],
                      mask[:-1, :, None] * upper * mask[1:, None, :],
                      mask[1:, :, None] * lower * mask[:-1, None, :])


def restrict_border(structure, slide, B, C):
    """A coupling's border on the chains' reduced system: its columns B (N,6,m) become
    ``mask_i C_i B_i`` and its rows C (m,N,6) ``C_j B_j mask_j``, the reduction of
    :func:`reduce` with the sliding drives' maps ``slide = (C, B, mask)``
    (:func:`slide_maps`; None: only the held dofs zeroed, ``structure.free_mask()``)."""
    if slide is None:
        mask = structure.free_mask()
        return B * mask[:, :, None], C * mask[None]
    Cs, Bs, mask = slide
    return (jnp.einsum("nij,njm->nim", Cs, B) * mask[:, :, None],
            jnp.einsum("mni,nij->mnj", C, Bs) * mask[None])


def held_increments(model, state, t1):
    """Prescribed ``w`` of held dofs: 0 for clamps and pins, ``log(H_n^-1 H_c(t))`` for drives.
    A sliding drive keeps its current slide ``s_n = (p_n - p_c(t_n)) . e``: its target
    position is ``p_c(t1) + s_n e`` (Newton then solves for the change of slide)."""
    w = jnp.zeros_like(state.v)
    s = model.structure
    if s.drive_nodes:
        idx = jnp.asarray(s.drive_nodes, int)
        Rc, pc = drive_poses(model, t1)
        if s.slide_drives:
            e = model.drive_slide  # zero rows for drives that do not slide
            s_n = jnp.sum((state.p[idx] - drive_poses(model, state.t)[1]) * e, axis=1)
            pc = pc + s_n[:, None] * e
        wd = jax.vmap(lambda Ra, pa, Rb, pb: lie.log_se3(lie.relative_pose(Ra, pa, Rb, pb)))(
            state.R[idx], state.p[idx], Rc, pc)
        w = w.at[idx].set(wd)
    return w
