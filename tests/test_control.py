"""Closed-loop control inside the rollout (``simulate(..., control=policy)``) against
closed forms:

* a P-controlled tip moment ``M = k (th* - th)`` on a damped cantilever in pure bending
  settles where ``th = M L / EI``: ``th = k th* / (EI/L + k)``; ``d th / d k`` through
  the whole closed loop (implicit derivative per step) equals
  ``th* (EI/L) / (EI/L + k)^2``; ``vmap`` over gains equals the loop over them; a policy
  that applies a constant moment reproduces the open-loop rollout with that moment;
* a PI controller on a tendon (offset r, no gravity) drives the tip height to its target
  with zero steady-state error, at the tension of the exact tendon arc (curvature
  ``T r / EI``, axial strain ``-T / EA``); a P controller alone stops where the arc's
  height and ``T = kp (z* - z)`` agree, short of the target;
* gradients of a tracking cost in the PID gains against central finite differences;
* the task-space helpers: tip velocity against a difference of positions, the static
  Jacobian of the tendon arm against the arc's derivative, the one-step Jacobian against
  finite differences, task-space PD against the pseudo-inverse.
"""
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import simsoft_jax as sj
from simsoft_jax.studies import control as ctl
from simsoft_jax.solvers import dynamics as dy

# ---------------------------------------------------------------- P-controlled tip moment
EI_M, L_M, TARGET = 1.0, 1.0, 0.5          # N m^2, m, rad
MOMENT_SCENE = {
    "solver": {"kind": "dynamic", "t_end": 1.0, "dt": 0.05},
    "rods": [{"name": "rod", "elements": 3, "geometry": {"kind": "straight", "length": L_M},
              "material": {"E": 1e6, "nu": 0.5, "density": 1000.0, "mass_damping": 20.0},
              "stiffness": {"EA": 1e4, "GAy": 1e4, "GAz": 1e4, "GJ": 1.0, "EIy": EI_M,
                            "EIz": EI_M},
              "inertia": {"rhoA": 0.1, "rhoJ": 0.1, "rhoIy": 0.1, "rhoIz": 0.1}}],
    "constraints": [{"kind": "clamp", "rod": "rod", "node": 0}],
    "loads": [{"kind": "moment", "rod": "rod", "node": -1, "vector": [0.0, 0.0, 0.0]}]}
MOMENT_SETTINGS = dy.DynamicSettings(dt=0.05, steps=400, save_every=40, tolerance=1e-12)


def tip_angle(R):
    """Rotation angle (rad) about y of a frame R = rot_y(th) (planar bending)."""
    return jnp.arctan2(R[..., 0, 2], R[..., 0, 0])


def moment_policy(t, state, model, k):
    """Tip moment about y, ``k (th* - th)`` N m, from the tip angle at the step's start."""
    th = tip_angle(ctl.tip_pose(model, state, "rod")[0])
    return model.replace(nodal_dead=model.nodal_dead.at[-1, 4].set(k * (TARGET - th)))


@pytest.fixture(scope="module")
def moment_model():
    return sj.build_model(sj.Scene.from_dict(MOMENT_SCENE))


def settled_angle(model, k, differentiable=False):
    traj = dy.simulate(model, MOMENT_SETTINGS, control=moment_policy,
                       control_params=jnp.asarray(k, jnp.float64),
                       differentiable=differentiable)
    return tip_angle(traj.R[-1, -1]), traj


def test_p_controlled_moment_settles_at_closed_form(moment_model):
    for k in (0.5, 1.0):
        th, traj = settled_angle(moment_model, k)
        assert bool(traj.converged), traj.message()
        expected = k * TARGET / (EI_M / L_M + k)
        assert abs(float(th) - expected) < 1e-9, (k, float(th), expected)
        # pure bending: every node on the arc of curvature th / L (the tip moment is uniform)
        kappa = float(th) / L_M
        s = np.linspace(0.0, L_M, 4)
        arc_z = -(1.0 - np.cos(kappa * s)) / kappa
        assert np.abs(np.asarray(traj.p[-1, :, 2]) - arc_z).max() < 1e-8


@pytest.mark.slow
def test_p_controlled_moment_gradient_in_gain_is_closed_form(moment_model):
    k = 1.0
    grad = jax.grad(lambda g: settled_angle(moment_model, g, differentiable=True)[0])(
        jnp.float64(k))
    expected = TARGET * (EI_M / L_M) / (EI_M / L_M + k) ** 2
    assert abs(float(grad) - expected) < 1e-6 * expected, (float(grad), expected)


@pytest.mark.slow
def test_vmap_over_gains_equals_the_loop(moment_model):
    gains = jnp.array([0.3, 1.0, 1.5])
    batched = jax.vmap(lambda k: settled_angle(moment_model, k)[1].p)(gains)
    for i, k in enumerate(gains):
        single = settled_angle(moment_model, k)[1].p
        np.testing.assert_allclose(np.asarray(batched[i]), np.asarray(single), rtol=0,
                                   atol=1e-12)
    # and each lane settles where its gain says: the tip of the arc of angle th
    th = np.asarray(gains) * TARGET / (EI_M / L_M + np.asarray(gains))
    np.testing.assert_allclose(np.asarray(batched[:, -1, -1, 0]), np.sin(th) / th * L_M,
                               rtol=0, atol=1e-8)


