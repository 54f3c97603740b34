"""Block linear algebra of mechanisms (:mod:`simsoft_jax.math.linalg`): chains on both paths
(dense LU, block cyclic reduction), chains coupled through a Schur complement (random couplings, a
weld between two rods, closed loops, no coupling), transposed solves and derivatives
through ``implicit_solve_coupled``, all against dense NumPy solves of the assembled
matrix."""
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from simsoft_jax.math import linalg

LIMIT = linalg.DENSE_LIMIT_NODES


def rel_err(a, b):
    a, b = np.asarray(a).ravel(), np.asarray(b).ravel()
    return np.linalg.norm(a - b) / np.linalg.norm(b)


def random_blocks(n, rng, symmetric=False):
    """A well-conditioned block-tridiagonal matrix (diagonally dominant)."""
    diag = rng.normal(size=(n, 6, 6))
    upper = 0.5 * rng.normal(size=(n - 1, 6, 6))
    if symmetric:
        diag = 0.5 * (diag + np.swapaxes(diag, 1, 2))
        lower = np.swapaxes(upper, 1, 2)
    else:
        lower = 0.5 * rng.normal(size=(n - 1, 6, 6))
    return diag + 12.0 * np.eye(6), upper, lower


def concatenate(*rods):
    """Rods' blocks end to end, with zero coupling blocks between them."""
    diag = np.concatenate([r[0] for r in rods])
    zero = np.zeros((1, 6, 6))
    upper = np.concatenate(sum([[r[1], zero] for r in rods], [])[:-1])
    lower = np.concatenate(sum([[r[2], zero] for r in rods], [])[:-1])
    return diag, upper, lower


def dense_np(blocks):
    diag, upper, lower = blocks
    n = diag.shape[0]
    K = np.zeros((n, 6, n, 6))
    for i in range(n):
        K[i, :, i] = diag[i]
    for i in range(n - 1):
        K[i, :, i + 1] = upper[i]
        K[i + 1, :, i] = lower[i]
    return K.reshape(6 * n, 6 * n)


def coupled_np(blocks, B, C, D):
    n, m = B.shape[0], B.shape[-1]
    return np.block([[dense_np(blocks), B.reshape(6 * n, m)], [C.reshape(m, 6 * n), D]])


def weld(n, pairs):
    """``B`` (n,6,6p) of weld constraints ``x[i] - x[j] = 0`` for each (i, j) in pairs."""
    B = np.zeros((n, 6, 6 * len(pairs)))
    for k, (i, j) in enumerate(pairs):
        B[i, :, 6 * k:6 * k + 6] += np.eye(6)
        B[j, :, 6 * k:6 * k + 6] -= np.eye(6)
    return B


def jnp_tree(tree):
    return jax.tree_util.tree_map(jnp.asarray, tree)


def check_coupled(blocks, B, C, D, rng, homogeneous=False):
    """Forward and transposed coupled solves against ``numpy.linalg.solve``; returns
    ``(b, x, y)`` of the forward solve (with ``c = 0`` if ``homogeneous``)."""
    n, m = B.shape[0], B.shape[-1]
    A = coupled_np(blocks, B, C, D)
    b, c = rng.normal(size=(2, n, 6)), rng.normal(size=(2, m))
    if homogeneous:
        c[0] = 0.0

    @jax.jit
    def both(matrix, b, c):  # one factorization, both solves
        factors = linalg.factorize_coupled(*matrix)
        return (linalg.solve_coupled(factors, b[0], c[0]),
                linalg.solve_coupled(factors, b[1], c[1], transpose=True))

    solutions = both(jnp_tree((blocks, B, C, D)), b, c)
    for (x, y), M, bk, ck in zip(solutions, (A, A.T), b, c):
        ref = np.linalg.solve(M, np.concatenate([bk.ravel(), ck]))
        assert rel_err(np.concatenate([np.ravel(x), y]), ref) < 1e-10
    return b[0], *map(np.asarray, solutions[0])


