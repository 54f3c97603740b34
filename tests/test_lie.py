"""Tests for simsoft_jax.math.lie (spec: shared/spec/algorithm.md §0-§1).

Every reference is computed here, independently of the module, in numpy extended precision
(np.longdouble, eps ~1e-19): matrix exponentials by scaling-and-squaring + Taylor, tangent
operators by the series (S21) T = sum (-ad)^k/(k+1)!, T^-1 = sum B_k (-ad)^k/k!.
Conventions: twists xi = [U; Omega] (linear; angular), body/right perturbations.
"""
from decimal import Decimal, getcontext
from fractions import Fraction
from math import comb, pi

import numpy as np
import pytest
from scipy.linalg import expm as scipy_expm
from scipy.spatial.transform import Rotation

import jax
import jax.numpy as jnp
from simsoft_jax.math import geometry, lie  # importing the package enables float64

LD = np.longdouble


# ----------------------------------------------------------------------------- references
def np_skew(w):
    return np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]], dtype=np.asarray(w).dtype)


def np_hat(xi):
    X = np.zeros((4, 4), dtype=np.asarray(xi).dtype)
    X[:3, :3], X[:3, 3] = np_skew(xi[3:]), xi[:3]
    return X


def np_vee(X):
    """Inverse of np_skew (3x3 -> 3) or np_hat (4x4 -> 6)."""
    w = np.array([X[2, 1], X[0, 2], X[1, 0]])
    return w if X.shape == (3, 3) else np.r_[X[:3, 3], w]


def np_ad(xi):
    A = np.zeros((6, 6), dtype=np.asarray(xi).dtype)
    A[:3, :3] = A[3:, 3:] = np_skew(xi[3:])
    A[:3, 3:] = np_skew(xi[:3])
    return A


def np_Ad(H):
    R, p = H[:3, :3], H[:3, 3]
    A = np.zeros((6, 6), dtype=H.dtype)
    A[:3, :3] = A[3:, 3:] = R
    A[:3, 3:] = np_skew(p) @ R
    return A


def np_expm(A, terms=30):
    """exp(A) in long double: scaling-and-squaring with a `terms`-term Taylor series."""
    A = np.asarray(A, dtype=LD)
    nrm = float(np.max(np.sum(np.abs(A), axis=1)))
    s = max(0, int(np.ceil(np.log2(nrm / 0.25)))) if nrm > 0 else 0
    B = A / LD(2.0) ** s
    E, term = np.eye(len(A), dtype=LD), np.eye(len(A), dtype=LD)
    for k in range(1, terms):
        term = term @ B / LD(k)
        E = E + term
    for _ in range(s):
        E = E @ E
    return E


def _bernoulli_over_factorial(n):
    """b_k = B_k / k! (B_1 = -1/2), exact rationals converted to long double."""
    B = [Fraction(1)]
    for m in range(1, n):
        B.append(-sum(comb(m + 1, k) * B[k] for k in range(m)) / (m + 1))
    getcontext().prec = 40
    out, fact = [], 1
    for k, b in enumerate(B):
        fact *= max(k, 1)
        q = b / fact
        out.append(LD(str(Decimal(q.numerator) / Decimal(q.denominator))))
    return out


BERN = _bernoulli_over_factorial(140)


def series_T(A, n=80):
    """(S21) T = sum_k (-A)^k/(k+1)!, A = ad_xi (6x6) or skew(w) (3x3), long double."""
    A = -np.asarray(A, dtype=LD)
    out, P = np.zeros_like(A), np.eye(len(A), dtype=LD)
    for k in range(n):
        P = P / LD(k + 1)
        out = out + P
        P = P @ A
    return out


def series_Tinv(A, n=140):
    """(S21) T^-1 = sum_k B_k (-A)^k/k!  (converges for angle < 2 pi)."""
    A = -np.asarray(A, dtype=LD)
    out, P = np.zeros_like(A), np.eye(len(A), dtype=LD)
    for k in range(n):
        out = out + BERN[k] * P
        P = P @ A
    return out


def np_ginv(E):
    """Inverse of a rotation (3x3) or homogeneous transform (4x4)."""
    if E.shape == (3, 3):
        return E.T
    Ei = np.eye(4, dtype=E.dtype)
    Ei[:3, :3], Ei[:3, 3] = E[:3, :3].T, -E[:3, :3].T @ E[:3, 3]
    return Ei


def f64(a):
    return np.asarray(a, dtype=np.float64)


