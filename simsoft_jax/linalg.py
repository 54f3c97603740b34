"""Block linear algebra of mechanisms: block-tridiagonal chains and their couplings.

What it solves:

* a chain ``K x = b`` (and ``K^T x = b``), ``K`` block-tridiagonal with 6x6 blocks: one rod,
  or several rods concatenated with zero coupling blocks between them;
* a coupled system ``[[K, B], [C, D]] [x; y] = [b; c]`` (and its transpose), where the m
  extra unknowns ``y`` are joint forces, rigid-body dofs or Lagrange multipliers. The
  constraint case ``C = B^T, D = 0`` (a saddle point) is included: only ``K`` and the Schur
  complement ``S`` below have to be nonsingular, not ``D``.

Shapes: ``K`` as blocks ``(diag (N,6,6), upper (N-1,6,6), lower (N-1,6,6))`` with
``upper[i] = K[i, i+1]``, ``lower[i] = K[i+1, i]``; x, b (N,6); B (N,6,m), C (m,N,6),
D (m,m); y, c (m,). m may be 0.

Method. Chain (spec 3.6): for N <= ``DENSE_LIMIT_NODES`` a partial-pivoting LU of the
assembled (6N, 6N) matrix; otherwise block Thomas, i.e. the block LU of a tridiagonal
matrix ``K = L U``: ``L`` block lower bidiagonal with pivot blocks
``S_i = D_i - L_i C_{i-1}`` (each LU-factorized with partial pivoting) and sub-diagonal
``lower``, ``U`` unit block upper bidiagonal with ``C_i = S_i^-1 U_i``; forward and back
substitution are ``lax.scan``s, and the same factors solve ``K^T = U^T L^T``. Coupling: Schur
complement on the coupling unknowns: with ``K`` factorized once, ``K^-1 B`` (m solves) and a
dense LU of ``S = D - C K^-1 B`` (m,m);
``y = S^-1 (c - C K^-1 b)``, ``x = K^-1 b - (K^-1 B) y``. The transpose uses
``S^T = D^T - B^T K^-T C^T`` with the same factors.

Cost: chain factorization and solve O(N) 6x6 operations (a fixed (6N)^3 below the dense
limit); coupled factorization O(N m) + O(m^3), coupled solve O(N + N m + m^2). m = 0 is
decided from static shapes and is the chain path itself, at no extra cost.
"""
from __future__ import annotations

import dataclasses
import functools

import jax
import jax.numpy as jnp
import numpy as np


def block_matvec(blocks, x):
    """``K @ x`` for a block-tridiagonal ``K`` and ``x`` (N,6)."""
    diag, upper, lower = blocks
    y = jnp.einsum("nij,nj->ni", diag, x)
    y = y.at[:-1].add(jnp.einsum("nij,nj->ni", upper, x[1:]))
    return y.at[1:].add(jnp.einsum("nij,nj->ni", lower, x[:-1]))


def dense(blocks):
    """The block-tridiagonal matrix as a dense (6N, 6N) array (the dense factorization,
    tests and debugging): one gather of the blocks by a static (N, N) table of which
    block (or a zero block) sits where (XLA on CPU would run a scatter as a loop)."""
    diag, upper, lower = blocks
    n = diag.shape[0]
    zero = jnp.zeros((1, 6, 6), diag.dtype)
    stacked = jnp.concatenate([zero, diag, upper, lower])        # 0, 1.., 1+n.., n+n..
    idx = np.arange(n)
    which = np.zeros((n, n), dtype=int)
    which[idx, idx] = 1 + idx
    which[idx[:-1], idx[1:]] = 1 + n + idx[:-1]
    which[idx[1:], idx[:-1]] = 2 * n + idx[:-1]
    return jnp.swapaxes(stacked[which], 1, 2).reshape(6 * n, 6 * n)


# Chains of at most this many nodes are solved by a dense LU of the assembled matrix: on
# CPU one LAPACK factorization of a (6N, 6N) matrix beats the N sequential 6x6 steps of the
# block-Thomas scan up to about 12 nodes (benchmarks/README.md), and a factorized dense
# matrix is re-solved in a few microseconds (modified Newton, IFT).
DENSE_LIMIT_NODES = 12


