"""Mass-proportional damping (material key ``mass_damping``, c in 1/s).

Closed form: with the residual ``M vdot + c M v + f_int(q) = f_ext``, every mode of the
linearised system obeys ``q'' + c q' + omega^2 q = 0``, whose solution is
``exp(-c t / 2) (a cos(omega_d t) + b sin(omega_d t))`` with
``omega_d = sqrt(omega^2 - c^2 / 4)``: all modes decay at the same rate ``c / 2``. A
cantilever released with a small transverse velocity in its static-deflection shape (mostly
the first mode) is fitted to that form; the fitted rate must be ``c / 2`` and the frequency
the Euler-Bernoulli first frequency ``1.8751^2 sqrt(EI / rhoA) / L^2`` damped as above.
The gradient of a tip displacement with respect to c (a traced Model leaf) is checked
against central differences, and both iteration-matrix paths against each other.
"""
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.optimize import curve_fit

import simsoft_jax as sj
from simsoft_jax.math import linalg
from simsoft_jax.solvers.dynamics import element_inertia
from simsoft_jax.solvers.dynamics.residual import residual_and_iteration_matrix
from simsoft_jax.solvers.dynamics.scheme import iteration_factors

from test_one_model import dynamic_scene
from test_tangent_paths import deformed

L, RADIUS, E, RHO, C = 1.0, 0.02, 1e6, 1000.0, 0.2
N = 6
AREA, I = np.pi * RADIUS**2, np.pi * RADIUS**4 / 4
OMEGA = 1.8751**2 * np.sqrt(E * I / (RHO * AREA)) / L**2   # rad/s, first cantilever mode
DT = 2 * np.pi / OMEGA / 40
STEPS = 100  # 2.5 periods


def cantilever(c):
    """A clamped slender rod (r/L = 0.02), no gravity, released with a tip speed of 1 mm/s
    in the static-deflection shape ``x^2 (3L - x) / (2 L^3)``."""
    scene = sj.Scene.from_dict({
        "solver": {"kind": "dynamic", "t_end": STEPS * DT, "dt": DT, "rho_inf": 1.0},
        "materials": [{"name": "m", "E": E, "G": E / 3, "density": RHO, "mass_damping": c}],
        "rods": [{"name": "b", "material": "m", "elements": N,
                  "section": {"shape": "circle", "diameter": 2 * RADIUS},
                  "geometry": {"kind": "straight", "length": L}}],
        "constraints": [{"kind": "clamp", "rod": "b", "node": 0}]})
    model = sj.build_model(scene)
    x = np.linspace(0.0, L, N + 1)
    v0 = np.zeros((N + 1, 6))
    v0[:, 2] = 1e-3 * x**2 * (3 * L - x) / (2 * L**3)      # w (m/s), body z = world z
    v0[:, 4] = -1e-3 * 3 * x * (2 * L - x) / (2 * L**3)     # rotation rate about y = -dw/dx
    return model.replace(v0=jnp.asarray(v0))


SETTINGS = sj.DynamicSettings(dt=DT, steps=STEPS, rho_inf=1.0, tolerance=1e-12)


@jax.jit
def tip_history(model):
    return sj.simulate(model, SETTINGS, differentiable=True).p[:, -1, 2]


@pytest.mark.slow
def test_mode_decays_at_half_the_damping_constant_and_gradient_matches_fd():
    model = cantilever(C)
    assert model.mass_damping is not None
    np.testing.assert_array_equal(np.asarray(model.mass_damping), np.full(N, C))
    z = np.asarray(tip_history(model))
    t = np.arange(STEPS + 1) * DT

    def form(t, rate, omega, a, b):
        return np.exp(-rate * t) * (a * np.cos(omega * t) + b * np.sin(omega * t))

    (rate, omega, *_), _ = curve_fit(form, t, z, p0=[0.1, OMEGA, 0.0, 1e-3 / OMEGA])
    assert abs(rate - C / 2) < 0.01 * C / 2
    assert abs(omega - np.sqrt(OMEGA**2 - C**2 / 4)) < 0.01 * OMEGA

    # d(tip z at t_end)/dc, c a traced leaf: implicit-function gradient vs central FD
    def final_tip(c):
        return tip_history(model.replace(mass_damping=c * jnp.ones(N)))[-1]

    grad = float(jax.jit(jax.grad(final_tip))(C))
    h = 1e-4
    fd = (float(final_tip(C + h)) - float(final_tip(C - h))) / (2 * h)
    assert abs(grad) > 1e-5 * float(np.abs(z).max())  # the tip is sensitive to c
    np.testing.assert_allclose(grad, fd, rtol=1e-5)


def test_iteration_matrix_paths_agree_with_mass_damping():
    """Closed-form ``C += c M_e`` and jax.jacfwd of the term give one iteration matrix, and
    its velocity part is the term's: the matrices with and without damping differ by
    ``gamma' c M`` (M the assembled mass matrix), at a deformed, moving state."""
    model = cantilever(C)
    R, p = deformed(model, 1)
    rng = np.random.default_rng(5)
    v, vd, w = (jnp.asarray(0.3 * rng.standard_normal(model.p0.shape[:1] + (6,)))
                for _ in range(3))
    beta_p, gamma_p = iteration_factors(0.8, 0.01)
    matrix = jax.jit(residual_and_iteration_matrix, static_argnums=10)
    undamped = model.replace(mass_damping=jnp.zeros(N))  # same structure: no recompilation
    (r1, b1), (r2, b2), (_, b0) = [
        matrix(m, element_inertia(m), R, p, v, vd, w, beta_p, gamma_p, None, tangent)
        for m, tangent in ((model, "closed_form"), (model, "autodiff"),
                           (undamped, "closed_form"))]
    S1, S2 = np.asarray(linalg.dense(b1)), np.asarray(linalg.dense(b2))
    np.testing.assert_allclose(np.asarray(r1), np.asarray(r2), rtol=0, atol=1e-10)
    np.testing.assert_allclose(S1, S2, rtol=0, atol=1e-10 * np.abs(S1).max())
    masses = element_inertia(model).masses
    a = np.asarray(model.structure.element_nodes)
    M = np.zeros((6 * (N + 1),) * 2)
    for e, Me in zip(a, np.asarray(masses)):
        M[6 * e:6 * e + 12, 6 * e:6 * e + 12] += Me
    free = np.asarray(model.structure.free_mask()).ravel()
    S0 = np.asarray(linalg.dense(b0))
    np.testing.assert_allclose((S1 - S0)[np.ix_(free > 0, free > 0)],
                               gamma_p * C * M[np.ix_(free > 0, free > 0)],
                               rtol=0, atol=1e-10 * np.abs(S1).max())


def test_mass_damping_key_is_validated_and_not_silently_dropped():
    scene = dynamic_scene()
    scene["materials"][0]["mass_damping"] = -1.0
    with pytest.raises(ValueError, match=r"materials\[0\]\.mass_damping"):
        sj.Scene.from_dict(scene)
    scene["materials"][0]["mass_damping"] = 0.0
    undamped = sj.build_model(sj.Scene.from_dict(scene))
    assert undamped.mass_damping is None
    with pytest.raises(ValueError, match="^mass_damping: this model was built without"):
        undamped.replace(mass_damping=jnp.ones(undamped.length.shape))