def call(fn, *args):  # module function on float64 jnp inputs -> numpy
    return np.asarray(fn(*(jnp.asarray(a, dtype=jnp.float64) for a in args)))


def fd_jac(fun, x, h):
    """Central differences in long double; result shape fun(x).shape + (n,)."""
    x = np.asarray(x, dtype=LD)
    cols = []
    for k in range(len(x)):
        e = np.zeros(len(x), dtype=LD)
        e[k] = h
        cols.append((np.asarray(fun(x + e)) - np.asarray(fun(x - e))) / (2 * LD(h)))
    return np.stack(cols, axis=-1)


# ----------------------------------------------------------------------------- samples
rng = np.random.default_rng(20240607)  # module-level samples only; tests seed their own


def unit(n=3, r=rng):
    v = r.normal(size=n)
    return v / np.linalg.norm(v)


ANGLES = [0.0, 1e-12, 1e-9, 1e-7, 1e-4, 9e-4, 1e-2, 0.3, 0.92, 0.999999, 1.0, 1.000001,
          1.299999, 1.300001, 2.2, 3.0, 3.1]
ROTVECS = [a * unit() for a in ANGLES]
TWISTS = [np.r_[unit() * rng.uniform(0.3, 1.5), w] for w in ROTVECS]
n0 = unit()
TWISTS += [np.r_[1.3 * n0, 1.2 * n0], np.r_[0.3, -1.0, 2.0, 0, 0, 0]]  # U || Omega; pure translation
TW_IDS = [f"{a:.7g}" for a in ANGLES] + ["parallel", "translation"]

GROUPS = {
    "so3": dict(exp=lie.exp_so3, log=lie.log_so3, T=lie.tangent_so3, Tinv=lie.tangent_so3_inv,
                hat=np_skew, vee=np_vee, ad=np_skew, samples=ROTVECS, ids=TW_IDS[:len(ANGLES)]),
    "se3": dict(exp=lie.exp_se3, log=lie.log_se3, T=lie.tangent_se3, Tinv=lie.tangent_se3_inv,
                hat=np_hat, vee=np_vee, ad=np_ad, samples=TWISTS, ids=TW_IDS),
}
CASES = [pytest.param(g, x, id=f"{g}-{i}") for g in GROUPS
         for x, i in zip(GROUPS[g]["samples"], GROUPS[g]["ids"])]


def scale(x):
    return max(1.0, float(np.linalg.norm(x)))


# ----------------------------------------------------------------------------- 0. basics
def test_hat_vee_skew_ad():
    a, b = np.random.default_rng(1).normal(size=(2, 6))
    np.testing.assert_allclose(call(lie.skew, a[3:]) @ b[3:], np.cross(a[3:], b[3:]), atol=1e-15)
    np.testing.assert_array_equal(call(lie.hat_se3, a), np_hat(a))
    np.testing.assert_array_equal(call(lie.vee_se3, np_hat(a)), a)
    # ad is the Lie bracket: hat(ad_a b) = hat(a) hat(b) - hat(b) hat(a)
    bracket = np_vee(np_hat(a) @ np_hat(b) - np_hat(b) @ np_hat(a))
    np.testing.assert_allclose(call(lie.ad_se3, a) @ b, bracket, atol=1e-14)
    np.testing.assert_allclose(call(lie.ad_se3, a), np_ad(a), atol=0)


def test_reference_expm_sanity():
    for xi in TWISTS:
        np.testing.assert_allclose(f64(np_expm(np_hat(xi))), scipy_expm(np_hat(xi)), atol=1e-13)


# ----------------------------------------------------------------------------- 1. exponential
@pytest.mark.parametrize("g,x", CASES)
def test_exp_matches_reference_expm(g, x):
    G = GROUPS[g]
    np.testing.assert_allclose(call(G["exp"], x), f64(np_expm(G["hat"](x))), rtol=0,
                               atol=1e-14 * scale(x))


# ----------------------------------------------------------------------------- 2. logarithm
@pytest.mark.parametrize("g,x", CASES)
def test_log_exp_roundtrip(g, x):
    G = GROUPS[g]
    y = call(G["log"], f64(np_expm(G["hat"](x))))  # log of the correctly rounded exp(x)
    y2 = call(G["log"], call(G["exp"], x))  # and of the module's own exp(x)
    for z in (y, y2):  # relative accuracy, exact 0 at x = 0
        err = np.linalg.norm(z - x)
        assert err <= 1e-13 * np.linalg.norm(x), f"|log(exp(x)) - x| = {err:.3g}, |x| = {np.linalg.norm(x):.6g}"


