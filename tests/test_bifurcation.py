"""The static continuation stays on the stable branch past a bifurcation.

A clamped-free column of length L, bending stiffness EI, under a dead axial tip force
P = 2 P_cr (``P_cr = pi^2 EI / (4 L^2)``), a small lateral tip force F (-z) and a small
initial crookedness against it (+z). Near P_cr the near-straight equilibrium becomes
unstable; a continuation that steps over P_cr lands on it (tip 1e-5 off the axis,
two negative eigenvalues). The stable state is the buckled elastica bent with F. The
reference is the inextensible planar elastica solved here by shooting:
``EI theta'' = -(F cos theta + P sin theta)`` (theta the angle of the centreline from
x toward z), ``theta(0) = 0``, ``theta'(L) = 0``, tip ``(int cos theta, int sin theta)``.
"""
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

import simsoft_jax as sj
from simsoft_jax.math import linalg
from simsoft_jax.solvers import stability
from simsoft_jax.physics.assembly import residual_and_tangent
from simsoft_jax.solvers.batched import solve_static_lane
from simsoft_jax.model.loads import full_loads
from simsoft_jax.solvers.statics import branch

L, EI = 1.0, 1.0
P_CR = np.pi**2 * EI / (4 * L**2)
P, F = 2.0 * P_CR, -1e-5


def column(crooked=1e-4, lateral=F, **solver):
    stiff = {"EA": 1e5, "GAy": 1e5, "GAz": 1e5, "GJ": 1.0, "EIy": EI, "EIz": EI}
    geometry = ({"kind": "polyline", "points": [[0, 0, 0], [L / 2, 0, crooked], [L, 0, 0]]}
                if crooked else {"kind": "straight", "length": L})
    return {"name": "column", "solver": {"kind": "static", **solver},
            "rods": [{"name": "c", "stiffness": stiff, "elements": 24,
                      "inertia": {"rhoA": 1.0, "rhoJ": 1.0, "rhoIy": 1.0, "rhoIz": 1.0},
                      "geometry": geometry}],
            "constraints": [{"kind": "clamp", "rod": "c", "node": 0}],
            "loads": [{"kind": "force", "rod": "c", "node": -1, "vector": [-P, 0.0, lateral],
                       "frame": "world"}]}


def elastica_tip(kappa_bracket):
    """Tip (x, z) of the elastica whose root curvature lies in ``kappa_bracket``."""
    def shoot(kappa0):
        rhs = lambda s, y: [y[1], -(F * np.cos(y[0]) + P * np.sin(y[0])) / EI,  # noqa: E731
                            np.cos(y[0]), np.sin(y[0])]
        return solve_ivp(rhs, (0.0, L), [0.0, kappa0, 0.0, 0.0], rtol=1e-12, atol=1e-12).y[:, -1]
    kappa0 = brentq(lambda k: shoot(k)[1], *kappa_bracket, xtol=1e-13)
    return shoot(kappa0)[2:]


def test_column_past_buckling_lands_on_the_stable_branch():
    """Default settings: the buckled state bent with the lateral load, stable, matching
    the elastica (24 elements, EA = GA = 1e5: extension and shear ~ P/EA = 5e-5)."""
    result = sj.run(column())
    assert result.converged
    assert result.stability == {"negative_eigenvalues": 0, "stable": True}
    x, z = elastica_tip((-6.0, -1.0))
    assert z < -0.7                                   # really buckled (0.797 L)
    tip = result.positions("c")[-1]
    np.testing.assert_allclose(tip, [x, 0.0, z], atol=2e-3)
    assert int(stability.negative_eigenvalues(result.model, result.raw)) == 0


@pytest.mark.parametrize("solver", [{"load_steps": 2}, {"max_load_step": 1.0}])
def test_large_load_steps_still_follow_the_stable_branch(solver):
    """Coarse continuations (2 levels; steps growing to the full loads) refine at the
    critical load and switch to the same stable branch."""
    result = sj.run(column(**solver))
    assert result.converged and result.stability["stable"]
    x, z = elastica_tip((-6.0, -1.0))
    np.testing.assert_allclose(result.positions("c")[-1], [x, 0.0, z], atol=2e-3)


