"""The two tangent paths (``tangent="closed_form"`` and ``"autodiff"``) build the same exact
tangent: the static tangent and the dynamic iteration matrix (damping, sliding drives,
lumped and consistent inertia) agree to round-off, and both agree with central
differences of the residual along the Lie-group chart ``H exp(eps x)``."""
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import simsoft_jax as sj
from simsoft_jax.physics import assembly
from simsoft_jax.couplings import drives
from simsoft_jax.math import lie, linalg
from simsoft_jax.model import loads
from simsoft_jax.solvers.dynamics import element_inertia
from simsoft_jax.solvers.dynamics.residual import residual_and_iteration_matrix
from simsoft_jax.solvers.dynamics.scheme import iteration_factors

from test_one_model import dynamic_scene, static_scene


def deformed(model, seed, size=0.05):
    """Frames moved away from the reference by random right perturbations."""
    x = size * np.random.default_rng(seed).standard_normal((model.structure.n_nodes, 6))
    return jax.vmap(lie.compose_exp)(model.R0, model.p0, jnp.asarray(x))


def check_static_paths(model, lam=0.7):
    """At frames deformed away from the reference: the static residual and tangent of the
    two paths agree to round-off, and the tangent matches central differences of the
    residual along the chart (free dofs only)."""
    R, p = deformed(model, 0)
    tangent = jax.jit(assembly.residual_and_tangent, static_argnums=4)
    (r1, b1), (r2, b2) = (tangent(model, R, p, lam, t) for t in ("closed_form", "autodiff"))
    K1, K2 = np.asarray(linalg.dense(b1)), np.asarray(linalg.dense(b2))
    np.testing.assert_allclose(np.asarray(r1), np.asarray(r2), rtol=0, atol=1e-12)
    np.testing.assert_allclose(K1, K2, rtol=0, atol=1e-10 * np.abs(K1).max())
    mask = np.asarray(model.structure.free_mask()).ravel() > 0
    x = np.random.default_rng(3).standard_normal(K1.shape[0]) * mask
    residual = jax.jit(lambda e: assembly.residual(
        model, *jax.vmap(lie.compose_exp)(R, p, e * jnp.asarray(x).reshape(-1, 6)), lam))
    eps = 1e-6
    fd = (np.asarray(residual(eps)) - np.asarray(residual(-eps))).ravel() / (2 * eps)
    np.testing.assert_allclose((K1 @ x)[mask], fd[mask], rtol=0, atol=1e-6 * np.abs(fd).max())


def check_dynamic_paths(model, sliding=False):
    """At a deformed, moving state: the dynamic residual and iteration matrix
    ``M beta' + C gamma' + K T(w)`` of the two paths agree to round-off."""
    R, p = deformed(model, 1)
    rng = np.random.default_rng(4)
    v, vd, w = (jnp.asarray(0.3 * rng.standard_normal(model.p0.shape[:1] + (6,)))
                for _ in range(3))
    beta_p, gamma_p = iteration_factors(0.8, 0.01)
    inert = element_inertia(model)
    slide = drives.slide_maps(model, R, w) if sliding else None
    matrix = jax.jit(residual_and_iteration_matrix, static_argnums=10)
    (r1, b1), (r2, b2) = (matrix(model, inert, R, p, v, vd, w, beta_p, gamma_p, slide, t)
                          for t in ("closed_form", "autodiff"))
    S1, S2 = np.asarray(linalg.dense(b1)), np.asarray(linalg.dense(b2))
    np.testing.assert_allclose(np.asarray(r1), np.asarray(r2), rtol=0, atol=1e-10)
    np.testing.assert_allclose(S1, S2, rtol=0, atol=1e-10 * np.abs(S1).max())


def test_static_tangent_paths_agree_and_match_finite_differences():
    check_static_paths(sj.build_model(sj.Scene.from_dict(static_scene())))


@pytest.mark.parametrize("inertia, sliding", [("consistent", False), ("lumped", True)],
                         ids=["consistent-drive", "lumped-sliding-drive"])
def test_dynamic_iteration_matrix_paths_agree(inertia, sliding):
    """Damped rod, all load kinds, a driven (or sliding) base: residual and iteration
    matrix of both paths agree."""
    scene = dynamic_scene()
    scene["solver"]["inertia"] = inertia
    if sliding:
        scene["constraints"][0]["slides_along"] = [1.0, 0.0, 0.0]
    model = loads.loads_at(sj.build_model(sj.Scene.from_dict(scene)), 0.2)
    assert model.viscosity is not None and bool(model.structure.slide_drives) == sliding
    check_dynamic_paths(model, sliding)


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
