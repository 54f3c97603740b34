"""Batched parameter sweeps: many scenes that differ only in numbers, one compiled call.

A sweep keeps the model structure (mesh, constraints, which loads exist) and varies
arrays: loads, load angles, stiffness, gravity, time-law parameters, initial velocities.
The user states how one point of the sweep changes the model with a function
``vary(model, point) -> model`` (``point`` a dict of scalars or arrays, one entry of
each swept array), and the sweep evaluates all points in one compiled program: split
over the devices of a mesh (every CPU core with :func:`use_host_devices`, or every GPU;
:mod:`simsoft_jax.studies.sharding`), and on each device ``chunk`` points at a time with
``jax.vmap`` (``lax.map`` over the chunks). The compiled program is cached per
(structure, ``vary``, settings, chunk, devices): define ``vary`` once (a module-level
function, not a new lambda per call) to reuse it::

    def vary(model, q):                      # Princeton map: angle and load of the tip weight
        return princeton.case_model(model, q["theta"], q["load"])
    points = sweeps.grid(theta=np.linspace(0, 90, 40), load=np.linspace(2, 18, 25))
    eq = sweeps.static_sweep(model, vary, points)      # eq.p: (1000, N, 3)

Every point runs the same Newton iterations as a single solve. Static points run one
after the other on each device by default (``STATIC_CHUNK`` = 1; a larger chunk vmaps
that many; on several CPU devices only with jaxlib >= 0.11.2, see :func:`_chunk`); large
chunks use the flat continuation of
:mod:`simsoft_jax.solvers.batched` (one loop of Newton passes, so a vmapped chunk runs as long
as its longest solve, not the sum of per-level maxima). Dynamic points run one after the
other on each device by default (``DYNAMIC_CHUNK``). What was
tried and measured: benchmarks/README.md, "Batched sweeps". Several processes
(``jax.distributed``): :func:`process_share`, :func:`gather_processes`, docs/sweeps.md.
"""
from __future__ import annotations

from typing import Callable

import jax
import jax.numpy as jnp
import jaxlib
import numpy as np

from ..math.xla import jit
from ..solvers.batched import solve_static_lane
from ..solvers.dynamics import DynamicSettings, Trajectory, simulate
from ..model.model import Model
from .sharding import (batch_mesh, gather_processes, process_share, sharded_map,
                       use_host_devices)
from ..solvers.statics import Equilibrium, StaticSettings, as_traced, equilibrium, solve_static

__all__ = ["DYNAMIC_CHUNK", "FLAT_FROM", "STATIC_CHUNK", "WARM_ATTEMPTS", "WARM_ITERATIONS",
           "batch_mesh", "dynamic_sweep",
           "gather_processes", "grid", "process_share", "static_sweep", "use_host_devices"]


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


def _arrays(points: dict) -> dict:
    _batch_size(points)
    return {name: jnp.asarray(value, jnp.float64) for name, value in points.items()}


def _sharded(fn, points: dict, chunk: int, mesh):
    """``fn`` over every point: split over the devices of ``mesh``, and on each device in
    chunks of ``chunk`` points (``jax.vmap`` inside a chunk, ``lax.map`` over chunks)."""
    def per_device(share):
        if chunk == 1:
            return jax.lax.map(fn, share)
        return jax.lax.map(fn, share, batch_size=chunk)
    return sharded_map(per_device, points, mesh)


@jit(static_argnames=("vary", "chunk", "mesh"))
def _static(model, points, vary, settings, chunk, mesh):
    solve = solve_static_lane if chunk >= FLAT_FROM else equilibrium
    return _sharded(lambda q: solve(vary(model, q), settings), points, chunk, mesh)


@jit(static_argnames=("vary",))
def _static_warm(model, points, vary, settings):
    def step(start, q):
        m = vary(model, q)
        eq = solve_static(m.replace(R0=start[0], p0=start[1]), settings)
        start = (jnp.where(eq.converged, eq.R, start[0]), jnp.where(eq.converged, eq.p, start[1]))
        return start, eq
    points = {name: jnp.asarray(value, jnp.float64) for name, value in points.items()}
    return jax.lax.scan(step, (model.R0, model.p0), points)[1]


# A warm start that needs more load steps than WARM_ATTEMPTS, or more Newton steps than
# WARM_ITERATIONS at one load level, is too far from the previous point: a solve from the
# reference shape with the full continuation is cheaper than halving on (a 6-element
# strip whose tip force jumps from 2 to 8 N: 50 Newton steps before the first halving and
# 70 in all warm, 28 before giving up with 12 steps a level, 19 cold).
WARM_ATTEMPTS = 3
WARM_ITERATIONS = 12

# Points solved together (jax.vmap) on one device, chosen from measurements
# (benchmarks/README.md, "Batched sweeps"): static solves gained from small vmapped chunks
# (CPU time per scene, random Princeton cases: chunk 8 0.6x a single solve, 32: 0.68x,
# 96: 0.76x); from FLAT_FROM points per chunk on (large batches, e.g. on a GPU) the flat
# continuation of simsoft_jax.solvers.batched is used, whose cost does not grow with the chunk
# (0.72x at 8, 32 and 96). Dynamic rollouts of different scenes lose when vmapped (their
# modified-Newton matrix rebuilds and iteration counts differ per step and a vmapped batch
# pays the union: 2.4x a single rollout per scene at chunk 8), so they run one after the
# other on each device. After the loose intermediate load levels of the static solver
# (fewer, more even Newton passes per case) vmapping no longer pays for statics either:
# CPU ms per Princeton case on one device, 400 cases, load 1.3-2: chunk 1 (lax.map, one
# after the other) 3.8-3.9, chunk 4 4.5-5.9, 8 4.6-4.7, 16 6.5-7.3; flat chunk 8 4.5-4.9.
STATIC_CHUNK = 1
FLAT_FROM = 64
DYNAMIC_CHUNK = 1