@pytest.mark.parametrize("n", [3, LIMIT, LIMIT + 1, 16, 17, 40])
def test_chain_solves_match_numpy_on_both_paths(n):
    rng = np.random.default_rng(n)
    blocks = random_blocks(n, rng)
    K = dense_np(blocks)
    b, bk = rng.normal(size=(n, 6)), rng.normal(size=(n, 6, 3))  # 1 and 3 right-hand sides

    @jax.jit
    def solves(blocks, b, bk):  # one factorization serves all
        factors = linalg.factorize(blocks)
        assert factors.kind == ("dense" if n <= LIMIT else "cyclic")
        return ([linalg.solve_factored(factors, rhs, transpose)
                 for transpose in (False, True) for rhs in (b, bk)],
                linalg.block_solve(blocks, b), linalg.dense(blocks),
                linalg.block_matvec(blocks, b))

    (x, xk, xt, xkt), x_direct, K_jax, Kb = solves(jnp_tree(blocks), b, bk)
    for M, x1, x3 in ((K, x, xk), (K.T, xt, xkt)):
        assert rel_err(x1, np.linalg.solve(M, b.ravel())) < 1e-10
        x3 = np.reshape(x3, (6 * n, 3))
        assert rel_err(x3, np.linalg.solve(M, bk.reshape(6 * n, 3))) < 1e-10
    assert np.array_equal(x_direct, x)
    assert np.array_equal(K_jax, K)
    assert rel_err(Kb, K @ b.ravel()) < 1e-14


@pytest.mark.parametrize("k", [linalg.TRIANGULAR_COLUMNS, linalg.TRIANGULAR_COLUMNS + 1, 75])
def test_lu_solve_with_many_right_hand_sides_matches_numpy(k):
    """``lu_solve`` splits many right-hand sides into chunks (a chunk boundary inside and
    at an uneven last chunk); both the solve and the transposed solve."""
    rng = np.random.default_rng(k)
    A = rng.normal(size=(30, 30)) + 8.0 * np.eye(30)
    b = rng.normal(size=(30, k))
    factors = jax.jit(linalg.lu)(jnp.asarray(A))
    for M, transpose in ((A, False), (A.T, True)):
        x = linalg.lu_solve(factors, jnp.asarray(b), transpose)
        assert rel_err(x, np.linalg.solve(M, b)) < 1e-12


@pytest.mark.parametrize("n", [5, 20])
def test_chain_implicit_solve_gradient_is_the_transposed_solve(n):
    rng = np.random.default_rng(10 + n)
    blocks = random_blocks(n, rng)
    K = dense_np(blocks)
    b, w = rng.normal(size=(n, 6)), rng.normal(size=(n, 6))
    g = jax.jit(jax.grad(lambda bl, bb: jnp.sum(w * linalg.implicit_solve(bl, bb)), 1))(
        jnp_tree(blocks), b)
    assert rel_err(g, np.linalg.solve(K.T, w.ravel())) < 1e-10


@pytest.mark.parametrize("n,m", [(5, 1), (5, 4), (30, 1), (30, 4)])
def test_random_coupling_matches_numpy(n, m):
    rng = np.random.default_rng(100 * n + m)
    blocks = random_blocks(n, rng)
    B, C = rng.normal(size=(n, 6, m)), rng.normal(size=(m, n, 6))
    D = rng.normal(size=(m, m)) + 6.0 * np.eye(m)
    check_coupled(blocks, B, C, D, rng)


@pytest.mark.parametrize("n1,n2", [(4, 5), (9, 14), (25, 30)])
def test_weld_between_two_rods_is_a_saddle_point_solve(n1, n2):
    """Node 2 of rod 1 welded to node n2-3 of rod 2: ``C = B^T``, ``D = 0``; the solution
    satisfies the weld and the multipliers are the forces on the welded nodes."""
    rng = np.random.default_rng(n1 + n2)
    blocks = concatenate(random_blocks(n1, rng, True), random_blocks(n2, rng, True))
    n, i, j = n1 + n2, 2, n1 + n2 - 3
    B = weld(n, [(i, j)])
    C, D = np.transpose(B, (2, 0, 1)), np.zeros((6, 6))
    b, x, y = check_coupled(blocks, B, C, D, rng, homogeneous=True)
    assert np.abs(x[i] - x[j]).max() < 1e-12 * np.abs(x).max()
    # the multipliers are equal and opposite forces on the welded nodes
    residual = (b.ravel() - dense_np(blocks) @ x.ravel()).reshape(n, 6)
    assert rel_err(residual[i], y) < 1e-10 and rel_err(residual[j], -y) < 1e-10
    assert np.abs(np.delete(residual, [i, j], axis=0)).max() < 1e-12 * np.abs(b).max()


