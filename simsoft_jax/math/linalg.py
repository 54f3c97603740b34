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
assembled (6N, 6N) matrix. Longer chains are first shortened by block cyclic reduction
(odd-even reduction; e.g. Golub & Van Loan, "Matrix Computations", 4th ed., section
4.5.4 for the scalar case): the odd-numbered nodes are eliminated at once, their 6x6
diagonal blocks ``A_o`` inverted in one batch (partial-pivoting LU), which leaves the
Schur complement ``S = E - C A^-1 B`` on the even-numbered nodes, again a
block-tridiagonal chain of half the length; levels are repeated until at most
``DENSE_LIMIT_NODES`` nodes are left, which the dense LU factorizes. It is the block LU
of the chain in odd-even order: O(N) 6x6 operations in ``log2(N / DENSE_LIMIT_NODES)``
batched levels (block Thomas, the natural order, needs N sequential steps, each a few
small library calls: a 16-node chain factorized and solved in 28 instead of 62 us). A
solve is ``y_o = A^-1 b_o``, ``b_e -= C y_o`` down the levels, the dense solve, then
``x_o = y_o - (A^-1 B) x_e`` back up; the transposed solve uses the same factors
(``S^T = E^T - B^T A^-T C^T``): ``b_e -= (A^-1 B)^T b_o`` down, ``x_o = A^-T (b_o - C^T
x_e)`` up. Coupling: Schur
complement on the coupling unknowns: with ``K`` factorized once, ``K^-1 B`` (m solves) and a
dense LU of ``S = D - C K^-1 B`` (m,m);
``y = S^-1 (c - C K^-1 b)``, ``x = K^-1 b - (K^-1 B) y``. The transpose uses
``S^T = D^T - B^T K^-T C^T`` with the same factors.

