"""Closed-loop control helpers: what a policy of ``simulate(..., control=policy)`` reads
from a :class:`~simsoft_jax.solvers.dynamics.State` and the controllers it applies, all pure JAX
functions (usable under ``jit``, ``vmap`` and ``grad``).

* Measurements: the pose and world velocity of a node or of a rod's tip.
* Task-space Jacobians ``d p_node / d u`` of a node's position with respect to actuator
  commands ``u``, by the implicit derivative of the static solve or of one dynamic step.
* Controllers: PID on any measured quantity (the integral is the controller's memory,
  carried by ``simulate(..., control_memory=...)``) and task-space PD through a Jacobian
  (damped least squares).

A policy has the signature ``policy(t, state, model, params) -> Model`` (or, with a
memory, ``policy(t, state, model, params, memory) -> (Model, memory)``) and returns
``model.replace(...)`` with the actuated arrays (tendon tensions, chamber pressures,
nodal loads, drive tables, the magnetic field) set from the state at the step's start;
the step is solved with them (zero-order hold).
"""
from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp

from ..solvers.dynamics import DynamicSettings, State, simulate
from ..model.model import Model
from ..solvers.statics import StaticSettings, solve_static


def node_pose(state: State, node: int):
    """Rotation (3,3) (columns: the section's axes in world coordinates) and position (3,)
    m of node ``node`` of ``state``."""
    return state.R[node], state.p[node]


def node_velocity(state: State, node: int):
    """World-frame linear (3,) m/s and angular (3,) rad/s velocity of node ``node``: the
    body velocity ``v = [v_lin; omega]`` rotated by the node's frame, ``R v_lin`` and
    ``R omega`` (the nodes carry body velocities, spec algorithm.md section 4)."""
    R, v = state.R[node], state.v[node]
    return R @ v[:3], R @ v[3:]


def tip_node(model: Model, rod: str) -> int:
    """Index of the last node of ``rod`` in the model's arrays."""
    info = model.structure.rod(rod)
    return info.first_node + info.nodes - 1


def tip_pose(model: Model, state: State, rod: str):
    """Rotation (3,3) and position (3,) m of the tip (last node) of ``rod``."""
    return node_pose(state, tip_node(model, rod))


def tip_velocity(model: Model, state: State, rod: str):
    """World linear (3,) m/s and angular (3,) rad/s velocity of the tip of ``rod``."""
    return node_velocity(state, tip_node(model, rod))


def static_jacobian(model: Model, actuate, u, node: int,
                    settings: StaticSettings = StaticSettings()):
    """Task-space Jacobian ``d p_node / d u`` (3, U) of the static equilibrium under the
    commands ``u`` (U,), where ``actuate(model, u) -> Model`` sets them; by the implicit
    function theorem of the static solve (forward mode, one linear solve per command).
    NaN when the solve fails (:func:`~simsoft_jax.solvers.statics.solve_static`)."""
    return jax.jacfwd(lambda x: solve_static(actuate(model, x), settings).p[node])(
        jnp.asarray(u, jnp.float64))


def step_jacobian(model: Model, settings: DynamicSettings, state: State, actuate, u,
                  node: int):
    """Task-space Jacobian ``d p_node(t + dt) / d u`` (3, U) of one dynamic step of size
    ``settings.dt`` from ``state`` with the commands ``u`` held over it (``actuate(model,
    u) -> Model``), by the implicit derivative of the step's Newton solve (spec S66).
    NaN when the step fails."""
    one = settings.replace(steps=1, save_every=1)
    return jax.jacfwd(lambda x: simulate(actuate(model, x), one, state,
                                         differentiable="forward").p[-1, node])(
        jnp.asarray(u, jnp.float64))


class PIDGains(NamedTuple):
    """Proportional ``kp``, integral ``ki`` (per s) and derivative ``kd`` (s) gains: scalars
    or arrays broadcasting with the error (units: command per unit of error)."""
    kp: jax.Array
    ki: jax.Array
    kd: jax.Array


def pid(gains: PIDGains, error, error_rate, integral, dt):
    """PID command ``kp e + ki I + kd de/dt`` and the next integral ``I + e dt``.

    ``error`` (target minus measurement) and ``error_rate`` (its time derivative, e.g.
    from :func:`node_velocity`, so no difference quotient is needed) at the step's start;
    ``integral`` the running integral of the error up to it (the controller's memory,
    zeros at the start); ``dt`` the step (s): the rectangle rule of a zero-order hold.
    Shapes broadcast; returns ``(command, integral)``."""
    command = gains.kp * error + gains.ki * integral + gains.kd * error_rate
    return command, integral + dt * error


def task_space_pd(jacobian, error, error_rate, kp, kd, damping=0.0):
    """Task-space PD through a Jacobian: the command change ``du`` (U,) whose first-order
    effect ``J du`` is the task-space demand ``f = kp e + kd de/dt`` (K,), by damped least
    squares ``du = J^T (J J^T + damping^2 I)^-1 f`` (the minimum-norm solution for
    ``damping = 0``; a positive damping, in command units, bounds ``du`` near singular
    configurations). ``jacobian`` (K,U), e.g. :func:`static_jacobian`."""
    J = jnp.asarray(jacobian)
    demand = kp * jnp.asarray(error) + kd * jnp.asarray(error_rate)
    gram = J @ J.T + damping**2 * jnp.eye(J.shape[0], dtype=J.dtype)
    return J.T @ jnp.linalg.solve(gram, demand)