@pytest.mark.parametrize("n1,n2", [(4, 5), (15, 20)])
def test_closed_loop_of_two_rods(n1, n2):
    """Rod 1's tip welded to rod 2's root and rod 2's tip to rod 1's root (m = 12)."""
    rng = np.random.default_rng(7 * n1 + n2)
    blocks = concatenate(random_blocks(n1, rng, True), random_blocks(n2, rng, True))
    n = n1 + n2
    B = weld(n, [(n1 - 1, n1), (n - 1, 0)])
    check_coupled(blocks, B, np.transpose(B, (2, 0, 1)), np.zeros((12, 12)), rng)


@pytest.mark.parametrize("n", [6, 30])
def test_closed_loop_of_one_rod(n):
    rng = np.random.default_rng(n + 3)
    blocks = random_blocks(n, rng, True)
    B = weld(n, [(0, n - 1)])
    check_coupled(blocks, B, np.transpose(B, (2, 0, 1)), np.zeros((6, 6)), rng)


@pytest.mark.parametrize("n", [LIMIT - 1, 40])
def test_no_coupling_is_the_chain_path_bit_for_bit(n):
    """m = 0: the coupled functions trace to the very program of the chain functions (no
    extra operation) and return the same bits."""
    rng = np.random.default_rng(n)
    blocks = jnp_tree(random_blocks(n, rng))
    b = jnp.asarray(rng.normal(size=(n, 6)))
    B, C, D, c = np.zeros((n, 6, 0)), np.zeros((0, n, 6)), np.zeros((0, 0)), np.zeros(0)

    def chain(blocks, b):
        factors = linalg.factorize(blocks)
        return (linalg.solve_factored(factors, b), linalg.solve_factored(factors, b, True),
                linalg.implicit_solve(blocks, b))

    def coupled(blocks, b):
        factors = linalg.factorize_coupled(blocks, B, C, D)
        (x, y), (xt, yt) = (linalg.solve_coupled(factors, b, c, t) for t in (False, True))
        xi, yi = linalg.implicit_solve_coupled(blocks, B, C, D, b, c)
        assert y.shape == yt.shape == yi.shape == (0,)
        return x, xt, xi

    assert str(jax.make_jaxpr(coupled)(blocks, b)) == str(jax.make_jaxpr(chain)(blocks, b))
    for x, x_chain in zip(jax.jit(coupled)(blocks, b), jax.jit(chain)(blocks, b)):
        assert np.array_equal(x, x_chain)


def dense_derivatives(blocks, B, C, D, b, c, w_x, w_y):
    """Gradient of ``w . z`` with ``A z = r`` (dense formula: ``dL/dr = A^-T w``,
    ``dL/dA = -(A^-T w) z^T``), split into the shapes of the inputs."""
    n, m = B.shape[0], B.shape[-1]
    A = coupled_np(blocks, B, C, D)
    z = np.linalg.solve(A, np.concatenate([b.ravel(), c]))
    lam = np.linalg.solve(A.T, np.concatenate([w_x.ravel(), w_y]))
    G = -np.outer(lam, z)
    GK = G[:6 * n, :6 * n].reshape(n, 6, n, 6)
    idx = np.arange(n)
    g_blocks = (GK[idx, :, idx], GK[idx[:-1], :, idx[1:]], GK[idx[1:], :, idx[:-1]])
    return (g_blocks, G[:6 * n, 6 * n:].reshape(n, 6, m), G[6 * n:, :6 * n].reshape(m, n, 6),
            G[6 * n:, 6 * n:], lam[:6 * n].reshape(n, 6), lam[6 * n:]), A, z


