"""Global static residual and block-tridiagonal tangent from vmapped element kernels.

Residual convention (spec S47, S70): ``r = f_int - lam * f_ext`` per node (N,6), in the
nodal frames. Tangent (left-invariant, S70): ``K_t = d r(q o exp(xi)) / d xi`` at xi = 0,
built from per-element 12x12 blocks (never the global residual). The residual itself is the
sum of the residual terms of :mod:`simsoft_jax.terms`. Two tangent paths, chosen for a
whole solve by ``tangent``: ``"closed_form"`` (the elastic part, gravity, world-frame
distributed loads and nodal loads in closed form, :func:`element_force_and_tangent`;
follower distributed loads by ``jax.jacfwd`` in 6 directions) and ``"autodiff"``
(``jax.jacfwd`` of the sum of the terms in the 12 frame perturbations,
:mod:`simsoft_jax.terms.autodiff`); both give the same exact tangent. They are assembled
into a
block-tridiagonal matrix of 6x6 blocks ``(diag (N,6,6), upper (N-1,6,6), lower (N-1,6,6))``,
``upper[i] = K[i, i+1]``, ``lower[i] = K[i+1, i]``. Held dofs get an identity row/column and
a zero residual, so the structure never changes. Linear solves: :func:`factorize` (dense
LU for short chains, block Thomas otherwise) and :func:`solve_factored`.
"""
from __future__ import annotations

import jax
import jax.numpy as jnp

from . import element, lie
from .model import Model
from .terms import ElementData, element_state
from .terms import autodiff as term_tangents

TANGENTS = ("closed_form", "autodiff")


def check_tangent(tangent: str) -> str:
    """``tangent`` if it names a tangent path, else a clear error."""
    if tangent not in TANGENTS:
        raise ValueError(f"tangent: must be one of {TANGENTS}, got {tangent!r}")
    return tangent


def dead_distributed_force(model: Model, lam):
    """``-lam (q_world + rho_a g)`` (3,) per element as a function of ``(rho_a, q_world)``:
    the dead force per unit length (N/m) of gravity and world-frame distributed loads on
    the residual side, or None when the scene has neither (then nothing of it is traced)."""
    s = model.structure
    if not (s.has_gravity or s.has_distributed_world):
        return None
    return lambda rho_a, q_world: -lam * (q_world + rho_a * model.gravity)


def follower_distributed_load(model: Model, lam):
    """``-lam f_local`` (12,) of one element's follower distributed load as a function of
    ``(d, P, length, q_local)`` (:func:`element.follower_distributed_force`), or None when
    the scene has none."""
    if not model.structure.has_distributed_local:
        return None
    return lambda d, P, length, q_local: -lam * element.follower_distributed_force(
        d, P, length, q_local)


def follower_load_and_tangent(load, d, P, length, q_local):
    """Value (12,) and left-invariant tangent (12,12) of a :func:`follower_distributed_load`:
    it depends on the frames through d only, so ``jax.jacfwd`` in the 6 components of d is
    chained with the chart ``d + P(d) x`` of spec S37."""
    def f(y):
        dd = d + y
        return load(dd, element.strain_map(dd), length, q_local)

    jac, val = jax.jacfwd(lambda y: (f(y),) * 2, has_aux=True)(jnp.zeros(6, d.dtype))
    return val, jac @ P


def element_force_and_tangent(P, d, stress, stress_jacobian, RA, length, dead, follower,
                              rho_a, q_world, q_local):
    """Nodal forces (12,) and left-invariant tangent (12,12) of one element from its section
    stress (6,) and ``d stress / d d`` (6,6) (elastic, plus viscous in dynamics) and its
    distributed loads: ``dead`` (:func:`dead_distributed_force`, of ``rho_a, q_world``) and
    ``follower`` (:func:`follower_distributed_load`, of ``q_local`` (3,)), each None when
    the scene has none.

    The dead load enters as an extra stress and stress Jacobian plus rigid-motion terms
    (:func:`element.dead_load_terms`), so one geometric term serves both (spec S42, S44).
    """
    direct = None
    if dead is not None:
        s_q, S_q, f_direct, K_direct = element.dead_load_terms(RA, d, P, length,
                                                               dead(rho_a, q_world))
        stress, stress_jacobian = stress + s_q, stress_jacobian + S_q
        direct = (f_direct, K_direct)
    f, k = element.stress_force_and_tangent(P, d, stress, stress_jacobian)
    if direct is not None:
        f, k = f + direct[0], k + direct[1]
    if follower is not None:
        f_q, k_q = follower_load_and_tangent(follower, d, P, length, q_local)
        f, k = f + f_q, k + k_q
    return f, k


