"""Gradients at contact onset are finite and right.

A rod lying exactly on an obstacle (gap 0: zero normal force at the first step) with
Coulomb friction is thrown forward and down onto it, so that it presses on the obstacle
and slides with friction; the reverse-mode gradient of its final tip
position through the differentiable rollout (implicit derivative of every step), in the
initial velocities and in the friction coefficient, is checked against central finite
differences of the rollout itself, for a plane, a sphere and a tube. The three cases
share one scene structure (one compiled program): each holds all three obstacles, the
two not under test far from the rod (a huge tube around it), where their contact force
and its derivatives are exactly zero. Dimensions are binary fractions, so the start
gaps are exactly 0. The contact is soft enough to be
resolved by the step (contact time pi sqrt(rhoA/k) = 0.07 s, fourteen steps).
Also each contact formula's derivatives at the singular points (zero gap, zero normal
force, zero slip, a point on an obstacle's axis or centre).
"""
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import simsoft_jax as sj
from simsoft_jax.physics import obstacles
from simsoft_jax.physics.terms import contact, static_friction

R_C = 1.0 / 64.0
OBSTACLES = {
    "plane": {"kind": "plane", "point": [0.0, 0.0, -R_C], "normal": [0.0, 0.0, 1.0]},
    "sphere": {"kind": "sphere", "center": [0.25, 0.0, -(0.125 + R_C)], "radius": 0.125},
    "tube": {"kind": "tube", "axis_point": [0.0, 0.0, 0.0625 - R_C], "axis": [1.0, 0.0, 0.0],
             "radius": 0.0625},
}
# the obstacles not under test: 10 m from the rod (the tube: around it, 10 m away)
FAR = {
    "plane": {"kind": "plane", "point": [0.0, 0.0, -10.0], "normal": [0.0, 0.0, 1.0]},
    "sphere": {"kind": "sphere", "center": [0.25, 0.0, -10.125], "radius": 0.125},
    "tube": {"kind": "tube", "axis_point": [0.0, 0.0, 0.0], "axis": [1.0, 0.0, 0.0],
             "radius": 10.0},
}
DT, STEPS = 0.005, 10
# a tight Newton tolerance: the central differences below divide the rollout's error by 2e-6
SETTINGS = sj.DynamicSettings(dt=DT, steps=STEPS, tolerance=1e-12)
WEIGHTS = jnp.asarray([0.3, -0.2, 1.0])


def thrown(kind, far=False, velocity=(0.25, 0.0, -0.05)):
    """The rod at gap 0 on the obstacle ``kind`` thrown at ``velocity`` (m/s; by default
    forward and down onto it); ``far``: with the other obstacles too, far away (in the
    order of :data:`OBSTACLES`' sorted names)."""
    kinds = sorted(OBSTACLES) if far else [kind]
    return {"solver": {"kind": "dynamic", "t_end": DT * STEPS, "dt": DT},
            "gravity": {"vector": [0.0, 0.0, -9.81]},
            "initial_velocity": [{"rod": "rod", "linear": list(velocity)}],
            "rods": [{"name": "rod", "elements": 4,
                      "geometry": {"kind": "straight", "length": 0.5},
                      "stiffness": {"EA": 1e4, "GAy": 1e4, "GAz": 1e4, "GJ": 1.0,
                                    "EIy": 1.0, "EIz": 1.0},
                      "inertia": {"rhoA": 0.5, "rhoJ": 1e-4, "rhoIy": 5e-5, "rhoIz": 5e-5}}],
            "obstacles": [{"name": k, "friction": 0.3,
                           **(OBSTACLES[k] if k == kind else FAR[k])} for k in kinds],
            "contact": {"radius": R_C, "stiffness": 1e3}}


def _tip(model):
    """The weighted final tip and whether the rollout converged (aux)."""
    traj = sj.simulate(model, SETTINGS, differentiable=True)
    return jnp.dot(traj.p[-1, -1], WEIGHTS), traj.converged


# one program for the gradient, the rollout's convergence and the finite differences, for
# all three obstacles (a plain call of the differentiable rollout would compile another)
TIP_AND_GRADIENT = jax.jit(jax.value_and_grad(_tip, has_aux=True))