@pytest.mark.parametrize("n1,n2", [(4, 5), (12, 13)])
def test_grad_and_jvp_through_implicit_solve_coupled(n1, n2):
    """A weld (D = 0) on the dense path (9 nodes) and the cyclic-reduction path (25 nodes):
    reverse mode (the transposed coupled solve) and forward mode against the dense formulas,
    and the gradient in one direction against central finite differences."""
    rng = np.random.default_rng(n1 * n2)
    blocks = concatenate(random_blocks(n1, rng, True), random_blocks(n2, rng, True))
    n = n1 + n2
    B = weld(n, [(1, n - 2)])
    C, D = np.transpose(B, (2, 0, 1)), np.zeros((6, 6))
    b, c, w_x, w_y = (rng.normal(size=s) for s in [(n, 6), 6, (n, 6), 6])
    inputs = (blocks, B, C, D, b, c)

    def loss(*args):
        x, y = linalg.implicit_solve_coupled(*args)
        return jnp.sum(w_x * x) + jnp.sum(w_y * y)

    grads = jax.jit(jax.grad(loss, argnums=range(6)))(*jnp_tree(inputs))
    ref, A, z = dense_derivatives(*inputs, w_x, w_y)
    for g, r in zip(jax.tree_util.tree_leaves(grads), jax.tree_util.tree_leaves(ref)):
        assert rel_err(g, r) < 1e-10

    tangents = jax.tree_util.tree_map(lambda a: rng.normal(size=np.shape(a)), inputs)
    _, (dx, dy) = jax.jit(lambda p, t: jax.jvp(linalg.implicit_solve_coupled, p, t))(
        jnp_tree(inputs), jnp_tree(tangents))
    dA = coupled_np(*tangents[:4])
    dz = np.linalg.solve(A, np.concatenate([tangents[4].ravel(), tangents[5]]) - dA @ z)
    assert rel_err(np.concatenate([np.ravel(dx), dy]), dz) < 1e-10

    def numeric_loss(t):
        p = jax.tree_util.tree_map(lambda a, da: a + t * da, inputs, tangents)
        zz = np.linalg.solve(coupled_np(*p[:4]), np.concatenate([p[4].ravel(), p[5]]))
        return zz @ np.concatenate([w_x.ravel(), w_y])

    h = 1e-5
    fd = (numeric_loss(h) - numeric_loss(-h)) / (2 * h)
    directional = sum(np.sum(np.asarray(g) * t) for g, t in zip(
        jax.tree_util.tree_leaves(grads), jax.tree_util.tree_leaves(tangents)))
    assert abs(directional - fd) < 1e-7 * abs(fd)


def test_grad_through_implicit_solve_coupled_with_constant_border_rows():
    """Reverse mode in b alone, the border's right-hand side c a constant (as the rod-rod
    contact's zero border rows are): the gradient is ``(A^-T w)`` on the chain rows (dense
    formula), where a right-hand side only partly linear in b once stopped the transpose."""
    rng = np.random.default_rng(7)
    n, m = 9, 12
    blocks = random_blocks(n, rng)
    B, C = rng.normal(size=(n, 6, m)), rng.normal(size=(m, n, 6))
    D = -np.eye(m)
    b, w_x, w_y = (rng.normal(size=s) for s in [(n, 6), (n, 6), m])
    args = jnp_tree((blocks, B, C, D))

    def loss(b):
        x, y = linalg.implicit_solve_coupled(*args, b, jnp.zeros(m))
        return jnp.sum(w_x * x) + jnp.sum(w_y * y)

    grad = jax.grad(loss)(jnp.asarray(b))
    ref = dense_derivatives(blocks, B, C, D, b, np.zeros(m), w_x, w_y)[0][4]
    assert rel_err(grad, ref) < 1e-10


@pytest.mark.parametrize("n, held", [(8, (0,)), (8, (0, 4)), (8, (3, 7)), (8, tuple(range(8))),
                                     (LIMIT + 4, (0,)), (LIMIT + 4, (0, 6, LIMIT + 3))])