def element_data(model: Model, maps=None, masses=None) -> ElementData:
    """The per-element model arrays (E, ...) of :class:`~simsoft_jax.terms.ElementData`
    (``maps``, ``masses``: element inertia in dynamics, None in statics)."""
    n = model.length.shape[0]
    return ElementData(model.d0, model.length, model.stiffness, model.inertia,
                       model.viscosity, model.distributed_world, model.distributed_local,
                       jnp.broadcast_to(model.gravity, (n, 3)), maps, masses)


def element_poses(model: Model, R, p):
    """Frames of the two nodes of every element: RA, pA, RB, pB (E,3,3)/(E,3)."""
    a = jnp.asarray(model.structure.element_nodes)
    return R[a], p[a], R[a + 1], p[a + 1]


def _nodal_load(model: Model, lam):
    """``-lam f_ext`` at one node (:mod:`simsoft_jax.terms.nodal`; spec S43)."""
    return term_tangents.node_residual(model.structure, lam)


def _element_args(model: Model, R, p):
    a = jnp.asarray(model.structure.element_nodes)
    d = jax.vmap(element.relative_twist)(R[a], p[a], R[a + 1], p[a + 1])
    return (R[a], d, model.d0, model.length, model.stiffness, model.inertia[:, 0],
            model.distributed_world, model.distributed_local)


def assemble_vector(n_nodes, element_nodes, f_el):
    """Scatter element vectors (E,12) to nodes (N,6) (spec S47)."""
    a = jnp.asarray(element_nodes)
    return jnp.zeros((n_nodes, 6)).at[a].add(f_el[:, :6]).at[a + 1].add(f_el[:, 6:])


def assemble_blocks(n_nodes, element_nodes, k_el):
    """Element matrices (E,12,12) -> block-tridiagonal ``(diag, upper, lower)`` (spec 3.6)."""
    a = jnp.asarray(element_nodes)
    diag = jnp.zeros((n_nodes, 6, 6)).at[a].add(k_el[:, :6, :6]).at[a + 1].add(k_el[:, 6:, 6:])
    upper = jnp.zeros((max(n_nodes - 1, 0), 6, 6)).at[a].set(k_el[:, :6, 6:])
    lower = jnp.zeros((max(n_nodes - 1, 0), 6, 6)).at[a].set(k_el[:, 6:, :6])
    return diag, upper, lower


def nodal_load_and_tangent(model: Model, lam, R, tangent: str = "closed_form"):
    """``-lam f_ext`` per node (N,6) and its left-invariant derivative (N,6,6) (spec S43):
    with ``a = R^T F`` (dead force or moment), ``(R exp(theta))^T F = a + skew(a) theta``,
    so the rotation columns hold ``-lam skew(R^T F)``, ``-lam skew(R^T M)``; follower loads
    do not depend on the frame. ``tangent="autodiff"``: ``jax.jacfwd`` of the node terms."""
    s = model.structure
    if tangent == "autodiff":
        return jax.vmap(term_tangents.node_tangent(s, lam))(R, model.nodal_dead,
                                                            model.nodal_follower)
    r = jax.vmap(_nodal_load(model, lam))(R, model.nodal_dead, model.nodal_follower)
    k = jnp.zeros(R.shape[:1] + (6, 6), R.dtype)
    if s.has_nodal_dead:
        local = jnp.einsum("nji,nkj->nki", R, model.nodal_dead.reshape(-1, 2, 3))
        skews = jax.vmap(jax.vmap(lie.skew))(local)                     # (N, 2, 3, 3)
        k = k.at[:, :3, 3:].set(-lam * skews[:, 0]).at[:, 3:, 3:].set(-lam * skews[:, 1])
    return r, k


def residual(model: Model, R, p, lam=1.0):
    """Global residual (N,6), held dofs zeroed (spec S47/S70): the sum of the terms."""
    s = model.structure
    zeros = jnp.zeros((s.n_elements, 12), p.dtype)
    element_residual = term_tangents.element_residual(s, lam, dynamic=False)
    f_el = jax.vmap(lambda RA, pA, RB, pB, data: element_residual(
        element_state(RA, pA, RB, pB, zeros[0], zeros[0]), data))(
        *element_poses(model, R, p), element_data(model))
    r = assemble_vector(s.n_nodes, s.element_nodes, f_el)
    if s.has_nodal_dead or s.has_nodal_follower:
        r = r + jax.vmap(_nodal_load(model, lam))(R, model.nodal_dead, model.nodal_follower)
    return r * s.free_mask()