@pytest.mark.parametrize("delta", [1e-3, 1e-6, 1e-9])
@pytest.mark.parametrize("axis", [[1, 0, 0], [0, -1, 0], [1, 1, 1], [-0.2, 0.9, -0.4], "random"])
@pytest.mark.parametrize("g", ["so3", "se3"])
def test_log_near_pi(g, axis, delta):
    r = np.random.default_rng(2)
    n = unit(3, r) if axis == "random" else np.asarray(axis, float) / np.linalg.norm(axis)
    theta = pi - delta
    x = theta * n if g == "so3" else np.r_[r.normal(size=3), theta * n]
    G = GROUPS[g]
    E = f64(np_expm(G["hat"](x)))
    y = call(G["log"], E)
    assert abs(np.linalg.norm(y[-3:]) - theta) <= 1e-12
    np.testing.assert_allclose(y, x, rtol=0, atol=1e-12 * scale(x))
    np.testing.assert_allclose(call(G["exp"], y), E, rtol=0, atol=1e-12)


def _exact_pi_rotations():
    yield from (np.diag(d).astype(float) for d in ([1, -1, -1], [-1, 1, -1], [-1, -1, 1]))
    for v in ([1, 1, 0], [1, -2, 3]):
        n = np.asarray(v, float) / np.linalg.norm(v)
        yield 2 * np.outer(n, n) - np.eye(3)


def test_numpy_log_se3_inverts_the_reference_exponential():
    """geometry.log_se3_np (the host logarithm of model building) is the logarithm: of the
    correctly rounded exp of twists at angles from 0 through the series switch (1 rad)
    to near pi, in one batch, it returns the twists."""
    r = np.random.default_rng(11)
    angles = [0.0, 1e-9, 1e-4, 0.3, 0.999, 1.001, 2.0, pi - 1e-3, pi - 1e-6]
    x = np.array([np.r_[r.normal(size=3), a * unit(3, r)] for a in angles])
    E = np.stack([f64(np_expm(np_hat(xi))) for xi in x])
    y = geometry.log_se3_np(E[:, :3, :3], E[:, :3, 3])
    for xi, yi, a in zip(x, y, angles):
        np.testing.assert_allclose(yi, xi, rtol=0, atol=(1e-12 if a > 3 else 1e-13) * scale(xi))


def test_exp_log_random_quaternions_and_pi():
    r = np.random.default_rng(3)
    Rs = list(Rotation.random(60, random_state=7).as_matrix()) + list(_exact_pi_rotations())
    for R in Rs:
        w = call(lie.log_so3, R)
        assert np.linalg.norm(w) <= pi + 1e-12
        np.testing.assert_allclose(call(lie.exp_so3, w), R, rtol=0, atol=1e-14)
        H = np.eye(4)
        H[:3, :3], H[:3, 3] = R, r.normal(size=3)
        np.testing.assert_allclose(call(lie.exp_se3, call(lie.log_se3, H)), H, rtol=0, atol=1e-13)


def test_log_so3_accuracy_sweep():
    """Relative accuracy of log_so3 on correctly rounded rotations, angles across (0, pi)."""
    r = np.random.default_rng(4)
    theta = np.r_[np.geomspace(1e-10, 1e-2, 9), np.linspace(1e-2, pi - 1e-3, 300)]
    W = np.stack([a * unit(3, r) for a in theta])
    R = np.stack([f64(np_expm(np_skew(w))) for w in W])
    err = np.linalg.norm(np.asarray(jax.jit(jax.vmap(lie.log_so3))(R)) - W, axis=1) / theta
    worst = int(np.argmax(err))
    assert err[worst] <= 1e-14, f"relative error {err[worst]:.3g} at angle {theta[worst]:.6f}"


# ----------------------------------------------------------------------------- 3./4. tangent
@pytest.mark.parametrize("g,x", CASES)
def test_tangent_vs_finite_differences_of_exp(g, x):
    G = GROUPS[g]
    Einv = np_ginv(np_expm(G["hat"](x)))
    fd = fd_jac(lambda z: G["vee"](Einv @ np_expm(G["hat"](z))), x, 1e-6)
    np.testing.assert_allclose(call(G["T"], x), f64(fd), rtol=0, atol=1e-8)