def lu(A):
    """Partial-pivoting LU of a square matrix: ``(lu, perm)`` with ``A[perm] = L U``;
    ``lu`` holds ``L`` and ``U`` transposed (``lu.T`` is LAPACK's packed factor).

    The row permutation is formed once here: ``jax.scipy.linalg.lu_solve`` rebuilds it
    from LAPACK's pivots at every solve in an n-step loop, which cost more than the two
    triangular solves themselves (66 loop iterations per solve of an 11-node chain).
    Kept transposed because LAPACK's column-major factor is then stored without a copy
    and handed back to its triangular solves without one at every solve.
    """
    factors, _, perm = jax.lax.linalg.lu(A)
    return factors.T, perm


def lu_solve(factors, b, transpose=False):
    """Solve ``A x = b`` (or ``A^T x = b``) with ``factors = lu(A)``; b (n,) or (n, k)."""
    f_t, perm = factors
    f = f_t.T
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


@functools.partial(jax.tree_util.register_dataclass,
                   data_fields=("lu", "perm", "C", "lower"), meta_fields=("kind", "identity"))
@dataclasses.dataclass(frozen=True)
class Factors:
    """Factors of a block-tridiagonal ``K`` (:func:`factorize`), a pytree.

    Of the F nodes not in ``identity`` (all N when it is empty), kind (static):
    ``"dense"``: ``lu`` (6F,6F) and ``perm`` (6F,) of :func:`lu` applied to the assembled
    matrix, ``C`` and ``lower`` None. ``"thomas"``: the block LU of block Thomas, ``lu``
    (F,6,6) and ``perm`` (F,6) of the pivot blocks ``S_i``, ``C`` (F,6,6) the blocks
    ``C_i = S_i^-1 U_i`` (``C_{F-1} = 0``), ``lower`` (F-1,6,6) the sub-diagonal.
    identity (static): the nodes with identity rows and columns that were left out.
    """
    kind: str
    lu: jax.Array
    perm: jax.Array
    C: jax.Array | None = None
    lower: jax.Array | None = None
    identity: tuple = ()


def factorize(blocks, identity: tuple = ()) -> Factors:
    """Factors of a block-tridiagonal ``K`` for :func:`solve_factored` (spec 3.6).

    Chosen at trace time by size: :func:`lu` of the (6N, 6N) matrix for
    N <= ``DENSE_LIMIT_NODES``; otherwise the block LU of block Thomas with pivot blocks
    ``S_i = D_i - L_i C_{i-1}`` (each LU-factorized with partial pivoting) and
    ``C_i = S_i^-1 U_i``. O(N) 6x6 operations (``lax.scan``); a singular pivot gives
    non-finite solutions, which the Newton solvers detect and report.

    ``identity``: static indices of nodes whose rows and columns of ``K`` are those of the
    identity (fully held nodes after :func:`simsoft_jax.assembly.apply_constraints`, e.g.
    a clamped rod end). ``K`` is then block diagonal in them and the rest, and the rest is
    again a block-tridiagonal chain (its blocks across a left-out node are zero): only the
    rest is factorized (a clamped 11-node rod: a 60 instead of 66 square dense LU, about
    15 % less work per factorization and solve; N counts the rest) and ``x = b`` on them.
    When every node is one, the whole identity is factorized as it is. Not checked: the
    caller guarantees it (:meth:`simsoft_jax.model.Structure.identity_nodes`).
    """
    n = blocks[0].shape[0]
    identity = tuple(sorted(set(identity))) if len(set(identity)) < n else ()
    if identity:
        rest = _rest(n, identity)
        linked = (np.diff(rest) == 1)[:, None, None]  # the blocks between rest neighbours
        diag, upper, lower = blocks
        blocks = (diag[rest], jnp.where(linked, upper[rest[:-1]], 0.0),
                  jnp.where(linked, lower[rest[:-1]], 0.0))
    return dataclasses.replace(_factorize_chain(blocks), identity=identity)


def _rest(n: int, identity: tuple) -> np.ndarray:
    """The node indices not in ``identity``, increasing (static)."""
    return np.array([i for i in range(n) if i not in identity], dtype=int)