def residual_and_tangent(model: Model, R, p, lam=1.0, tangent: str = "closed_form"):
    """Residual (N,6) and block-tridiagonal tangent ``(diag, upper, lower)`` (spec S70),
    by the ``tangent`` path ("closed_form" or "autodiff", see the module docstring)."""
    s = model.structure
    if tangent == "autodiff":
        zero = jnp.zeros(12, p.dtype)
        tangents = term_tangents.element_tangents(s, lam, dynamic=False)
        f_el, k_el, _, _ = jax.vmap(lambda RA, pA, RB, pB, data: tangents(
            RA, pA, RB, pB, zero, zero, data))(*element_poses(model, R, p), element_data(model))
    else:
        dead = dead_distributed_force(model, lam)
        follower = follower_distributed_load(model, lam)

        def value_and_jac(RA, d, d0, length, stiffness, rho_a, q_world, q_local):
            # elastic stress and loads in closed form (spec S42, S44); follower loads by jacfwd
            P = element.strain_map(d)
            return element_force_and_tangent(
                P, d, stiffness * (d - d0) / length, jnp.diag(stiffness / length), RA, length,
                dead, follower, rho_a, q_world, q_local)

        f_el, k_el = jax.vmap(value_and_jac)(*_element_args(model, R, p))
    r = assemble_vector(s.n_nodes, s.element_nodes, f_el)
    diag, upper, lower = assemble_blocks(s.n_nodes, s.element_nodes, k_el)
    if s.has_nodal_dead or s.has_nodal_follower:
        f_n, k_n = nodal_load_and_tangent(model, lam, R, tangent)
        r = r + f_n
        diag = diag + k_n
    return apply_constraints(s.free_mask(), r, (diag, upper, lower))


def apply_constraints(mask, r, blocks):
    """Zero held rows of ``r``; identity rows/columns for held dofs in the blocks."""
    diag, upper, lower = blocks
    diag = mask[:, :, None] * diag * mask[:, None, :] + jax.vmap(jnp.diag)(1.0 - mask)
    upper = mask[:-1, :, None] * upper * mask[1:, None, :]
    lower = mask[1:, :, None] * lower * mask[:-1, None, :]
    return r * mask, (diag, upper, lower)


# --------------------------------------------------------------------------------------
# Block-tridiagonal linear algebra
# --------------------------------------------------------------------------------------

def block_matvec(blocks, x):
    """``K @ x`` for a block-tridiagonal ``K`` and ``x`` (N,6)."""
    diag, upper, lower = blocks
    y = jnp.einsum("nij,nj->ni", diag, x)
    y = y.at[:-1].add(jnp.einsum("nij,nj->ni", upper, x[1:]))
    return y.at[1:].add(jnp.einsum("nij,nj->ni", lower, x[:-1]))


def block_transpose(blocks):
    """Blocks of ``K^T``."""
    diag, upper, lower = blocks
    t = lambda b: jnp.swapaxes(b, -1, -2)  # noqa: E731
    return t(diag), t(lower), t(upper)


# Chains of at most this many nodes are solved by a dense LU of the assembled matrix: on
# CPU one LAPACK factorization of a (6N, 6N) matrix beats the N sequential 6x6 steps of the
# block-Thomas scan up to about 12 nodes (benchmarks/README.md), and a factorized dense
# matrix is re-solved in a few microseconds (modified Newton, IFT).
DENSE_LIMIT_NODES = 12


def lu(A):
    """Partial-pivoting LU of a square matrix: ``(lu, perm)`` with ``A[perm] = L U``.

    The row permutation is formed once here: ``jax.scipy.linalg.lu_solve`` rebuilds it
    from LAPACK's pivots at every solve in an n-step loop, which cost more than the two
    triangular solves themselves (66 loop iterations per solve of an 11-node chain).
    """
    factors, _, perm = jax.lax.linalg.lu(A)
    return factors, perm