def test_perfect_column_has_no_side_and_stays_straight():
    """Without crookedness or lateral load the path is symmetric: no branch to prefer,
    the straight (unstable) state is kept and reported by the stability count."""
    scene = column(crooked=0.0)
    scene["loads"][0]["vector"] = [-P, 0.0, 0.0]
    result = sj.run(scene)
    assert result.converged
    tip = result.positions("c")[-1]
    assert abs(tip[1]) < 1e-12 and abs(tip[2]) < 1e-12
    assert result.stability == {"negative_eigenvalues": 2, "stable": False}


def test_batched_lanes_each_take_their_own_stable_side():
    """The flat continuation of batched sweeps under ``vmap``: two lanes with the lateral
    load and crookedness mirrored (+-z) end on mirrored stable branches, one per side."""
    base = sj.build_model(sj.Scene.from_dict(column()))
    other = sj.build_model(sj.Scene.from_dict(column(crooked=-1e-4, lateral=-F)))
    models = jax.tree_util.tree_map(lambda a, b: np.stack([a, b]), base, other)
    settings = sj.statics.as_traced(sj.StaticSettings())
    eq = jax.jit(jax.vmap(solve_static_lane, in_axes=(0, None)))(models, settings)
    assert np.all(np.asarray(eq.converged))
    x, z = elastica_tip((-6.0, -1.0))
    tips = np.asarray(eq.p)[:, -1]
    np.testing.assert_allclose(tips[0], [x, 0.0, z], atol=2e-3)
    np.testing.assert_allclose(tips[1], [x, 0.0, -z], atol=2e-3)


@pytest.mark.parametrize("eigh_limit", [0, 1000])
def test_critical_kick_is_inverse_iteration_on_the_symmetric_tangent(monkeypatch, eigh_limit):
    """Both ways to the branch-switching move (a dense eigendecomposition for short rods,
    inverse iteration with the block factorization for long ones) give the move of the
    package docstring: eight inverse iterations ``S^-8 d`` (NumPy, dense S: the
    symmetric part of the tangent of the straight column past P_cr) scaled to a largest
    nodal rotation or translation / char_length of KICK, on the side of ``d``; the move
    is mostly a buckling mode (the eigenvectors of the negative eigenvalue of S; a
    torsion mode of an eigenvalue close in size keeps a share after eight passes)."""
    scene = column(crooked=0.0)
    scene["loads"][0]["vector"] = [-P, 0.0, 0.0]
    model = sj.build_model(sj.Scene.from_dict(scene))
    eq = sj.solve_static(model)
    _, blocks = residual_and_tangent(full_loads(model), eq.R, eq.p, 1.0)
    n = model.p0.shape[0]
    d = np.random.default_rng(3).normal(size=(n, 6))
    d[0] = 0.0                                       # the clamped node does not move
    monkeypatch.setattr(branch, "EIGH_LIMIT_NODES", eigh_limit)
    kick = np.asarray(branch.critical_kick(model, blocks, jnp.asarray(d)))

    K = np.asarray(linalg.dense(blocks))
    S = 0.5 * (K + K.T)
    x = d.ravel()
    for _ in range(8):
        x = np.linalg.solve(S, x)
        x /= np.linalg.norm(x)
    scale = np.array([1 / float(model.char_length)] * 3 + [1.0] * 3)
    weighted = x.reshape(n, 6) * scale
    size = np.max(np.maximum(np.linalg.norm(weighted[:, :3], axis=1),
                             np.linalg.norm(weighted[:, 3:], axis=1)))
    side = np.sign(np.vdot(weighted, d * scale))
    np.testing.assert_allclose(kick, side * branch.KICK / size * x.reshape(n, 6),
                               rtol=0, atol=1e-9 * branch.KICK)
    lam, modes = np.linalg.eigh(S)
    buckling = modes[:, lam < 0.0]                   # the two buckling planes
    assert buckling.shape[1] == 2
    k = kick.ravel()
    assert np.linalg.norm(buckling.T @ k) > 0.95 * np.linalg.norm(k)
