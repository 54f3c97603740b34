"""Batched parameter sweeps: many scenes that differ only in numbers, one compiled call.

A sweep keeps the model structure (mesh, constraints, which loads exist) and varies
arrays: loads, load angles, stiffness, gravity, time-law parameters, initial velocities.
The user states how one point of the sweep changes the model with a function
``vary(model, point) -> model`` (``point`` a dict of scalars or arrays, one entry of
each swept array), and the sweep evaluates all points with ``jax.vmap`` (in chunks of
``chunk`` points with :func:`jax.lax.map` to bound memory). The compiled program is cached
per (structure, ``vary``, settings): define ``vary`` once (a module-level function, not a
new lambda per call) to reuse it::

    def vary(model, q):                      # Princeton map: angle and load of the tip weight
        return princeton.case_model(model, q["theta"], q["load"])
    points = sweeps.grid(theta=np.linspace(0, 90, 40), load=np.linspace(2, 18, 25))
    eq = sweeps.static_sweep(model, vary, points)      # eq.p: (1000, N, 3)

Every point runs the same Newton iterations as a single solve (a vmapped while-loop
runs until the slowest point has converged; converged points are left unchanged).
"""
from __future__ import annotations

from typing import Callable

import jax
import jax.numpy as jnp
import numpy as np

from ._xla import jit
from .dynamics import DynamicSettings, Trajectory, simulate
from .model import Model
from .statics import Equilibrium, StaticSettings, solve_static


def grid(**axes) -> dict:
    """Cartesian product of named 1-D axes, flattened: ``{name: (prod of lengths,)}``.

    The first axis varies slowest (``numpy.meshgrid(..., indexing="ij")`` order), so a
    result of the sweep reshapes to ``(len(axis_1), len(axis_2), ...)``.
    """
    if not axes:
        raise ValueError("grid: give at least one named axis")
    values = []
    for name, axis in axes.items():
        axis = np.asarray(axis, float)
        if axis.ndim != 1 or axis.size == 0:
            raise ValueError(f"grid: axis {name!r} must be a non-empty 1-D array, got shape {axis.shape}")
        values.append(axis)
    meshes = np.meshgrid(*values, indexing="ij")
    return {name: mesh.ravel() for name, mesh in zip(axes, meshes)}


def _batch_size(points: dict) -> int:
    if not isinstance(points, dict) or not points:
        raise ValueError("points: need a non-empty dict of arrays with a leading batch axis")
    sizes = {name: np.shape(value)[0] if np.ndim(value) else None for name, value in points.items()}
    bad = [name for name, size in sizes.items() if size is None]
    if bad:
        raise ValueError(f"points: {bad[0]!r} has no leading batch axis (a scalar)")
    if len(set(sizes.values())) != 1:
        raise ValueError(f"points: every array needs the same leading length, got {sizes}")
    return next(iter(sizes.values()))


def _map(fn, points: dict, chunk: int | None):
    size = _batch_size(points)
    points = {name: jnp.asarray(value, jnp.float64) for name, value in points.items()}
    if chunk is None or chunk >= size:
        return jax.vmap(fn)(points)
    return jax.lax.map(fn, points, batch_size=int(chunk))


@jit(static_argnames=("vary", "chunk"))
def _static(model, points, vary, settings, chunk):
    return _map(lambda q: solve_static(vary(model, q), settings), points, chunk)


@jit(static_argnames=("vary",))
def _static_warm(model, points, vary, settings):
    def step(start, q):
        m = vary(model, q)
        eq = solve_static(m.replace(R0=start[0], p0=start[1]), settings)
        start = (jnp.where(eq.converged, eq.R, start[0]), jnp.where(eq.converged, eq.p, start[1]))
        return start, eq
    points = {name: jnp.asarray(value, jnp.float64) for name, value in points.items()}
    return jax.lax.scan(step, (model.R0, model.p0), points)[1]


# A warm start that needs more load steps than this is too far from the previous point: a
# solve from the reference shape with the full continuation is cheaper than halving on.
WARM_ATTEMPTS = 3


def static_sweep(model: Model, vary: Callable, points: dict,
                 settings: StaticSettings = StaticSettings(), chunk: int | None = None,
                 warm_start: bool = False) -> Equilibrium:
    """Static equilibria of ``vary(model, point)`` for every point (one compile).

    points: ``{name: (B, ...) array}``; returns an :class:`Equilibrium` whose arrays have
    a leading batch axis ``B`` (``p`` (B, N, 3), ``converged`` (B,), ...). Differentiable
    like :func:`solve_static`.

    ``warm_start=True`` solves the points one after the other (``lax.scan``), each from
    the equilibrium of the previous converged point with its full load at once
    (``load_steps=1``; a failing step is still halved by the continuation, at most
    ``WARM_ATTEMPTS`` load steps in all, after which the point counts as failed): a natural
    continuation along the sweep, a few Newton iterations per point when neighbouring
    points are close (order them so: :func:`grid` varies its last axis fastest). On a
    multistable problem it may follow a different branch than a solve from the
    reference shape. Points whose warm start fails are solved again from the reference
    shape (vmapped, ``settings`` as given; ``chunk`` applies to them). The warm path
    inspects ``converged`` on the host: call it outside ``jax.jit``/``jax.grad`` (the
    vmapped default is the differentiable one).
    """
    _batch_size(points)
    if not warm_start:
        return _static(model, points, vary, settings, chunk)
    eq = _static_warm(model, points, vary,
                      settings.replace(load_steps=1, max_attempts=WARM_ATTEMPTS))
    failed = np.flatnonzero(~np.asarray(eq.converged))
    if failed.size:       # too far from the previous point: solve those from the reference
        cold = _static(model, {name: np.asarray(value)[failed] for name, value in points.items()},
                       vary, settings, chunk)
        eq = jax.tree.map(lambda warm, again: warm.at[failed].set(again), eq, cold)
    return eq


@jit(static_argnames=("vary", "chunk"))
def _dynamic(model, points, vary, settings, chunk):
    return _map(lambda q: simulate(vary(model, q), settings), points, chunk)


def dynamic_sweep(model: Model, vary: Callable, points: dict, settings: DynamicSettings,
                  chunk: int | None = None) -> Trajectory:
    """Rollouts of ``vary(model, point) -> model`` for every point.

    ``vary`` may change any Model array (stiffness, inertia, loads and their time-law
    parameters in ``model.channels``, initial velocities ``v0``, drive tables). Returns a
    :class:`Trajectory` with a leading batch axis ``B``: ``p`` (B, T, N, 3), ``converged``
    (B,), ``failed_at`` (B,).
    """
    _batch_size(points)
    return _dynamic(model, points, vary, settings, chunk)
