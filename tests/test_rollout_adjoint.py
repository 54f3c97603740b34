"""Reverse-mode gradients of rollouts by the discrete adjoint (``simulate(...,
differentiable=True)``: the backward pass runs the steps in reverse, one transposed solve
each) against central finite differences of plain rollouts, on a rod in free motion
(clamped, no coupling) and on a closed loop of two rods welded to a body (joints: the
bordered system). Both forward passes are covered: the compiled program of ``sj.run``
(every step saved) and the recorded rollout (every second step saved)."""
import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import simsoft_jax as sj
from simsoft_jax.solvers import dynamics as dy
from test_compile_once import compilations
from test_dynamics_gradients import SCENE
from test_joints_dynamics import loop_scene


def check_against_central_differences(scalar, x0, h=1e-5, rtol=1e-6):
    """jax.grad of ``scalar(x, True)`` equals central differences of ``scalar(x, False)``
    (plain rollouts) to ``rtol`` relative (2-norm), every component moving it."""
    grad = np.asarray(jax.grad(lambda x: scalar(x, True))(x0))
    fd = np.array([(float(scalar(x0 + h * e, False)) - float(scalar(x0 - h * e, False)))
                   / (2 * h) for e in np.eye(len(x0))])
    assert np.all(np.abs(fd) > 1e-8 * np.linalg.norm(fd)), fd
    assert np.linalg.norm(grad - fd) <= rtol * np.linalg.norm(fd), (grad, fd)


@pytest.mark.parametrize("save_every", [1, 2])
def test_free_rod_gradient_equals_central_differences(save_every):
    """d/d(stiffness scale, load scale, initial velocity scale) of a weighted sum of the
    tip position after 20 steps and of the final accelerations."""
    model = sj.build_model(sj.Scene.from_dict(SCENE))
    settings = dy.DynamicSettings(dt=0.01, steps=20, rho_inf=0.9, save_every=save_every,
                                  tolerance=1e-13)
    weights = jnp.asarray(np.random.default_rng(3).standard_normal(model.v0.shape))

    def scalar(x, differentiable):
        channels = model.channels.replace(nodal_dead=model.channels.nodal_dead * x[1])
        m = model.replace(stiffness=model.stiffness * x[0], channels=channels,
                          v0=model.v0 * x[2])
        traj = dy.simulate(m, settings, differentiable=differentiable)
        assert bool(traj.converged)
        return (traj.p[-1, -1] @ jnp.array([0.3, -1.0, 0.7])
                + 1e-3 * jnp.sum(weights * traj.final.vd))

    check_against_central_differences(scalar, jnp.array([1.0, 1.0, 1.0]))


def test_gradient_from_a_given_state_equals_central_differences():
    """From a moving state of an earlier rollout (t = 0.05 s), d/d(stiffness scale, load
    scale, scale of that state's velocities) of the tip after 10 more steps and of the
    final accelerations; the forward pass is the program of ``sj.run`` started from
    that state (no recorded rollout compiled), the differences plain rollouts from it."""
    model = sj.build_model(sj.Scene.from_dict(SCENE))
    settings = dy.DynamicSettings(dt=0.01, steps=10, rho_inf=0.9, tolerance=1e-13)
    start = dy.simulate(model, settings.replace(steps=5)).final
    assert float(start.t) == pytest.approx(0.05) and np.any(np.asarray(start.v) != 0)
    weights = jnp.asarray(np.random.default_rng(4).standard_normal(model.v0.shape))

    def scalar(x, differentiable):
        channels = model.channels.replace(nodal_dead=model.channels.nodal_dead * x[1])
        m = model.replace(stiffness=model.stiffness * x[0], channels=channels)
        traj = dy.simulate(m, settings, state=start._replace(v=start.v * x[2]),
                           differentiable=differentiable)
        assert bool(traj.converged)
        if not differentiable:
            assert float(traj.time[0]) == pytest.approx(0.05)
        return (traj.p[-1, -1] @ jnp.array([0.3, -1.0, 0.7])
                + 1e-3 * jnp.sum(weights * traj.final.vd))

    with compilations() as seen:
        check_against_central_differences(scalar, jnp.array([1.0, 1.0, 1.0]))
    assert not any("recorded" in name for name in seen), seen


def test_welded_loop_gradient_equals_central_differences():
    """d/d(plate mass, rod stiffness scale, plate inertia I_xx) of the plate's position
    after 30 steps of the closed loop (two rods welded to a plate)."""
    model = sj.build_model(sj.Scene.from_dict(loop_scene()))
    settings = dy.DynamicSettings(dt=0.005, steps=30, rho_inf=0.9, tolerance=1e-13)
    plate = dict(model.structure.bodies)["plate"]
    k = list(model.structure.mass_nodes).index(plate)

    def scalar(x, differentiable):
        m = dataclasses.replace(
            model, mass=model.mass.at[k].set(0.05 * x[0]), stiffness=model.stiffness * x[1],
            mass_inertia=model.mass_inertia.at[k, 0, 0].set(1e-4 * x[2]))
        traj = dy.simulate(m, settings, differentiable=differentiable)
        assert bool(traj.converged)
        return traj.p[-1, plate] @ jnp.array([1.0, 0.5, -2.0])

    check_against_central_differences(scalar, jnp.array([1.0, 1.0, 1.0]))


def test_forward_mode_needs_the_forward_option():
    """The adjoint is reverse only: jax.jvp through ``differentiable=True`` is refused by
    JAX, and ``differentiable="forward"`` gives the same derivative as jax.grad."""
    model = sj.build_model(sj.Scene.from_dict(SCENE))
    settings = dy.DynamicSettings(dt=0.01, steps=5, rho_inf=0.9)

    def tip(s, differentiable):
        return dy.simulate(model.replace(stiffness=model.stiffness * s), settings,
                           differentiable=differentiable).p[-1, -1, 2]

    with pytest.raises(TypeError, match="custom_vjp"):
        jax.jvp(lambda s: tip(s, True), (1.0,), (1.0,))
    forward = jax.jvp(lambda s: tip(s, "forward"), (1.0,), (1.0,))[1]
    reverse = jax.grad(lambda s: tip(s, True))(1.0)
    assert abs(float(forward)) > 1e-6
    assert abs(float(forward) - float(reverse)) <= 1e-9 * abs(float(forward))
    with pytest.raises(ValueError, match="differentiable"):
        dy.simulate(model, settings, differentiable="sideways")


def test_gradient_reuses_the_compiled_rollout():
    """After a plain rollout of a structure (the program of ``sj.run``), jax.grad through
    the differentiable rollout compiles its backward program only, and a second gradient
    (another stiffness) compiles nothing."""
    model = sj.build_model(sj.Scene.from_dict(SCENE))
    settings = dy.DynamicSettings(dt=0.01, steps=7, rho_inf=0.9)
    dy.simulate(model, settings)

    def tip(s):
        return dy.simulate(model.replace(stiffness=model.stiffness * s), settings,
                           differentiable=True).p[-1, -1, 2]

    with compilations() as first:
        jax.grad(tip)(1.0)
    programs = ("program", "chunk", "gradient")
    solvers = {name: n for name, n in first.items() if any(p in name for p in programs)}
    assert solvers == {"jit(rollout_gradient)": 1}, first
    with compilations() as again:
        jax.grad(tip)(1.1)
    assert not any(p in name for name in again for p in programs), again