def lu_solve(factors, b, transpose=False):
    """Solve ``A x = b`` (or ``A^T x = b``) with ``factors = lu(A)``; b (n,) or (n, k)."""
    f, perm = factors
    tri = jax.lax.linalg.triangular_solve
    x = b if b.ndim == 2 else b[:, None]
    if transpose:  # A^T = U^T L^T P: solve U^T, then L^T, then undo the permutation
        x = tri(f, x, left_side=True, lower=False, transpose_a=True)
        x = tri(f, x, left_side=True, lower=True, unit_diagonal=True, transpose_a=True)
        x = jnp.zeros_like(x).at[perm].set(x)
    else:
        x = tri(f, x[perm], left_side=True, lower=True, unit_diagonal=True)
        x = tri(f, x, left_side=True, lower=False)
    return x if b.ndim == 2 else x[:, 0]


def factorize(blocks):
    """Factors of a block-tridiagonal ``K`` for :func:`solve_factored` (spec 3.6).

    Chosen at trace time by size: ``(lu, perm)`` (:func:`lu`) of the (6N, 6N) matrix for
    N <= ``DENSE_LIMIT_NODES``; otherwise the block LU of block Thomas
    ``(lu (N,6,6), perm (N,6), C (N,6,6), lower (N-1,6,6))`` with pivot blocks
    ``S_i = D_i - L_i C_{i-1}`` (each LU-factorized with partial pivoting) and
    ``C_i = S_i^-1 U_i``. O(N) 6x6 operations (``lax.scan``); a singular pivot gives
    non-finite solutions, which the Newton solvers detect and report.
    """
    diag, upper, lower = blocks
    n = diag.shape[0]
    if n <= DENSE_LIMIT_NODES:
        return lu(dense(blocks))
    pad_u = jnp.concatenate([upper, jnp.zeros((1, 6, 6))])
    pad_l = jnp.concatenate([jnp.zeros((1, 6, 6)), lower])

    def forward(c_prev, inputs):
        D, U, L = inputs
        factors = lu(D - L @ c_prev)
        c = lu_solve(factors, U)
        return c, (*factors, c)

    _, (f, perm, C) = jax.lax.scan(forward, jnp.zeros((6, 6)), (diag, pad_u, pad_l))
    return f, perm, C, lower


def solve_factored(factors, b):
    """Solve ``K x = b`` with the factors of :func:`factorize`; b, x (N,6)."""
    if len(factors) == 2:
        return lu_solve(factors, b.reshape(-1)).reshape(b.shape)
    f, perm, C, lower = factors
    pad_l = jnp.concatenate([jnp.zeros((1, 6, 6)), lower])

    def forward(y_prev, inputs):
        f_i, perm_i, L, bi = inputs
        y = lu_solve((f_i, perm_i), bi - L @ y_prev)
        return y, y

    _, Y = jax.lax.scan(forward, jnp.zeros(6), (f, perm, pad_l, b))

    def backward(x_next, inputs):
        c, y = inputs
        x = y - c @ x_next
        return x, x

    _, X = jax.lax.scan(backward, jnp.zeros(6), (C, Y), reverse=True)
    return X


def block_solve(blocks, b):
    """Solve ``K x = b`` for a block-tridiagonal ``K``; b, x (N,6) (see :func:`factorize`)."""
    return solve_factored(factorize(blocks), b)


def implicit_solve(blocks, b):
    """``K^-1 b`` (N,6) inside ``lax.custom_linear_solve`` (the implicit-function-theorem
    solve of statics and dynamics): one factorization of ``K`` serves the solve, and for
    dense factors the transposed solve of reverse mode too."""
    factors = factorize(blocks)

    def transpose_solve(_, y):
        if len(factors) == 2:
            return lu_solve(factors, y.reshape(-1), transpose=True).reshape(y.shape)
        return block_solve(block_transpose(blocks), y)

    return jax.lax.custom_linear_solve(
        lambda x: block_matvec(blocks, x), b,
        solve=lambda _, y: solve_factored(factors, y), transpose_solve=transpose_solve)


def dense(blocks):
    """The block-tridiagonal matrix as a dense (6N, 6N) array (tests and debugging)."""
    diag, upper, lower = blocks
    n = diag.shape[0]
    K = jnp.zeros((n, 6, n, 6))
    idx = jnp.arange(n)
    K = K.at[idx, :, idx, :].set(diag)
    if n > 1:
        K = K.at[idx[:-1], :, idx[1:], :].set(upper)
        K = K.at[idx[1:], :, idx[:-1], :].set(lower)
    return K.reshape(6 * n, 6 * n)