Cost: chain factorization and solve O(N) 6x6 operations in O(log N) batched steps, plus
a dense LU of at most ``6 DENSE_LIMIT_NODES`` rows; coupled factorization O(N m) + O(m^3), coupled solve O(N + N m + m^2). m = 0 is
decided from static shapes and is the chain path itself, at no extra cost.
"""
from __future__ import annotations

import dataclasses
import functools
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from .lanes import lane_max
from .xla import take_rows


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
    return jnp.swapaxes(take_rows(stacked, which), 1, 2).reshape(6 * n, 6 * n)


# Chains of at most this many nodes are solved by a dense LU of the assembled matrix, and
# longer ones are reduced by cyclic reduction to at most this many nodes first: on CPU
# one LAPACK factorization of a (6N, 6N) matrix is as fast as the batched levels up to
# 6-8 nodes and slower above (benchmarks/README.md, "Cyclic reduction": 37 against 28 us
# at 12 and 16 nodes). A lower limit adds levels, each a few more operations to compile.
DENSE_LIMIT_NODES = 6


def lu(A):
    """Partial-pivoting LU of a square matrix: ``(lu, perm)`` with ``A[perm] = L U``
    (``perm`` unsigned);
    ``lu`` holds ``L`` and ``U`` transposed (``lu.T`` is LAPACK's packed factor).

    The row permutation is formed once here: ``jax.scipy.linalg.lu_solve`` rebuilds it
    from LAPACK's pivots at every solve in an n-step loop, which cost more than the two
    triangular solves themselves (66 loop iterations per solve of an 11-node chain).
    Kept transposed because LAPACK's column-major factor is then stored without a copy
    and handed back to its triangular solves without one at every solve.
    """
    factors, _, perm = jax.lax.linalg.lu(A)
    return factors.T, perm.astype(jnp.uint32)   # unsigned: its gathers wrap no index


# Right-hand sides per triangular solve: XLA's CPU triangular solve takes ~16 ms, whatever
# the size, from about 48 right-hand sides on (measured on the 2-core development machine
# under load: a 24x24 factor with 32 columns 7 us, with 54 columns 16 ms; a 108x108 one
# with 108 columns 16-19 ms against 12 us in chunks of 32), which made the K^-1 B of
# rod-rod contact (108 columns, :func:`factorize_coupled`) 30x dearer than the rest of
# a Newton iteration (benchmarks/rod_contact_cost.py).
TRIANGULAR_COLUMNS = 32


def _triangular(f, x, **options):
    """``jax.lax.linalg.triangular_solve(f, x, left_side=True, **options)`` on x (n, k),
    ``TRIANGULAR_COLUMNS`` columns at a time."""
    tri = functools.partial(jax.lax.linalg.triangular_solve, f, left_side=True, **options)
    k = x.shape[1]
    if k <= TRIANGULAR_COLUMNS:
        return tri(x)
    return jnp.concatenate([tri(x[:, i:i + TRIANGULAR_COLUMNS])
                            for i in range(0, k, TRIANGULAR_COLUMNS)], axis=1)


def lu_solve(factors, b, transpose=False):
    """Solve ``A x = b`` (or ``A^T x = b``) with ``factors = lu(A)``; b (n,) or (n, k)."""
    f_t, perm = factors
    f = f_t.T
    tri = functools.partial(_triangular, f)
    x = b if b.ndim == 2 else b[:, None]
    if transpose:  # A^T = U^T L^T P: solve U^T, then L^T, then undo the permutation
        x = tri(x, lower=False, transpose_a=True)
        x = tri(x, lower=True, unit_diagonal=True, transpose_a=True)
        x = jnp.zeros_like(x).at[perm].set(x)
    else:
        x = tri(x[perm], lower=True, unit_diagonal=True)
        x = tri(x, lower=False)
    return x if b.ndim == 2 else x[:, 0]


@functools.partial(jax.tree_util.register_dataclass,
                   data_fields=("lu", "perm", "levels", "last"), meta_fields=("identity",))
@dataclasses.dataclass(frozen=True)
class Factors:
    """Factors of a block-tridiagonal ``K`` (:func:`factorize`), a pytree.

    Of the F nodes not in ``identity`` (all N when it is empty): ``levels`` one
    :class:`Level` per cyclic-reduction level (none for F <= ``DENSE_LIMIT_NODES``), and
    ``lu`` (6D,6D), ``perm`` (6D,) of :func:`lu` applied to the assembled chain of the D
    nodes left after the last level (D = F without levels), ``last`` (6D,6D) that chain.
    identity (static): the nodes with identity rows and columns that were left out.
    """
    lu: jax.Array
    perm: jax.Array
    levels: tuple = ()
    last: jax.Array | None = None
    identity: tuple = ()

    @property
    def kind(self) -> str:
        """``"dense"`` (the dense LU alone) or ``"cyclic"`` (reduction levels first)."""
        return "cyclic" if self.levels else "dense"


class Level(NamedTuple):
    """One level of block cyclic reduction of a chain of n nodes: its k = n // 2 odd
    nodes (1, 3, ...) eliminated, m = (n + 1) // 2 even nodes left.

    ``inverse`` (k,6,6): ``A_o^-1`` of their diagonal blocks; ``left``, ``right``
    (k,6,6): ``A_o^-1 K[o, o-1]`` and ``A_o^-1 K[o, o+1]`` (zero where the neighbour does
    not exist); ``to_left``, ``to_right`` (m,6,6): ``K[e, e-1]`` and ``K[e, e+1]`` of the
    even nodes (zero where absent)."""
    inverse: jax.Array
    left: jax.Array
    right: jax.Array
    to_left: jax.Array
    to_right: jax.Array


def factorize(blocks, identity: tuple = ()) -> Factors:
    """Factors of a block-tridiagonal ``K`` for :func:`solve_factored` (spec 3.6).

    Chosen at trace time by size: :func:`lu` of the (6N, 6N) matrix for
    N <= ``DENSE_LIMIT_NODES``; otherwise levels of block cyclic reduction (module
    docstring), whose pivot blocks (the odd nodes' diagonal blocks of each level's chain)
    are inverted by partial-pivoting LU, until the dense LU takes the chain that is left.
    O(N) 6x6 operations in ``log2(N / DENSE_LIMIT_NODES)`` batched levels; a singular
    pivot gives non-finite solutions, which the Newton solvers detect and report.

    ``identity``: static indices of nodes whose rows and columns of ``K`` are those of the
    identity (fully held nodes after :func:`simsoft_jax.physics.assembly.apply_constraints`, e.g.
    a clamped rod end). ``K`` is then block diagonal in them and the rest, and the rest is
    again a block-tridiagonal chain (its blocks across a left-out node are zero): only the
    rest is factorized (a clamped 11-node rod: 10 nodes instead of 11, about 10 % less
    work per factorization and solve; N counts the rest) and ``x = b`` on them.
    When every node is one, the whole identity is factorized as it is. Not checked: the
    caller guarantees it (:meth:`simsoft_jax.model.model.Structure.identity_nodes`).
    """
    n = blocks[0].shape[0]
    identity = tuple(sorted(set(identity))) if len(set(identity)) < n else ()
    if identity:
        rest = _rest(n, identity)
        linked = (np.diff(rest) == 1)[:, None, None]  # the blocks between rest neighbours
        diag, upper, lower = blocks
        blocks = (take_rows(diag, rest), jnp.where(linked, take_rows(upper, rest[:-1]), 0.0),
                  jnp.where(linked, take_rows(lower, rest[:-1]), 0.0))
    return dataclasses.replace(_factorize_chain(blocks), identity=identity)


def _rest(n: int, identity: tuple) -> np.ndarray:
    """The node indices not in ``identity``, increasing (static)."""
    return np.array([i for i in range(n) if i not in identity], dtype=int)


def _factorize_chain(blocks) -> Factors:
    """:func:`factorize` of a chain without identity nodes: cyclic-reduction levels until
    at most ``DENSE_LIMIT_NODES`` nodes are left, then the dense LU of that chain."""
    levels, left = _reduce_chain(blocks, _batched_solve)
    last = dense(left)
    return Factors(*lu(last), levels, last)


def _reduce_chain(blocks, batched_solve):
    """Cyclic-reduction levels of a chain ``(diag, upper, lower)`` until at most
    ``DENSE_LIMIT_NODES`` nodes are left (none for a chain that short), the odd nodes'
    pivot blocks solved by ``batched_solve`` (as :func:`_batched_solve`): (the
    :class:`Level` tuple, the chain left as ``(diag, upper, lower)``)."""
    diag, upper, lower = blocks
    if diag.shape[0] <= DENSE_LIMIT_NODES:
        return (), blocks
    zero = jnp.zeros((1, 6, 6), diag.dtype)
    # K[i, i-1] and K[i, i+1] of every node, zero at the ends
    to_left, to_right = jnp.concatenate([zero, lower]), jnp.concatenate([upper, zero])
    levels = []
    while diag.shape[0] > DENSE_LIMIT_NODES:
        level, (diag, to_left, to_right) = _reduce(diag, to_left, to_right, batched_solve)
        levels.append(level)
    return tuple(levels), (diag, to_right[:-1], to_left[1:])


def positive_definite(diag, lower):
    """Whether the symmetric block-tridiagonal matrix with diagonal blocks ``diag``
    (N,6,6) and ``lower[i] = K[i+1, i]`` (N-1,6,6) is positive definite (bool array).

    The chain is reduced as :func:`factorize` does, with Cholesky factors of the pivot
    blocks instead of LU (a symmetric matrix is positive definite iff its pivot blocks
    and the Schur complement left are, Haynsworth), and the chain left is given to one
    Cholesky factorization: a failed factorization is NaN and propagates to it. O(N) 6x6
    operations in a few batched calls; an indefinite or singular matrix gives False."""
    _, left = _reduce_chain((diag, jnp.swapaxes(lower, -1, -2), lower),
                            _batched_cholesky_solve)
    return jnp.all(jnp.isfinite(_cholesky(dense(left))))


def pivots_positive_definite(factors: Factors) -> jax.Array:
    """Whether the pivots of a factorization done (:func:`factorize` of ``K``) have
    positive definite symmetric parts (bool array): the pivot blocks ``A_o`` of every
    cyclic-reduction level, read from their inverses (for x = A y, ``x^T A^-1 x = y^T
    A^T y = y^T A y``: ``A^-1`` has a positive definite symmetric part iff ``A`` has) in
    one batched Cholesky test, and the chain left in one dense Cholesky test. For a
    symmetric ``K`` (the pivots then symmetric) this is whether ``K`` is positive
    definite (Haynsworth, as :func:`positive_definite`), without a second factorization;
    for a non-symmetric ``K`` it is not a test of its symmetric part."""
    def positive(A):
        return jnp.all(jnp.isfinite(_cholesky(0.5 * (A + jnp.swapaxes(A, -1, -2)))))

    if not factors.levels:
        return positive(factors.last)
    return positive(factors.last) & positive(
        jnp.concatenate([level.inverse for level in factors.levels]))


def _cholesky(A):
    """Lower Cholesky factor of symmetric positive definite A (..., n, n) from its lower
    triangle, NaN where A is not positive definite. ``jnp.linalg.cholesky`` first
    symmetrizes A, which cost 5x the factorization of a batch of 6x6 blocks on CPU."""
    return jax.lax.linalg.cholesky(A, symmetrize_input=False)


def _batched_solve(A, rhs):
    """``A_k^-1 rhs_k`` for a batch of square matrices A (k,6,6) and rhs (k,6,r):
    :func:`lu` and :func:`lu_solve` vmapped (one batched LAPACK factorization and two
    batched triangular solves)."""
    return jax.vmap(lambda a, r: lu_solve(lu(a), r))(A, rhs)


def _batched_cholesky_solve(A, rhs):
    """:func:`_batched_solve` for symmetric positive definite A by Cholesky factors (NaN
    where a block is not positive definite; only the lower triangle of A is read)."""
    tri = jax.lax.linalg.triangular_solve
    c = _cholesky(A)
    x = tri(c, rhs, left_side=True, lower=True)
    return tri(c, x, left_side=True, lower=True, transpose_a=True)


# Neighbours in one level of an n-node chain, with k = n // 2 odd nodes (1, 3, ...) and
# m = (n + 1) // 2 even nodes (0, 2, ...): even node 2i has the odd nodes i - 1 (left)
# and i (right), odd node 2i + 1 the even nodes i (left) and i + 1 (right). A missing
# neighbour (past either end) reads zeros: slices and zero padding, no gathers.

def _odd_to_left(y, m: int):
    """Per even node, the value ``y`` (k, ...) of its left odd neighbour (zero for node 0)."""
    return jnp.concatenate([jnp.zeros_like(y[:1]), y])[:m]


def _odd_to_right(y, m: int):
    """Per even node, the value ``y`` (k, ...) of its right odd neighbour (zero past the end)."""
    return jnp.concatenate([y, jnp.zeros_like(y[:1])])[:m]


def _even_to_right(x, k: int):
    """Per odd node, the value ``x`` (m, ...) of its right even neighbour (zero past the end)."""
    return jnp.concatenate([x, jnp.zeros_like(x[:1])])[1:k + 1]


def _interleave(x_even, x_odd):
    """The chain's values in node order from those of its even (m) and odd (k) nodes."""
    k = x_odd.shape[0]
    pairs = jnp.stack([x_even[:k], x_odd], axis=1).reshape((2 * k,) + x_odd.shape[1:])
    return jnp.concatenate([pairs, x_even[k:]])


def _reduce(diag, to_left, to_right, batched_solve):
    """One level of block cyclic reduction of a chain of n >= 2 nodes given by its
    diagonal blocks ``diag`` (n,6,6) and couplings ``to_left[i] = K[i, i-1]``,
    ``to_right[i] = K[i, i+1]`` (n,6,6; zero past the ends): (:class:`Level`, the Schur
    complement on the even nodes, a chain of (n + 1) // 2 nodes, as
    ``(diag, to_left, to_right)``). ``batched_solve``: as :func:`_batched_solve`."""
    n = diag.shape[0]
    eye = jnp.eye(6, dtype=diag.dtype)
    m = (n + 1) // 2
    odd = slice(1, None, 2)
    # A_o^-1 [I, K[o, o-1], K[o, o+1]] in one batched solve
    solved = batched_solve(diag[odd], jnp.concatenate(
        [jnp.broadcast_to(eye, (n // 2, 6, 6)), to_left[odd], to_right[odd]], axis=2))
    inverse, left, right = solved[:, :, :6], solved[:, :, 6:12], solved[:, :, 12:]
    KL, KR = to_left[::2], to_right[::2]
    # Schur complement on the even nodes: E - C A^-1 B, a chain of m nodes
    schur = diag[::2] - KL @ _odd_to_left(right, m) - KR @ _odd_to_right(left, m)
    reduced = (schur, -KL @ _odd_to_left(left, m), -KR @ _odd_to_right(right, m))
    return Level(inverse, left, right, KL, KR), reduced


def solve_factored(factors: Factors, b, transpose=False):
    """Solve ``K x = b`` (or ``K^T x = b``) with the factors of :func:`factorize`; b, x
    (N,6), or (N,6,k) for k right-hand sides at once."""
    if not factors.identity:
        return _solve_levels(factors, factors.levels, b, transpose)
    n = b.shape[0]
    rest = _rest(n, factors.identity)
    x = _solve_levels(factors, factors.levels, take_rows(b, rest), transpose)
    # x on the rest, b on the identity nodes: one static gather (no scatter)
    where = np.arange(rest.size, rest.size + n)
    where[rest] = np.arange(rest.size)
    return take_rows(jnp.concatenate([x, b]), where)


def _apply(M, x, transpose=False):
    """``M_k @ x_k`` (or ``M_k^T @ x_k``) for a batch of 6x6 blocks M (k,6,6) and x (k,6)
    or (k,6,r)."""
    return jnp.einsum("kji,kj...->ki..." if transpose else "kij,kj...->ki...", M, x)


def _solve_levels(factors: Factors, levels, b, transpose):
    """:func:`solve_factored` on the chain that was factorized (the rest of the nodes),
    with its cyclic-reduction ``levels`` from the first one (module docstring):
    down the levels the right-hand side of the even nodes is reduced, the dense factors
    of ``factors`` solve the chain left after the last level, and back up the odd nodes
    are recovered."""
    if not levels:
        n = b.shape[0]
        x = lu_solve((factors.lu, factors.perm), b.reshape(6 * n, *b.shape[2:]), transpose)
        return x.reshape(b.shape)
    level, rest = levels[0], levels[1:]
    m, k = level.to_left.shape[0], level.inverse.shape[0]
    b_odd, b_even = b[1::2], b[::2]
    if transpose:   # b_e - (A^-1 B)^T b_o: an even node gets from its odd neighbours
        reduced = (b_even - _odd_to_left(_apply(level.right, b_odd, True), m)
                   - _odd_to_right(_apply(level.left, b_odd, True), m))
    else:
        y = _apply(level.inverse, b_odd)
        reduced = (b_even - _apply(level.to_left, _odd_to_left(y, m))
                   - _apply(level.to_right, _odd_to_right(y, m)))
    x_even = _solve_levels(factors, rest, reduced, transpose)
    if transpose:   # A^-T (b_o - C^T x_e): C^T couples an odd node to its even neighbours
        coupled = (_apply(level.to_right[:k], x_even[:k], True)
                   + _even_to_right(_apply(level.to_left, x_even, True), k))
        x_odd = _apply(level.inverse, b_odd - coupled, True)
    else:
        x_odd = (y - _apply(level.left, x_even[:k])
                 - _apply(level.right, _even_to_right(x_even, k)))
    return _interleave(x_even, x_odd)


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
                   data_fields=("chain", "B", "C", "KinvB", "schur_lu", "schur_perm",
                                "order", "size"),
                   meta_fields=())
@dataclasses.dataclass(frozen=True)
class CoupledFactors:
    """Factors of ``[[K, B], [C, D]]`` (:func:`factorize_coupled`), a pytree: ``chain`` the
    :class:`Factors` of ``K``; ``B`` (N,6,m) and ``C`` (m,N,6) the couplings; ``KinvB``
    (N,6,m) ``= K^-1 B[..., order]``; ``schur_lu`` (m,m) and ``schur_perm`` (m,) the
    :func:`lu` of the Schur complement in the order ``order`` (m,) of the border unknowns,
    ``S[order][:, order]`` with ``S = D - C K^-1 B`` (the unknowns that couple first,
    :func:`factorize_coupled`; None: the unknowns' own order, a border of one size);
    ``size`` () the index in ``border_sizes(m) + (0,)`` of the leading unknowns (in
    ``order``) factorized as a whole, the others coupling to nothing (their ``KinvB``
    columns zero, their factor D's diagonal; None with ``order``); the last five are None
    when m = 0."""
    chain: Factors
    B: jax.Array
    C: jax.Array
    KinvB: jax.Array | None
    schur_lu: jax.Array | None
    schur_perm: jax.Array | None
    order: jax.Array | None
    size: jax.Array | None = None


def border_sizes(m: int) -> tuple:
    """The border sizes (static, decreasing from m) :func:`factorize_coupled` chooses
    from: m halved while above ``4 TRIANGULAR_COLUMNS`` (each size is a branch XLA
    compiles: a border of the default 8 rod-rod pairs, 108 unknowns, keeps one)."""
    sizes = [m]
    while sizes[-1] > 4 * TRIANGULAR_COLUMNS:
        sizes.append(-(-sizes[-1] // 2))
    return tuple(sizes)


def factorize_coupled(blocks, B, C, D, identity: tuple = ()) -> CoupledFactors:
    """Factors of ``[[K, B], [C, D]]`` for :func:`solve_coupled`: ``K`` (blocks) factorized
    once (:func:`factorize`, also for ``identity``), ``K^-1 B`` for the m columns of B
    (N,6,m), and the dense LU of the Schur complement ``S = D - C K^-1 B`` (m,m); C
    (m,N,6), D (m,m). O(N m) + O(m^3). Needs ``K`` and ``S`` nonsingular (``D = 0`` is
    fine: constraints ``C = B^T``). For m = 0 (static) only ``K`` is factorized.

    Border unknowns that couple to nothing (their column of B, row of C and off-diagonal
    row and column of D exactly zero: e.g. the unused node slots of rod-rod contact) have
    ``K^-1 B = 0`` there and ``S``'s row and column equal to D's: they are ordered last,
    and only the smallest of :func:`border_sizes` (or none, where no unknown couples) that
    holds the others is solved for (``lax.switch``; the rest of the factor is D's
    diagonal), O(N k) + O(k^3) for k of them; :func:`solve_coupled` takes the same size.
    Exact (the same operations on the coupled unknowns)."""
    chain = factorize(blocks, identity)
    m = B.shape[-1]
    if m == 0:
        return CoupledFactors(chain, B, C, None, None, None, None)
    sizes = border_sizes(m)
    if len(sizes) == 1:     # one size: the whole border, in its own order
        KinvB = solve_factored(chain, B)
        return CoupledFactors(chain, B, C, KinvB,
                              *lu(D - jnp.einsum("anj,njb->ab", C, KinvB)), None)
    sizes = sizes + (0,)
    off = D - jnp.diag(jnp.diag(D))
    coupled = (jnp.any(B != 0, axis=(0, 1)) | jnp.any(C != 0, axis=(1, 2))
               | jnp.any(off != 0, axis=0) | jnp.any(off != 0, axis=1))
    order = jnp.argsort(~coupled, stable=True).astype(jnp.int32)

    def solved(k):
        def branch():
            first, rest = order[:k], jnp.diag(D)[order[k:]]
            if k == 0:
                return (jnp.zeros_like(B), jnp.diag(rest), jnp.arange(m, dtype=jnp.uint32))
            KinvB = solve_factored(chain, B[..., first])
            S = D[first][:, first] - jnp.einsum("anj,njb->ab", C[first], KinvB)
            f_t, perm = lu(S)
            if k == m:
                return KinvB, f_t, perm
            return (jnp.concatenate([KinvB, jnp.zeros(KinvB.shape[:2] + (m - k,),
                                                      KinvB.dtype)], axis=-1),
                    jnp.zeros((m, m), S.dtype).at[:k, :k].set(f_t)
                    .at[np.arange(k, m), np.arange(k, m)].set(rest),
                    jnp.concatenate([perm, jnp.arange(k, m, dtype=perm.dtype)]))
        return branch

    # the smallest size holding every coupled unknown (of every lane under vmap, so that
    # one branch runs: simsoft_jax.math.lanes): sizes decrease
    which = jnp.sum(jnp.asarray(sizes) >= lane_max(jnp.sum(coupled))) - 1
    KinvB_o, f_t, perm = jax.lax.switch(which, [solved(k) for k in sizes])
    return CoupledFactors(chain, B, C, KinvB_o, f_t, perm, order, which)


def _schur_solve(chain, schur, B, C, KinvB, x0, b, c, transpose):
    """``(x, y)`` of :func:`solve_coupled` from ``x0 = K^-1 b`` (or ``K^-T b``), the
    Schur complement's factors ``schur`` and the border's B (N,6,k), C (k,N,6), KinvB
    (N,6,k), c (k,)."""
    if transpose:
        y = lu_solve(schur, c - jnp.einsum("nja,nj->a", B, x0), True)
        return solve_factored(chain, b - jnp.einsum("anj,a->nj", C, y), transpose=True), y
    y = lu_solve(schur, c - jnp.einsum("anj,nj->a", C, x0))
    return x0 - jnp.einsum("nja,a->nj", KinvB, y), y


def solve_coupled(factors: CoupledFactors, b, c, transpose=False):
    """``(x, y)`` solving ``[[K, B], [C, D]] [x; y] = [b; c]`` (or the transposed system
    ``[[K^T, C^T], [B^T, D^T]] [x; y] = [b; c]``) with the factors of
    :func:`factorize_coupled`; b, x (N,6); c, y (m,).

    ``y = S^-1 (c - C K^-1 b)``, ``x = K^-1 b - (K^-1 B) y``: one chain solve and O(N m).
    Transposed: ``y = S^-T (c - B^T K^-T b)``, ``x = K^-T (b - C^T y)``: two transposed
    chain solves. For m = 0 this is :func:`solve_factored` and ``y = c``. ``S`` is
    factorized in the order ``factors.order``: ``y[order]`` solves with ``S[order][:,
    order]`` and the right-hand side's ``[order]``, the unknowns that couple to nothing
    by D's diagonal alone (``lax.switch`` on ``factors.size``: O(N k + k^2) for the k
    that couple).
    """
    chain = factors.chain
    m = factors.B.shape[-1]
    if m == 0:
        return solve_factored(chain, b, transpose), c
    schur, order = (factors.schur_lu, factors.schur_perm), factors.order
    if order is None:
        return _schur_solve(chain, schur, factors.B, factors.C, factors.KinvB,
                            solve_factored(chain, b, transpose), b, c, transpose)

    def solved(k):
        """The solve with the first k unknowns of ``order`` coupled (the others' B
        columns, C rows and KinvB columns zero: ``y = c / D_jj`` there)."""
        def branch(b, c):
            first, later = order[:k], order[k:]
            y_later = c[later] / jnp.diagonal(factors.schur_lu)[k:]
            x0 = solve_factored(chain, b, transpose)
            if k == 0:
                return x0, jnp.zeros_like(c).at[later].set(y_later)
            x, y = _schur_solve(chain, (factors.schur_lu[:k, :k], factors.schur_perm[:k]),
                                factors.B[..., first], factors.C[first],
                                factors.KinvB[..., :k], x0, b, c[first], transpose)
            return x, jnp.zeros_like(c).at[order].set(jnp.concatenate([y, y_later]))
        return branch

    # factors selected lane by lane under vmap may differ in size: the largest of the
    # lanes' (its solve is exact for the smaller ones too), so one branch runs
    size = -lane_max(-factors.size)
    return jax.lax.switch(size, [solved(k) for k in border_sizes(m) + (0,)], b, c)


def implicit_solve_coupled(blocks, B, C, D, b, c, identity: tuple = ()):
    """``(x, y)`` solving ``[[K, B], [C, D]] [x; y] = [b; c]`` inside
    ``lax.custom_linear_solve``, like :func:`implicit_solve` (differentiable in all of
    blocks, B, C, D, b and c): one :func:`factorize_coupled` serves the solve and the
    transposed solve of reverse mode. m = 0 (static) is :func:`implicit_solve`.
    ``identity``: see :func:`factorize`."""
    if B.shape[-1] == 0:
        return implicit_solve(blocks, b, identity), c
    factors = factorize_coupled(blocks, B, C, D, identity)
    # one flat right-hand side: a part of it that is constant in the tangent (the rod-rod
    # contact's zero border rows) would otherwise stop reverse mode, whose transposed
    # solve needs every right-hand side linear
    size = b.size

    def unpack(v):
        return v[:size].reshape(b.shape), v[size:]

    def pack(x, y):
        return jnp.concatenate([x.reshape(-1), y])

    def matvec(v):
        x, y = unpack(v)
        return pack(block_matvec(blocks, x) + jnp.einsum("nja,a->nj", B, y),
                    jnp.einsum("anj,nj->a", C, x) + D @ y)

    return unpack(jax.lax.custom_linear_solve(
        matvec, pack(b, c), solve=lambda _, r: pack(*solve_coupled(factors, *unpack(r))),
        transpose_solve=lambda _, r: pack(*solve_coupled(factors, *unpack(r),
                                                         transpose=True))))