def constant_moment(t, state, model, m):
    return model.replace(nodal_dead=model.nodal_dead.at[-1, 4].set(m))


def test_constant_policy_reproduces_open_loop(moment_model):
    settings = MOMENT_SETTINGS.replace(steps=20, save_every=5)
    closed = dy.simulate(moment_model, settings, control=constant_moment,
                         control_params=jnp.float64(0.3))
    opened = dy.simulate(moment_model.replace(
        nodal_dead=moment_model.nodal_dead.at[-1, 4].set(0.3)), settings)
    assert bool(closed.converged) and bool(opened.converged)
    np.testing.assert_allclose(np.asarray(closed.p), np.asarray(opened.p), rtol=0, atol=1e-13)


def test_policy_errors_name_the_field(moment_model):
    settings = MOMENT_SETTINGS.replace(steps=2, save_every=1)
    with pytest.raises(ValueError, match="nodal_dead"):
        dy.simulate(moment_model, settings, control=lambda t, s, m, p: m.replace(
            nodal_dead=m.nodal_dead[:-1]), control_params=jnp.float64(0.0))
    with pytest.raises(ValueError, match="not a Model"):
        dy.simulate(moment_model, settings, control=lambda t, s, m, p: m.nodal_dead,
                    control_params=jnp.float64(0.0))
    with pytest.raises(ValueError, match="need a control policy"):
        dy.simulate(moment_model, settings, control_params=jnp.float64(1.0))


# ----------------------------------------------------------------- PID on a tendon
L_T, EA_T, EI_T, R_T = 0.2, 50.0, 2e-4, 0.005     # m, N, N m^2, m
Z_TARGET = 0.049                                   # m, tip height to reach
TENDON_SCENE = {
    "solver": {"kind": "dynamic", "t_end": 1.0, "dt": 0.05},
    "rods": [{"name": "arm", "elements": 3, "geometry": {"kind": "straight", "length": L_T},
              "material": {"E": 1e6, "nu": 0.5, "density": 1000.0, "mass_damping": 30.0},
              "stiffness": {"EA": EA_T, "GAy": 20.0, "GAz": 20.0, "GJ": 1.5e-4,
                            "EIy": EI_T, "EIz": EI_T},
              "inertia": {"rhoA": 0.03, "rhoJ": 1e-4, "rhoIy": 1e-4, "rhoIz": 1e-4}}],
    "constraints": [{"kind": "clamp", "rod": "arm", "node": 0}],
    "tendons": [{"name": "t", "rod": "arm", "from_node": 0, "to_node": -1,
                 "offset": [0.0, R_T], "tension": 0.0}]}
DT_T, RAMP = 0.05, 1.0                             # s


def arc_height(T):
    """Tip height (m) of the arm pulled by a straight tendon at offset r with tension T:
    an arc of curvature ``T r / EI`` per reference length, axial strain ``-T / EA``."""
    kappa = T * R_T / EI_T
    return (1.0 - T / EA_T) * (1.0 - np.cos(kappa * L_T)) / kappa


def bisect(f, lo, hi):
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if f(lo) * f(mid) > 0 else (lo, mid)
    return 0.5 * (lo + hi)


def pid_policy(t, state, model, gains, integral):
    """PID on the tendon tension from the tip height error: a reference ramped to the
    target over the first ``RAMP`` s minus the height (derivative on the measurement)."""
    _, p = ctl.tip_pose(model, state, "arm")
    linear, _ = ctl.tip_velocity(model, state, "arm")
    reference = Z_TARGET * jnp.minimum(t / RAMP, 1.0)
    tension, integral = ctl.pid(gains, reference - p[2], -linear[2], integral, DT_T)
    return model.replace(tendon_tension=model.tendon_tension.at[0].set(tension)), integral


@pytest.fixture(scope="module")
def tendon_model():
    return sj.build_model(sj.Scene.from_dict(TENDON_SCENE))


def pid_run(model, gains, steps=300, differentiable=False):
    settings = dy.DynamicSettings(dt=DT_T, steps=steps, save_every=10, tolerance=1e-12)
    return dy.simulate(model, settings, control=pid_policy,
                       control_params=ctl.PIDGains(*(jnp.float64(g) for g in gains)),
                       control_memory=jnp.float64(0.0), differentiable=differentiable)


def test_pi_on_tendon_has_zero_steady_state_error(tendon_model):
    kp, ki = 2.0, 6.0
    traj = pid_run(tendon_model, (kp, ki, 0.0))
    assert bool(traj.converged), traj.message()
    z = np.asarray(traj.p[:, -1, 2])
    assert abs(z[-1] - Z_TARGET) < 1e-8, z[-1] - Z_TARGET
    assert abs(z[-2] - Z_TARGET) < 1e-8
    tension = ki * float(traj.control_memory)   # e = de/dt = 0: the integral term alone
    exact = bisect(lambda T: arc_height(T) - Z_TARGET, 1e-3, 0.3)
    assert abs(tension - exact) < 1e-6 * exact, (tension, exact)
    # the arm is the arc of that tension
    assert abs(arc_height(tension) - z[-1]) < 1e-8


