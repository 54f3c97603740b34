"""The two tangent paths (``tangent="closed_form"`` and ``"autodiff"``) build the same exact
tangent: the static tangent and the dynamic iteration matrix (damping, sliding drives,
lumped and consistent inertia) agree to round-off, and both agree with central
differences of the residual along the Lie-group chart ``H exp(eps x)``."""
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import simsoft_jax as sj
from simsoft_jax import assembly, drives, lie, linalg, loads
from simsoft_jax.dynamics import element_inertia
from simsoft_jax.dynamics.residual import residual_and_iteration_matrix
from simsoft_jax.dynamics.scheme import iteration_factors

from test_one_model import dynamic_scene, static_scene


def deformed(model, seed, size=0.05):
    """Frames moved away from the reference by random right perturbations."""
    x = size * np.random.default_rng(seed).standard_normal((model.structure.n_nodes, 6))
    return jax.vmap(lie.compose_exp)(model.R0, model.p0, jnp.asarray(x))


def test_static_tangent_paths_agree_and_match_finite_differences():
    model = sj.build_model(sj.Scene.from_dict(static_scene()))
    R, p = deformed(model, 0)
    r1, b1 = jax.jit(assembly.residual_and_tangent, static_argnums=4)(model, R, p, 0.7,
                                                                      "closed_form")
    r2, b2 = jax.jit(assembly.residual_and_tangent, static_argnums=4)(model, R, p, 0.7,
                                                                      "autodiff")
    K1, K2 = np.asarray(linalg.dense(b1)), np.asarray(linalg.dense(b2))
    np.testing.assert_allclose(np.asarray(r1), np.asarray(r2), rtol=0, atol=1e-12)
    np.testing.assert_allclose(K1, K2, rtol=0, atol=1e-10 * np.abs(K1).max())
    # central differences of the residual along the chart, free dofs only
    mask = np.asarray(model.structure.free_mask()).ravel() > 0
    rng = np.random.default_rng(3)
    x = rng.standard_normal(K1.shape[0]).reshape(-1, 6) * mask.reshape(-1, 6)
    eps = 1e-6

    @jax.jit
    def residual_along(e):
        Rx, px = jax.vmap(lie.compose_exp)(R, p, e * jnp.asarray(x))
        return assembly.residual(model, Rx, px, 0.7)

    def res(e):
        return np.asarray(residual_along(e)).ravel()

    fd = (res(eps) - res(-eps)) / (2 * eps)
    np.testing.assert_allclose((K1 @ x.ravel())[mask], fd[mask], rtol=0,
                               atol=1e-6 * np.abs(fd).max())


@pytest.mark.parametrize("inertia, sliding", [("consistent", False), ("lumped", True)],
                         ids=["consistent-drive", "lumped-sliding-drive"])
def test_dynamic_iteration_matrix_paths_agree(inertia, sliding):
    """Damped rod, all load kinds, a driven (or sliding) base: residual and iteration
    matrix ``M beta' + C gamma' + K T(w)`` of both paths agree."""
    scene = dynamic_scene()
    scene["solver"]["inertia"] = inertia
    if sliding:
        scene["constraints"][0]["slides_along"] = [1.0, 0.0, 0.0]
    model = loads.loads_at(sj.build_model(sj.Scene.from_dict(scene)), 0.2)
    assert model.structure.has_viscosity and bool(model.structure.slide_drives) == sliding
    R, p = deformed(model, 1)
    rng = np.random.default_rng(4)
    v, vd, w = (jnp.asarray(0.3 * rng.standard_normal(model.p0.shape[:1] + (6,)))
                for _ in range(3))
    beta_p, gamma_p = iteration_factors(0.8, 0.01)
    inert = element_inertia(model)
    slide = drives.slide_maps(model, R, w) if sliding else None
    matrix = jax.jit(residual_and_iteration_matrix, static_argnums=10)
    out = [matrix(model, inert, R, p, v, vd, w, beta_p, gamma_p, slide, tangent)
           for tangent in ("closed_form", "autodiff")]
    (r1, b1), (r2, b2) = out
    S1, S2 = np.asarray(linalg.dense(b1)), np.asarray(linalg.dense(b2))
    np.testing.assert_allclose(np.asarray(r1), np.asarray(r2), rtol=0, atol=1e-10)
    np.testing.assert_allclose(S1, S2, rtol=0, atol=1e-10 * np.abs(S1).max())


def test_static_solves_agree_on_both_paths():
    model = sj.build_model(sj.Scene.from_dict(static_scene()))
    eqs = [sj.solve_static(model, sj.StaticSettings(tangent=t)) for t in ("closed_form",
                                                                          "autodiff")]
    assert all(bool(e.converged) for e in eqs)
    np.testing.assert_allclose(eqs[0].p, eqs[1].p, rtol=0, atol=1e-11)


@pytest.mark.slow
def test_rollouts_agree_on_both_paths():
    """A 30-step rollout of the damped, driven rod gives the same answer on both paths."""
    model = sj.build_model(sj.Scene.from_dict(dynamic_scene()))
    trajs = [sj.simulate(model, sj.DynamicSettings(dt=0.01, steps=30, tangent=t))
             for t in ("closed_form", "autodiff")]
    assert all(bool(t.converged) for t in trajs)
    np.testing.assert_allclose(trajs[0].p, trajs[1].p, rtol=0, atol=1e-9)


def test_unknown_tangent_is_refused():
    with pytest.raises(ValueError, match="tangent: must be one of"):
        sj.StaticSettings(tangent="numeric")
    with pytest.raises(ValueError, match="solver.tangent"):
        sj.Scene.from_dict(dict(static_scene(), solver={"kind": "static", "tangent": "fd"}))