def _factorize_chain(blocks) -> Factors:
    """:func:`factorize` of a chain without identity nodes."""
    diag, upper, lower = blocks
    n = diag.shape[0]
    if n <= DENSE_LIMIT_NODES:
        return Factors("dense", *lu(dense(blocks)))
    pad_u = jnp.concatenate([upper, jnp.zeros((1, 6, 6))])
    pad_l = jnp.concatenate([jnp.zeros((1, 6, 6)), lower])

    def forward(c_prev, inputs):
        D, U, L = inputs
        factors = lu(D - L @ c_prev)
        c = lu_solve(factors, U)
        return c, (*factors, c)

    _, (f, perm, C) = jax.lax.scan(forward, jnp.zeros((6, 6)), (diag, pad_u, pad_l))
    return Factors("thomas", f, perm, C, lower)


def solve_factored(factors: Factors, b, transpose=False):
    """Solve ``K x = b`` (or ``K^T x = b``) with the factors of :func:`factorize`; b, x
    (N,6), or (N,6,k) for k right-hand sides at once."""
    if not factors.identity:
        return _solve_chain(factors, b, transpose)
    n = b.shape[0]
    rest = _rest(n, factors.identity)
    x = _solve_chain(factors, b[rest], transpose)
    # x on the rest, b on the identity nodes: one static gather (no scatter)
    where = np.arange(rest.size, rest.size + n)
    where[rest] = np.arange(rest.size)
    return jnp.concatenate([x, b])[where]


def _solve_chain(factors: Factors, b, transpose=False):
    """:func:`solve_factored` on the chain that was factorized (the rest of the nodes)."""
    n = b.shape[0]
    if factors.kind == "dense":
        x = lu_solve((factors.lu, factors.perm), b.reshape(6 * n, *b.shape[2:]), transpose)
        return x.reshape(b.shape)
    f, perm, C, lower = factors.lu, factors.perm, factors.C, factors.lower
    zero = jnp.zeros(b.shape[1:])
    if transpose:  # K^T = U^T L^T: U^T z = b forward, then L^T x = z backward
        def forward_t(z_prev, inputs):
            c_prev, bi = inputs
            z = bi - c_prev.T @ z_prev
            return z, z

        pad_c = jnp.concatenate([jnp.zeros((1, 6, 6)), C[:-1]])
        _, Z = jax.lax.scan(forward_t, zero, (pad_c, b))

        def backward_t(x_next, inputs):
            f_i, perm_i, L, zi = inputs
            x = lu_solve((f_i, perm_i), zi - L.T @ x_next, transpose=True)
            return x, x

        pad_l = jnp.concatenate([lower, jnp.zeros((1, 6, 6))])
        _, X = jax.lax.scan(backward_t, zero, (f, perm, pad_l, Z), reverse=True)
        return X
    pad_l = jnp.concatenate([jnp.zeros((1, 6, 6)), lower])

    def forward(y_prev, inputs):
        f_i, perm_i, L, bi = inputs
        y = lu_solve((f_i, perm_i), bi - L @ y_prev)
        return y, y

    _, Y = jax.lax.scan(forward, zero, (f, perm, pad_l, b))

    def backward(x_next, inputs):
        c, y = inputs
        x = y - c @ x_next
        return x, x

    _, X = jax.lax.scan(backward, zero, (C, Y), reverse=True)
    return X


def block_solve(blocks, b, identity: tuple = ()):
    """Solve ``K x = b`` for a block-tridiagonal ``K``; b, x (N,6) (see :func:`factorize`,
    also for ``identity``)."""
    return solve_factored(factorize(blocks, identity), b)


def implicit_solve(blocks, b, identity: tuple = ()):
    """``K^-1 b`` (N,6) inside ``lax.custom_linear_solve`` (the implicit-function-theorem
    solve of statics and dynamics): one factorization of ``K`` serves the solve and the
    transposed solve of reverse mode. ``identity``: see :func:`factorize`."""
    factors = factorize(blocks, identity)
    return jax.lax.custom_linear_solve(
        lambda x: block_matvec(blocks, x), b,
        solve=lambda _, y: solve_factored(factors, y),
        transpose_solve=lambda _, y: solve_factored(factors, y, transpose=True))


@functools.partial(jax.tree_util.register_dataclass,
                   data_fields=("chain", "B", "C", "KinvB", "schur_lu", "schur_perm"),
                   meta_fields=())
