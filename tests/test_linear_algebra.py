"""The closed-form element tangent against forward-mode autodiff references (the block
linear algebra is tested in test_linalg_couplings.py, the assembled tangent against
finite differences in test_model_kinematics.py)."""
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from simsoft_jax.physics import element
from simsoft_jax.math import lie


@pytest.mark.parametrize("angle", [0.0, 1e-7, 0.4, 1.7, 3.0])
def test_stress_tangent_matches_autodiff_of_the_chart(angle):
    """K = d/dx [P(d(x))^T stress(d(x))] with d(x) = d + P(d) x (spec S37, S42) by jacfwd."""
    rng = np.random.default_rng(5)
    w = rng.normal(size=3)
    d = jnp.asarray(np.concatenate([rng.normal(size=3), angle * w / np.linalg.norm(w)]))
    d0 = jnp.asarray([0.1, 0.0, 0.0, 0.0, 0.0, 0.0])
    stiffness = jnp.asarray([10.0, 4.0, 5.0, 0.3, 0.7, 0.9])
    length = 0.1

    @jax.jit
    def both(d):
        P = element.strain_map(d)
        closed = element.stress_force_and_tangent(P, d, stiffness * (d - d0) / length,
                                                  jnp.diag(stiffness / length))
        chart = lambda x: element.internal_force(  # noqa: E731
            element.strain_map(d + P @ x), d + P @ x, d0, length, stiffness)
        return closed, (chart(jnp.zeros(12)), jax.jacfwd(chart)(jnp.zeros(12)))

    (f, K), (f_ref, K_ref) = both(d)
    np.testing.assert_allclose(f, f_ref, rtol=1e-13, atol=1e-13)
    np.testing.assert_allclose(K, K_ref, rtol=1e-11, atol=1e-11)


def test_inverse_coefficient_derivatives_match_autodiff():
    for w in (jnp.zeros(3), jnp.asarray([0.3, -0.2, 0.5]), jnp.asarray([1.5, 0.9, -1.2])):
        (g2, g4), (g2x, g4x) = lie.inverse_coefficients_and_derivatives(w)
        x = jnp.dot(w, w)
        coef = lambda xx: jnp.stack(lie.inverse_coefficients(  # noqa: E731
            jnp.asarray([jnp.sqrt(xx), 0.0, 0.0])))
        if float(x) > 0:
            np.testing.assert_allclose([g2x, g4x], jax.jacfwd(coef)(x), rtol=1e-10)
        np.testing.assert_allclose([g2, g4], lie.inverse_coefficients(w), rtol=1e-14)
    # at 0 the series slopes are the x-coefficients: g2 = 1/12 + x/720, g4 = 1/360 + x/7560
    (_, _), (g2x, g4x) = lie.inverse_coefficients_and_derivatives(jnp.zeros(3))
    np.testing.assert_allclose([g2x, g4x], [1 / 720, 1 / 7560], rtol=1e-14)


def test_translation_coefficients_and_derivatives_match_closed_forms():
    """c1 = (1 - cos phi)/phi^2, c2 = (phi - sin phi)/phi^3 (V = I + c1 W + c2 W^2) and their
    first and second x-derivatives (x = phi^2) against autodiff of the closed forms in
    NumPy-independent jnp, and the series values at 0."""
    closed = lambda x: jnp.stack([(1.0 - jnp.cos(jnp.sqrt(x))) / x,  # noqa: E731
                                  (jnp.sqrt(x) - jnp.sin(jnp.sqrt(x))) / x ** 1.5])
    for x in (0.3, 0.99, 1.01, 2.5, 9.0):
        values, first, second = lie.translation_coefficients(jnp.asarray([0.0, jnp.sqrt(x), 0.0]))
        np.testing.assert_allclose(values, closed(x), rtol=1e-13)
        np.testing.assert_allclose(first, jax.jacfwd(closed)(x), rtol=1e-9)
        np.testing.assert_allclose(second, jax.jacfwd(jax.jacfwd(closed))(x), rtol=1e-7)
    values, first, second = lie.translation_coefficients(jnp.zeros(3))
    np.testing.assert_allclose(values, [1 / 2, 1 / 6], rtol=1e-15)
    np.testing.assert_allclose(first, [-1 / 24, -1 / 120], rtol=1e-14)
    np.testing.assert_allclose(second, [2 / 720, 2 / 5040], rtol=1e-14)


@pytest.mark.slow
@pytest.mark.parametrize("angle", [0.0, 1e-7, 0.6, 2.0])
def test_dead_load_is_the_gradient_of_its_potential_with_matching_tangent(angle):
    """Closed-form dead distributed load (spec S44) against the potential
    ``W = int_0^L f . p(s) ds`` evaluated from the nodal poses with exp/log (3-point Gauss):
    nodal forces = dW/dx under right perturbations ``H exp(x)`` of both nodes, and the
    tangent = d/dy of the closed-form forces at ``H exp(y)``."""
    rng = np.random.default_rng(7)
    w = rng.normal(size=3)
    d = jnp.asarray(np.concatenate([[0.3, 0.05, -0.04], angle * w / np.linalg.norm(w)]))
    RA = lie.exp_so3(jnp.asarray(rng.normal(size=3)))
    pA = jnp.asarray(rng.normal(size=3))
    HA = lie.pose(RA, pA)
    HB = HA @ lie.exp_se3(d)
    force, length = jnp.asarray([0.4, -1.3, 2.2]), 0.3
    points = 0.5 * (1.0 + np.array([-np.sqrt(0.6), 0.0, np.sqrt(0.6)]))
    weights = np.array([5.0, 8.0, 5.0]) / 18.0

    def frames(x):
        return HA @ lie.exp_se3(x[:6]), HB @ lie.exp_se3(x[6:])

    def potential(x):
        ha, hb = frames(x)
        dd = lie.log_se3(jnp.linalg.inv(ha) @ hb)
        return sum(wk * length * jnp.dot(force, (ha @ lie.exp_se3(xk * dd))[:3, 3])
                   for xk, wk in zip(points, weights))

    def closed_force(x):
        ha, hb = frames(x)
        dd = lie.log_se3(jnp.linalg.inv(ha) @ hb)
        P = element.strain_map(dd)
        s, _, f_direct, _ = element.dead_load_terms(ha[:3, :3], dd, P, length, force)
        return P.T @ s + f_direct

    P = element.strain_map(d)
    s, S, f_direct, K_direct = element.dead_load_terms(RA, d, P, length, force)
    K = element.stress_force_and_tangent(P, d, s, S)[1] + K_direct
    zero = jnp.zeros(12)
    np.testing.assert_allclose(P.T @ s + f_direct, jax.grad(potential)(zero),
                               rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(K, jax.jacfwd(closed_force)(zero), rtol=1e-8, atol=1e-10)