# jaxlib before 0.11.2 splits a batched LAPACK call (a vmapped chunk's factorizations)
# over XLA's CPU thread pool and blocks a pool thread until the pieces are done; with one
# host device per core, every pool thread can be such a waiting call, and the process
# hangs (seen: 64 Princeton cases per chunk on two host devices; jaxlib 0.11.2 removed
# that parallel path). Vmapped chunks on several CPU devices are refused there.
_LAPACK_BATCHES_WAIT_ON_POOL = tuple(
    int(part) for part in jaxlib.__version__.split(".")[:3] if part.isdigit()) < (0, 11, 2)


def _chunk(chunk, default: int, mesh) -> int:
    """The chunk size (``default`` for None), checked against the mesh it runs on."""
    chunk = default if chunk is None else int(chunk)
    if chunk < 1:
        raise ValueError(f"chunk: must be >= 1, got {chunk}")
    devices = mesh.devices.ravel()
    if (chunk > 1 and devices.size > 1 and devices[0].platform == "cpu"
            and _LAPACK_BATCHES_WAIT_ON_POOL):
        raise ValueError(
            f"chunk: {chunk} points vmapped per chunk on {devices.size} CPU devices can "
            f"hang jaxlib {jaxlib.__version__} (its batched LAPACK calls wait on the "
            "thread pool the devices share; fixed in jaxlib 0.11.2): use chunk=1 (the "
            "default on CPU, one point after the other) or devices=1")
    return chunk


def static_sweep(model: Model, vary: Callable, points: dict,
                 settings: StaticSettings = StaticSettings(), chunk: int | None = None,
                 warm_start: bool = False, devices=None) -> Equilibrium:
    """Static equilibria of ``vary(model, point)`` for every point (one compile).

    points: ``{name: (B, ...) array}``; returns an :class:`Equilibrium` whose arrays have
    a leading batch axis ``B`` (``p`` (B, N, 3), ``converged`` (B,), ``status`` and
    ``cause`` (B,), ...): each point reports its own status, a failed point leaves the
    others untouched. The results are those of :func:`solve_static` on each point (same
    Newton iterations, to round-off), and differentiable like it.

    The points are split over ``devices`` (default: every local device, see
    :func:`simsoft_jax.studies.sharding.batch_mesh` and :func:`use_host_devices` for CPU cores)
    and solved on each device ``chunk`` at a time, vmapped (default ``STATIC_CHUNK`` = 1:
    one after the other);
    chunks of ``FLAT_FROM`` points or more use the flat continuation of
    :mod:`simsoft_jax.solvers.batched` (same results, a cost that does not grow with the chunk).

    ``warm_start=True`` solves the points one after the other (``lax.scan``), each from
    the equilibrium of the previous converged point with its full load at once
    (``load_steps=1``; a failing step is still halved by the continuation, at most
    ``WARM_ATTEMPTS`` load steps in all and ``WARM_ITERATIONS`` Newton steps per load
    step, after which the point counts as failed): a natural
    continuation along the sweep, a few Newton iterations per point when neighbouring
    points are close (order them so: :func:`grid` varies its last axis fastest). On a
    multistable problem it may follow a different branch than a solve from the
    reference shape. Points whose warm start fails are solved again from the reference
    shape (batched, ``settings`` as given). The warm path runs on one device and
    inspects ``converged`` on the host: call it outside ``jax.jit``/``jax.grad``.
    """
    points = _arrays(points)
    mesh = batch_mesh(devices)
    chunk = _chunk(chunk, STATIC_CHUNK, mesh)
    if not warm_start:
        return _static(model, points, vary, as_traced(settings), chunk, mesh)
    eq = _static_warm(model, points, vary, settings.replace(
        load_steps=1, max_attempts=WARM_ATTEMPTS,
        max_iterations=min(settings.max_iterations, WARM_ITERATIONS)))
    failed = np.flatnonzero(~np.asarray(eq.converged))
    if failed.size:       # too far from the previous point: solve those from the reference
        cold = _static(model, {name: value[failed] for name, value in points.items()},
                       vary, settings, chunk, mesh)
        eq = jax.tree.map(lambda warm, again: warm.at[failed].set(again), eq, cold)
    return eq


@jit(static_argnames=("vary", "chunk", "mesh"))
def _dynamic(model, points, vary, settings, chunk, mesh):
    return _sharded(lambda q: simulate(vary(model, q), settings), points, chunk, mesh)


def dynamic_sweep(model: Model, vary: Callable, points: dict, settings: DynamicSettings,
                  chunk: int | None = None, devices=None) -> Trajectory:
    """Rollouts of ``vary(model, point) -> model`` for every point.

    ``vary`` may change any Model array (stiffness, inertia, loads and their time-law
    parameters in ``model.channels``, initial velocities ``v0``, drive tables). Returns a
    :class:`Trajectory` with a leading batch axis ``B``: ``p`` (B, T, N, 3), ``converged``
    (B,), ``failed_at`` (B,), ``status``/``cause`` (B,); each point is the rollout
    :func:`simulate` gives alone (to round-off) and a failed point leaves the others
    untouched. The points are split over ``devices`` (as in :func:`static_sweep`) and
    run on each device ``chunk`` at a time (default ``DYNAMIC_CHUNK`` = 1: one after the
    other; a larger chunk vmaps that many rollouts, which pays when they are nearly
    identical).
    """
    points, mesh = _arrays(points), batch_mesh(devices)
    return _dynamic(model, points, vary, as_traced(settings),
                    _chunk(chunk, DYNAMIC_CHUNK, mesh), mesh)