@pytest.mark.parametrize("g,x", CASES)
def test_tangent_vs_series(g, x):
    G = GROUPS[g]
    A = G["ad"](np.asarray(x, LD))
    T_ref, Tinv_ref = series_T(A), series_Tinv(A)
    assert np.abs(T_ref @ Tinv_ref - np.eye(len(A))).max() < 1e-16  # reference sanity
    tol = 1e-14 * scale(x)
    np.testing.assert_allclose(call(G["T"], x), f64(T_ref), rtol=0, atol=tol)
    np.testing.assert_allclose(call(G["Tinv"], x), f64(Tinv_ref), rtol=0, atol=tol)


@pytest.mark.parametrize("g,x", CASES)
def test_tangent_identities(g, x):
    G = GROUPS[g]
    T, Ti, Tm = call(G["T"], x), call(G["Tinv"], x), call(G["T"], -x)
    I = np.eye(len(x))
    tol = 1e-13 * scale(x) ** 2
    np.testing.assert_allclose(T @ Ti, I, rtol=0, atol=tol)
    np.testing.assert_allclose(Ti @ T, I, rtol=0, atol=tol)
    np.testing.assert_allclose(T @ x, x, rtol=0, atol=1e-14 * scale(x))            # (S23)
    E = f64(np_expm(G["hat"](x)))
    Ad = E[:3, :3] if g == "so3" else f64(np_Ad(np_expm(np_hat(x))))
    np.testing.assert_allclose(Tm, Ad @ T, rtol=0, atol=tol)                       # (S22)/(S10)
    Adm = E[:3, :3].T if g == "so3" else f64(np_Ad(np_expm(np_hat(-x))))
    np.testing.assert_allclose(G["ad"](x) @ T, I - Adm, rtol=0, atol=tol)         # (S23)
    if g == "so3":
        np.testing.assert_allclose(T.T, Tm, rtol=0, atol=1e-15)                    # (S10)


@pytest.mark.parametrize("phi", [0.999999, 1.0, 1.000001, 1.299999, 1.3, 1.300001])
@pytest.mark.parametrize("g", ["so3", "se3"])
def test_series_closed_form_switch(g, phi):
    """Both sides of the series/closed-form switch agree with the series reference to ~1e-14."""
    G, r = GROUPS[g], np.random.default_rng(5)
    for _ in range(4):
        w = phi * unit(3, r)
        x = w if g == "so3" else np.r_[unit(3, r), w]
        A = G["ad"](np.asarray(x, LD))
        np.testing.assert_allclose(call(G["T"], x), f64(series_T(A)), rtol=0, atol=1e-14)
        np.testing.assert_allclose(call(G["Tinv"], x), f64(series_Tinv(A)), rtol=0, atol=1e-14)
        np.testing.assert_allclose(call(G["exp"], x), f64(np_expm(G["hat"](x))), rtol=0, atol=1e-14)


# ----------------------------------------------------------------------------- 5. adjoint
def test_adjoint():
    r = np.random.default_rng(6)
    for _ in range(10):
        a, b, y = r.normal(size=(3, 6))
        a[3:] *= 3.0 / np.linalg.norm(a[3:]) * r.uniform()  # rotation angle up to 3
        H1, H2 = f64(np_expm(np_hat(a))), f64(np_expm(np_hat(b)))
        Ad1, Ad2 = call(lie.adjoint_se3, H1), call(lie.adjoint_se3, H2)
        np.testing.assert_allclose(call(lie.adjoint_se3, H1 @ H2), Ad1 @ Ad2, rtol=0, atol=1e-13)
        np.testing.assert_allclose(Ad1, scipy_expm(np_ad(a)), rtol=0, atol=1e-13)
        np.testing.assert_allclose(Ad1 @ y, np_vee(H1 @ np_hat(y) @ np_ginv(H1)), rtol=0, atol=1e-13)
        np.testing.assert_allclose(call(lie.adjoint_se3, np_ginv(H1)), np.linalg.inv(Ad1), atol=1e-12)


# ----------------------------------------------------------------------------- 6. derivatives
KERNELS = {  # name: (function, input dim, long-double reference or None for identity)
    "exp_so3": (lie.exp_so3, 3, lambda x: np_expm(np_skew(x))),
    "log_exp_so3": (lambda x: lie.log_so3(lie.exp_so3(x)), 3, None),
    "exp_se3": (lie.exp_se3, 6, lambda x: np_expm(np_hat(x))),
    "log_exp_se3": (lambda x: lie.log_se3(lie.exp_se3(x)), 6, None),
    "tangent_so3": (lie.tangent_so3, 3, lambda x: series_T(np_skew(x), 40)),
    "tangent_so3_inv": (lie.tangent_so3_inv, 3, lambda x: series_Tinv(np_skew(x), 40)),
    "tangent_se3": (lie.tangent_se3, 6, lambda x: series_T(np_ad(x), 40)),
    "tangent_se3_inv": (lie.tangent_se3_inv, 6, lambda x: series_Tinv(np_ad(x), 40)),
}