def test_identity_nodes_left_out_of_the_factorization(n, held):
    """Fully held nodes (identity rows and columns after
    :func:`simsoft_jax.physics.assembly.apply_constraints`) are left out of the chain's
    factorization (dense LU and block cyclic reduction): solves, transposed solves, several
    right-hand sides and a coupled system agree with NumPy's solve of the whole assembled
    matrix; so do the implicit-solve derivatives."""
    from simsoft_jax.physics.assembly import apply_constraints

    rng = np.random.default_rng(7)
    mask = np.ones((n, 6))
    mask[list(held)] = 0.0
    mask[5, :3] = 0.0                     # a pinned node stays in (partly held)
    b = rng.normal(size=(n, 6))
    _, blocks = apply_constraints(jnp.asarray(mask), jnp.asarray(b),
                                  tuple(map(jnp.asarray, random_blocks(n, rng))))
    K = dense_np(blocks)
    factors = linalg.factorize(blocks, identity=held)
    kept = n - len(held) if len(held) < n else n     # all held: nothing left out
    # each kept node is eliminated at one cyclic-reduction level or in the dense LU left
    assert (sum(level.inverse.shape[0] for level in factors.levels)
            + factors.lu.shape[0] // 6) == kept
    for transpose in (False, True):
        expected = np.linalg.solve(K.T if transpose else K, b.ravel()).reshape(n, 6)
        got = linalg.solve_factored(factors, jnp.asarray(b), transpose)
        assert rel_err(got, expected) < 1e-12
    many = rng.normal(size=(n, 6, 3))
    expected = np.linalg.solve(K, many.reshape(6 * n, 3)).reshape(n, 6, 3)
    assert rel_err(linalg.solve_factored(factors, jnp.asarray(many)), expected) < 1e-12
    # a border of m = 4 unknowns with rows on the held nodes too
    B, C = rng.normal(size=(n, 6, 4)), rng.normal(size=(4, n, 6))
    D, c = rng.normal(size=(4, 4)) + 5.0 * np.eye(4), rng.normal(size=4)
    full = np.linalg.solve(coupled_np(blocks, B, C, D), np.concatenate([b.ravel(), c]))
    x, y = linalg.solve_coupled(linalg.factorize_coupled(blocks, B, C, D, held), b, c)
    assert rel_err(np.concatenate([np.ravel(x), y]), full) < 1e-12

    def scaled(scale):   # the held rows stay the identity
        return apply_constraints(jnp.asarray(mask), jnp.asarray(b),
                                 (blocks[0] * scale,) + tuple(blocks[1:]))[1]

    def solution(scale):
        return linalg.implicit_solve(scaled(scale), jnp.asarray(b), held)

    def reference(scale):
        return jnp.linalg.solve(linalg.dense(scaled(scale)),
                                jnp.asarray(b).ravel()).reshape(n, 6)

    for f in (jax.jacfwd, jax.jacrev):   # zero when every node is held
        got, expected = np.asarray(f(solution)(1.3)), np.asarray(f(reference)(1.3))
        assert np.max(np.abs(got - expected)) <= 1e-10 * max(1.0, np.max(np.abs(expected)))


@pytest.mark.parametrize("n", [2, LIMIT, LIMIT + 1, 16, 17, 40])
def test_positive_definite_matches_numpy_eigenvalues(n):
    """The Cholesky test, and the one read from the pivots of :func:`linalg.factorize`,
    agree with the sign of numpy's smallest eigenvalue, for positive definite chains and
    for chains made indefinite by a shift of one diagonal block (at each end, in the
    middle: its node sits on different reduction levels or in the dense chain left)."""
    rng = np.random.default_rng(n)
    diag, upper, lower = random_blocks(n, rng, symmetric=True)
    smallest = np.linalg.eigvalsh(dense_np((diag, upper, lower)))[0]
    assert smallest > 0.0
    assert bool(linalg.positive_definite(jnp.asarray(diag), jnp.asarray(lower)))
    assert bool(linalg.pivots_positive_definite(linalg.factorize((diag, upper, lower))))
    for node in sorted({0, n // 2, n - 1}):
        shifted = diag.copy()
        shifted[node] -= (smallest + 20.0) * np.eye(6)
        assert np.linalg.eigvalsh(dense_np((shifted, upper, lower)))[0] < 0.0
        assert not bool(linalg.positive_definite(jnp.asarray(shifted), jnp.asarray(lower)))
        # the same test read from the factorization a solve does (symmetric chains)
        assert not bool(linalg.pivots_positive_definite(
            linalg.factorize((shifted, upper, lower))))


@pytest.mark.parametrize("coupled", [0, 5, 40, 70, 200])
def test_border_unknowns_that_couple_to_nothing_are_left_out_exactly(coupled):
    """A border of 200 unknowns of which only ``coupled`` (scattered, not the first)
    have columns of B, rows of C and off-diagonal entries of D; the others only D's
    diagonal (2.5): the factorization solves for the smallest of the border sizes that
    holds the coupled ones (none at all for 0), and the solve and transposed solve match the dense NumPy
    solve of the whole assembled matrix, the decoupled unknowns y_j = c_j / 2.5."""
    rng = np.random.default_rng(coupled)
    n, m = 30, 200
    assert linalg.border_sizes(m) == (200, 100)
    blocks = random_blocks(n, rng)
    on = np.zeros(m, bool)
    on[rng.choice(m, coupled, replace=False)] = True
    B = rng.normal(size=(n, 6, m)) * on
    C = rng.normal(size=(m, n, 6)) * on[:, None, None]
    D = np.where(np.outer(on, on), rng.normal(size=(m, m)), 0.0) + np.diag(
        np.where(on, -8.0, 2.5))
    A = np.block([[np.asarray(linalg.dense(blocks)), B.reshape(6 * n, m)],
                  [C.reshape(m, 6 * n), D]])
    b, c = rng.normal(size=(n, 6)), rng.normal(size=m)
    factors = jax.jit(linalg.factorize_coupled)(blocks, B, C, D)
    for transpose in (False, True):
        x, y = linalg.solve_coupled(factors, jnp.asarray(b), jnp.asarray(c), transpose)
        ref = np.linalg.solve(A.T if transpose else A, np.concatenate([b.ravel(), c]))
        assert rel_err(np.concatenate([np.ravel(x), y]), ref) < 1e-11
        np.testing.assert_allclose(np.asarray(y)[~on], c[~on] / 2.5, rtol=1e-12)


def test_vmapped_border_of_several_sizes_keeps_one_branch_and_matches_numpy():
    """Three lanes with 0, 40 and 150 coupled unknowns of a 200-unknown border, vmapped:
    the size chosen is the one holding the lane with the most (simsoft_jax.math.lanes), so
    the program keeps the size choice as a branch (under vmap a branch on a batched
    index would run every size, and on jaxlib < 0.11.2 their batched LU calls at once
    can hang the thread pool), and each lane's solve matches the dense NumPy solve."""
    rng = np.random.default_rng(7)
    n, m = 20, 200
    lanes = []
    for coupled in (0, 40, 150):       # one for each size: 0, 100, 200
        on = np.zeros(m, bool)
        on[rng.choice(m, coupled, replace=False)] = True
        blocks = random_blocks(n, rng)
        B = rng.normal(size=(n, 6, m)) * on
        C = rng.normal(size=(m, n, 6)) * on[:, None, None]
        D = np.where(np.outer(on, on), rng.normal(size=(m, m)), 0.0) + np.diag(
            np.where(on, -8.0, 2.5))
        lanes.append((blocks, B, C, D, rng.normal(size=(n, 6)), rng.normal(size=m)))
    stacked = jax.tree.map(lambda *a: jnp.stack([jnp.asarray(x) for x in a]), *lanes)

    def solve(blocks, B, C, D, b, c):
        return linalg.solve_coupled(linalg.factorize_coupled(blocks, B, C, D), b, c)

    batched = jax.vmap(solve)
    # the sizes stay branches: the factorization's and the solve's conds of one branch per
    # size (and one for no coupled unknown), an LU in each factorization branch but that
    jaxpr = jax.make_jaxpr(batched)(*stacked).jaxpr
    sized = [e for e in jaxpr.eqns if e.primitive.name == "cond"
             and len(e.params["branches"]) == len(linalg.border_sizes(m)) + 1]
    assert len(sized) == 2
    assert sorted(sum("lu" in {q.primitive.name for q in b.jaxpr.eqns}
                      for b in e.params["branches"]) for e in sized) == [
        0, len(linalg.border_sizes(m))]
    x, y = jax.jit(batched)(*stacked)
    # factors made lane by lane (their sizes differ), solved vmapped: the solve is done
    # at the largest lane's size, still one branch, and exact for every lane
    one = jax.jit(linalg.factorize_coupled)
    factors = jax.tree.map(lambda *a: jnp.stack(a), *(
        one(*(jax.tree.map(lambda a: a[k], stacked[:4]))) for k in range(3)))
    assert sorted(np.asarray(factors.size).tolist()) == [0, 1, 2]
    solve_lanes = jax.vmap(linalg.solve_coupled)
    assert "cond" in {e.primitive.name for e in jax.make_jaxpr(solve_lanes)(
        factors, *stacked[4:]).jaxpr.eqns}
    x2, y2 = jax.jit(solve_lanes)(factors, *stacked[4:])
    np.testing.assert_allclose(np.asarray(y2), np.asarray(y), rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(np.asarray(x2), np.asarray(x), rtol=1e-10, atol=1e-12)
    for k, (blocks, B, C, D, b, c) in enumerate(lanes):
        A = np.block([[np.asarray(linalg.dense(blocks)), B.reshape(6 * n, m)],
                      [C.reshape(m, 6 * n), D]])
        ref = np.linalg.solve(A, np.concatenate([b.ravel(), c]))
        assert rel_err(np.concatenate([np.ravel(x[k]), y[k]]), ref) < 1e-11