@dataclasses.dataclass(frozen=True)
class CoupledFactors:
    """Factors of ``[[K, B], [C, D]]`` (:func:`factorize_coupled`), a pytree: ``chain`` the
    :class:`Factors` of ``K``; ``B`` (N,6,m) and ``C`` (m,N,6) the couplings; ``KinvB``
    (N,6,m) ``= K^-1 B``; ``schur_lu`` (m,m) and ``schur_perm`` (m,) the :func:`lu` of the
    Schur complement ``S = D - C K^-1 B``; the last three are None when m = 0."""
    chain: Factors
    B: jax.Array
    C: jax.Array
    KinvB: jax.Array | None
    schur_lu: jax.Array | None
    schur_perm: jax.Array | None


def factorize_coupled(blocks, B, C, D, identity: tuple = ()) -> CoupledFactors:
    """Factors of ``[[K, B], [C, D]]`` for :func:`solve_coupled`: ``K`` (blocks) factorized
    once (:func:`factorize`, also for ``identity``), ``K^-1 B`` for the m columns of B
    (N,6,m), and the dense LU of the Schur complement ``S = D - C K^-1 B`` (m,m); C
    (m,N,6), D (m,m). O(N m) + O(m^3). Needs ``K`` and ``S`` nonsingular (``D = 0`` is
    fine: constraints ``C = B^T``). For m = 0 (static) only ``K`` is factorized."""
    chain = factorize(blocks, identity)
    m = B.shape[-1]
    if m == 0:
        return CoupledFactors(chain, B, C, None, None, None)
    KinvB = solve_factored(chain, B)
    return CoupledFactors(chain, B, C, KinvB, *lu(D - jnp.einsum("anj,njb->ab", C, KinvB)))


def solve_coupled(factors: CoupledFactors, b, c, transpose=False):
    """``(x, y)`` solving ``[[K, B], [C, D]] [x; y] = [b; c]`` (or the transposed system
    ``[[K^T, C^T], [B^T, D^T]] [x; y] = [b; c]``) with the factors of
    :func:`factorize_coupled`; b, x (N,6); c, y (m,).

    ``y = S^-1 (c - C K^-1 b)``, ``x = K^-1 b - (K^-1 B) y``: one chain solve and O(N m).
    Transposed: ``y = S^-T (c - B^T K^-T b)``, ``x = K^-T (b - C^T y)``: two transposed
    chain solves. For m = 0 this is :func:`solve_factored` and ``y = c``.
    """
    chain = factors.chain
    x0 = solve_factored(chain, b, transpose)
    if factors.B.shape[-1] == 0:
        return x0, c
    schur = (factors.schur_lu, factors.schur_perm)
    if transpose:
        y = lu_solve(schur, c - jnp.einsum("nja,nj->a", factors.B, x0), transpose=True)
        return solve_factored(chain, b - jnp.einsum("anj,a->nj", factors.C, y),
                              transpose=True), y
    y = lu_solve(schur, c - jnp.einsum("anj,nj->a", factors.C, x0))
    return x0 - jnp.einsum("nja,a->nj", factors.KinvB, y), y


def implicit_solve_coupled(blocks, B, C, D, b, c, identity: tuple = ()):
    """``(x, y)`` solving ``[[K, B], [C, D]] [x; y] = [b; c]`` inside
    ``lax.custom_linear_solve``, like :func:`implicit_solve` (differentiable in all of
    blocks, B, C, D, b and c): one :func:`factorize_coupled` serves the solve and the
    transposed solve of reverse mode. m = 0 (static) is :func:`implicit_solve`.
    ``identity``: see :func:`factorize`."""
    if B.shape[-1] == 0:
        return implicit_solve(blocks, b, identity), c
    factors = factorize_coupled(blocks, B, C, D, identity)

    def matvec(xy):
        x, y = xy
        return (block_matvec(blocks, x) + jnp.einsum("nja,a->nj", B, y),
                jnp.einsum("anj,nj->a", C, x) + D @ y)

    return jax.lax.custom_linear_solve(
        matvec, (b, c), solve=lambda _, r: solve_coupled(factors, *r),
        transpose_solve=lambda _, r: solve_coupled(factors, *r, transpose=True))