@pytest.mark.parametrize("name", list(KERNELS))
def test_derivatives_finite_and_correct_near_zero(name):
    fn, n, ref = KERNELS[name]
    r = np.random.default_rng(8)
    d = unit(n, r)
    points = [np.zeros(n), 1e-12 * d, 1e-7 * d] + ([np.r_[0.3, -1.0, 2.0, 0, 0, 0]] if n == 6 else [])
    W = jnp.asarray(r.normal(size=np.shape(fn(jnp.zeros(n)))))  # fixed random linear functional
    lin = lambda x: jnp.sum(W * fn(x))
    # compile-time dominated (~75% of this file): LLVM opt level 0 compiles ~25% faster, same semantics
    derivs = jax.jit(lambda x: (jax.jacfwd(fn)(x), jax.jacrev(fn)(x), jax.hessian(lin)(x)),
                     compiler_options={"xla_backend_optimization_level": 0})
    for x in points:
        Jf, Jr, Hl = D = [np.asarray(M) for M in derivs(jnp.asarray(x))]
        for M in D:
            assert np.all(np.isfinite(M)), (name, x)
        np.testing.assert_allclose(Jf, Jr, rtol=0, atol=1e-14)
        np.testing.assert_allclose(Hl, Hl.T, rtol=0, atol=1e-12)
        if ref is None:  # log(exp(x)) = x  ->  Jacobian = I
            np.testing.assert_allclose(Jf, np.eye(n), rtol=0, atol=1e-14 if not x.any() else 1e-12)
            continue
        np.testing.assert_allclose(Jf, f64(fd_jac(ref, x, 1e-6)), rtol=0, atol=1e-9)
        Wl = np.asarray(W, LD)
        H_fd = fd_jac(lambda z: fd_jac(lambda u: np.sum(Wl * ref(u)), z, 1e-4), x, 1e-4)
        np.testing.assert_allclose(Hl, f64(H_fd), rtol=0, atol=1e-6)


JAC_EXP_SE3 = jax.jit(jax.jacfwd(lie.exp_se3))


@pytest.mark.parametrize("phi", [1e-6, 1e-4, 5e-4, 9e-4, 0.5, 0.999999, 1.000001, 2.5])
def test_exp_se3_jacobian_vs_reference(phi):
    """jacfwd(exp_se3) == exp(x) hat(T(x) e_k) (exact, long double) and == central FD of expm."""
    r = np.random.default_rng(9)
    x = np.r_[unit(3, r), phi * unit(3, r)]
    J = call(JAC_EXP_SE3, x)
    E, T = np_expm(np_hat(x)), series_T(np_ad(np.asarray(x, LD)))
    exact = np.stack([E @ np_hat(T[:, k]) for k in range(6)], axis=-1)
    np.testing.assert_allclose(J, f64(exact), rtol=0, atol=1e-14)
    np.testing.assert_allclose(J, f64(fd_jac(lambda z: np_expm(np_hat(z)), x, 1e-6)), rtol=0, atol=1e-9)


# ----------------------------------------------------------------------------- 8. jit / vmap
R_BATCH = np.stack([f64(np_expm(np_skew(w))) for w in ROTVECS])
H_BATCH = np.stack([f64(np_expm(np_hat(x))) for x in TWISTS])
BATCHES = {"rotvec": np.stack(ROTVECS), "twist": np.stack(TWISTS), "R": R_BATCH, "H": H_BATCH}


@pytest.mark.parametrize("name,batch", [
    ("exp_so3", "rotvec"), ("log_so3", "R"), ("tangent_so3", "rotvec"), ("tangent_so3_inv", "rotvec"),
    ("exp_se3", "twist"), ("log_se3", "H"), ("tangent_se3", "twist"), ("tangent_se3_inv", "twist"),
    ("adjoint_se3", "H"), ("ad_se3", "twist"), ("hat_se3", "twist"), ("skew", "rotvec")])
def test_jit_vmap_matches_loop(name, batch):
    fn, X = getattr(lie, name), BATCHES[batch]
    out = np.asarray(jax.jit(jax.vmap(fn))(jnp.asarray(X)))
    loop = np.stack([call(fn, x) for x in X])
    assert out.dtype == np.float64
    np.testing.assert_allclose(out, loop, rtol=0, atol=1e-14)