def test_p_alone_on_tendon_stops_short(tendon_model):
    kp = 2.0
    traj = pid_run(tendon_model, (kp, 0.0, 0.0))
    z = float(traj.p[-1, -1, 2])
    exact = bisect(lambda T: arc_height(T) - (Z_TARGET - T / kp), 1e-4, 0.3)
    assert Z_TARGET - z > 0.02                                 # a steady-state error
    assert abs(kp * (Z_TARGET - z) - exact) < 1e-6 * exact     # where arc and law meet


@pytest.mark.slow
def test_gradient_in_pid_gains_matches_finite_differences(tendon_model):
    gains = np.array([2.0, 6.0, 0.05])
    steps = 40

    def cost(g, differentiable):
        traj = pid_run(tendon_model, tuple(g), steps, differentiable)
        return jnp.sum((traj.p[:, -1, 2] - Z_TARGET) ** 2), traj.converged

    grad = np.asarray(jax.grad(lambda g: cost(g, True)[0])(jnp.asarray(gains)))
    delta = 1e-5
    for i in range(3):
        e = np.zeros(3)
        e[i] = delta
        (plus, ok_p), (minus, ok_m) = cost(gains + e, False), cost(gains - e, False)
        assert bool(ok_p) and bool(ok_m)
        fd = (float(plus) - float(minus)) / (2 * delta)
        assert abs(fd) > 1e-8
        assert abs(grad[i] - fd) <= 1e-5 * abs(fd) + 1e-12, (i, grad[i], fd)


# ----------------------------------------------------------------- helpers
def test_tip_velocity_is_the_rate_of_the_tip_position(moment_model):
    dt = 0.002
    settings = MOMENT_SETTINGS.replace(dt=dt, steps=20, save_every=1)
    traj = dy.simulate(moment_model, settings, control=constant_moment,
                       control_params=jnp.float64(0.3))
    for n in (5, 10, 15):
        state = dy.State(traj.R[n], traj.p[n], traj.v[n], traj.v[n], traj.v[n], traj.time[n])
        linear, angular = ctl.tip_velocity(moment_model, state, "rod")
        rate = (traj.p[n + 1, -1] - traj.p[n - 1, -1]) / (2 * dt)
        assert np.linalg.norm(rate) > 1e-2
        assert np.linalg.norm(np.asarray(linear - rate)) < 1e-2 * np.linalg.norm(rate)
        th = tip_angle(traj.R[:, -1])
        th_rate = (th[n + 1] - th[n - 1]) / (2 * dt)
        assert abs(float(angular[1] - th_rate)) < 1e-2 * abs(float(th_rate))


def test_static_jacobian_is_the_arc_derivative(tendon_model):
    T0 = 0.1

    def actuate(model, u):
        return model.replace(tendon_tension=u)

    J = ctl.static_jacobian(tendon_model, actuate, jnp.array([T0]), -1,
                            sj.StaticSettings(tolerance=1e-12))
    h = 1e-6
    dz = (arc_height(T0 + h) - arc_height(T0 - h)) / (2 * h)
    assert abs(float(J[2, 0]) - dz) < 1e-6 * abs(dz)
    assert abs(float(J[1, 0])) < 1e-12


def test_task_space_pd_is_the_least_squares_command():
    J = jnp.array([[1.0, 2.0, 0.0], [0.0, 1.0, 1.0]])
    du = ctl.task_space_pd(J, jnp.array([0.2, -0.1]), jnp.array([0.0, 1.0]), 3.0, 0.5)
    demand = np.array([0.6, -0.3 + 0.5])
    np.testing.assert_allclose(np.asarray(J @ du), demand, atol=1e-14)
    np.testing.assert_allclose(np.asarray(du), np.linalg.pinv(np.asarray(J)) @ demand,
                               atol=1e-14)


@pytest.mark.slow
def test_step_jacobian_matches_finite_differences(tendon_model):
    """``d p_tip(t + dt) / d T`` of one dynamic step (implicit derivative) against central
    differences of plain steps, from a moving state (5 steps of 0.01 s under 0.02 N)."""
    settings = dy.DynamicSettings(dt=0.01, steps=5, save_every=1, tolerance=1e-12)

    def actuate(model, u):
        return model.replace(tendon_tension=u)

    state = dy.simulate(actuate(tendon_model, jnp.array([0.02])), settings).final
    J = ctl.step_jacobian(tendon_model, settings, state, actuate, jnp.array([0.03]), -1)
    one = settings.replace(steps=1)
    h = 1e-6

    def tip(u):
        return np.asarray(dy.simulate(actuate(tendon_model, jnp.array([u])), one,
                                      state).p[-1, -1])

    fd = (tip(0.03 + h) - tip(0.03 - h)) / (2 * h)
    assert np.linalg.norm(fd) > 1e-4
    np.testing.assert_allclose(np.asarray(J[:, 0]), fd, rtol=0, atol=1e-6 * np.linalg.norm(fd))