@pytest.mark.slow
@pytest.mark.parametrize("kind", sorted(OBSTACLES))
def test_thrown_from_gap_zero_with_friction_gradients_match_finite_differences(kind):
    model = sj.build_model(sj.Scene.from_dict(thrown(kind, far=True)))
    (_, converged), grad = TIP_AND_GRADIENT(model)
    assert bool(converged)
    assert all(bool(jnp.all(jnp.isfinite(x))) for x in jax.tree_util.tree_leaves(grad)
               if jnp.issubdtype(x.dtype, jnp.floating))
    f = lambda **change: float(TIP_AND_GRADIENT(model.replace(**change))[0][0])  # noqa: E731
    direction = jnp.asarray(np.random.default_rng(0).standard_normal(model.v0.shape))
    e = 1e-6
    fd = (f(v0=model.v0 + e * direction) - f(v0=model.v0 - e * direction)) / (2 * e)
    np.testing.assert_allclose(float(jnp.vdot(grad.v0, direction)), fd, rtol=1e-4, atol=1e-9)
    mu = model.obstacle_friction
    fd_mu = (f(obstacle_friction=mu + e) - f(obstacle_friction=mu - e)) / (2 * e)
    assert abs(fd_mu) > 1e-4          # the friction acts on the sliding rod
    np.testing.assert_allclose(float(jnp.sum(grad.obstacle_friction)), fd_mu, rtol=1e-4,
                               atol=1e-9)


@pytest.mark.slow
def test_thrown_onto_a_stiff_plane_the_differentiable_rollout_sub_steps_like_the_plain_one():
    """The robustness issue's case: 10 elements, the default contact stiffness, dt = 0.01.
    The impact needs sub-steps; the differentiable rollout takes the same ones (its
    trajectory equals the plain rollout's) and its gradient in ``v0`` is finite and equals
    central finite differences (it was NaN: the differentiable step did not sub-step). The
    stiff impact curves the final tip sharply in ``v0``: central differences approach the
    derivative only below a step of 1e-6 (1e-5: -5.58, 1e-6: -6.0268, 1e-7: -6.03090
    against -6.03096 here), so the check takes 1e-7 with a tight Newton tolerance."""
    scene = thrown("plane", velocity=(0.25, 0.0, 0.25))     # up, then back onto the plane
    scene["rods"][0]["elements"] = 10
    del scene["contact"]["stiffness"]
    scene["solver"].update(dt=0.01, t_end=0.1)
    model = sj.build_model(sj.Scene.from_dict(scene))
    settings = sj.DynamicSettings(dt=0.01, steps=10, tolerance=1e-13)
    plain = sj.simulate(model, settings)
    weights = jnp.asarray([0.3, -0.2, 1.0])

    def tip(v0):
        """The weighted final tip; aux: the differentiable rollout's positions and
        convergence (from the gradient's own program: a plain call of the differentiable
        rollout would compile another)."""
        smooth = sj.simulate(model.replace(v0=v0), settings, differentiable=True)
        return jnp.dot(smooth.p[-1, -1], weights), (smooth.p, smooth.converged)

    both = jax.jit(jax.value_and_grad(tip, has_aux=True))
    (_, (smooth_p, smooth_converged)), grad = both(model.v0)
    assert bool(plain.converged) and bool(smooth_converged), plain.message()
    assert int(np.max(plain.substeps)) > 1                     # the impact was sub-stepped
    np.testing.assert_allclose(smooth_p, plain.p, rtol=0, atol=1e-12)
    assert bool(jnp.all(jnp.isfinite(grad)))
    direction = jnp.asarray(np.random.default_rng(1).standard_normal(model.v0.shape))
    e = 1e-7
    fd = (float(both(model.v0 + e * direction)[0][0])
          - float(both(model.v0 - e * direction)[0][0])) / (2 * e)
    np.testing.assert_allclose(float(jnp.vdot(grad, direction)), fd, rtol=1e-4, atol=1e-9)


def test_penalty_and_friction_formulas_have_finite_derivatives_at_onset():
    """psi, psi' at zero penetration and at the end of the cubic start; the quasi-static
    friction line load at zero normal force and zero slip (the dynamic one is the same
    formula in the velocities, covered by the rollouts above); the signed
    distances at a sphere's centre and on a tube's axis."""
    k, eps = 1e3, 1e-4
    for delta in (0.0, eps):
        for fn in (contact.penalty, contact.penalty_slope):
            assert np.isfinite(jax.grad(fn, argnums=(0, 1, 2))(delta, k, eps)).all()
    normals = jnp.asarray([[[0.0, 0.0, 1.0]]])

    def quasi_static(load, slip, scale, mu):
        return jnp.sum(static_friction.line_load(load, normals, slip, scale, mu))

    args = (jnp.zeros((1, 1)), jnp.zeros((1, 3)), jnp.asarray(1e-5), jnp.asarray([0.3]))
    for g in jax.grad(quasi_static, argnums=(0, 1, 2, 3))(*args):
        assert np.all(np.isfinite(g))
    row = jnp.zeros(11).at[6].set(0.1).at[3:6].set(jnp.asarray([1.0, 0.0, 0.0]))
    for kind in ("sphere", "tube", "cylinder", "capsule"):
        g = jax.grad(lambda x, p: obstacles.signed_distance(kind, p, x), argnums=(0, 1))(
            jnp.zeros(3), row)
        assert all(np.all(np.isfinite(x)) for x in g)
