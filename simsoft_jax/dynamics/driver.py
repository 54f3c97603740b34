"""Host driver of long rollouts: one compiled chunk of steps, called repeatedly from
Python, with progress reports between chunks, a stop at the first failure and a clean
stop on KeyboardInterrupt (Ctrl-C) that keeps the chunks computed so far."""
from __future__ import annotations

import time

import jax
import jax.numpy as jnp

from ..model import Model
from ..statics import as_traced
from ..status import Status
from .rollout import Trajectory, _check_viscosity, _simulate, initial_state
from .scheme import DynamicSettings

_initial_state = jax.jit(initial_state)


def _chunk_saves(total_saves: int, save_every: int, target_steps: int = 200) -> int:
    """Largest divisor of ``total_saves`` whose chunk has at most ~target_steps steps."""
    limit = max(1, target_steps // save_every)
    return max(k for k in range(1, min(total_saves, limit) + 1) if total_saves % k == 0)


def compile_key(model: Model, settings: DynamicSettings):
    """What a compiled rollout depends on: the model's structure and array shapes and the
    integer settings (float settings and array values are traced)."""
    leaves, treedef = jax.tree_util.tree_flatten(model)
    return (treedef, tuple(x.shape for x in leaves), jax.tree_util.tree_structure(settings))


def step_count(t_end: float, dt: float) -> int:
    """Full steps of size ``dt`` before ``t_end``: ``floor(t_end/dt)``, rounded to the
    nearest integer when ``t_end/dt`` is within 1e-9 of one (round-off)."""
    ratio = t_end / dt
    return max(1, int(round(ratio)) if abs(ratio - round(ratio)) <= 1e-9 * ratio
               else int(ratio))


def _tail(traj: Trajectory, converged: bool) -> Trajectory:
    """The part of the closing chunk that is kept: its last saved state when it
    converged, all its saved states otherwise (the caller cuts them at the failure)."""
    return traj._replace(time=traj.time[-1:], R=traj.R[-1:], p=traj.p[-1:],
                         v=traj.v[-1:]) if converged else traj._replace(
        time=traj.time[1:], R=traj.R[1:], p=traj.p[1:], v=traj.v[1:])


def _concatenate(chunks, state) -> Trajectory:
    """One trajectory of the saved states of ``chunks``, ending with the last one's flags."""
    cat = lambda name: jnp.concatenate([getattr(c, name) for c in chunks])  # noqa: E731
    last = chunks[-1]
    return Trajectory(cat("time"), cat("R"), cat("p"), cat("v"), last.converged,
                      last.failed_at, cat("iterations"), cat("substeps"), state, last.status,
                      last.cause, last.residual)


def _interrupted(chunks, state) -> Trajectory:
    """The completed ``chunks`` of a run stopped by KeyboardInterrupt (status INTERRUPTED,
    failed_at the last saved time, residual nan)."""
    traj = _concatenate(chunks, state)
    return traj._replace(converged=jnp.asarray(False), failed_at=traj.time[-1],
                         status=jnp.asarray(int(Status.INTERRUPTED)),
                         cause=jnp.asarray(int(Status.NOT_RUN)),
                         residual=jnp.asarray(jnp.nan))


def rollout(model: Model, dt: float, t_end: float, rho_inf: float = 0.9,
            save_every: int = 1, progress=None, compiled=None,
            tolerance: float = 1e-10, max_iterations: int = 25, tangent: str = "closed_form"):
    """Run from the initial state to exactly ``t_end`` in compiled chunks of one length.

    Steps of ``dt`` (s) are taken in chunks, the state after every ``save_every``-th step
    saved. What is left before ``t_end`` when ``t_end/dt`` or ``save_every`` does not
    divide evenly (less than ``save_every`` steps of ``dt``) is covered by one more call
    of the same compiled chunk with a smaller step, ``(t_end - t)/(chunk length)``; its
    last state, at ``t_end``, is saved. So the run always ends at ``t_end`` and saves it,
    without a second compilation (the closing steps are shorter, never longer, than dt);
    the last saved time is ``t_end`` itself (the sum of the steps differs from it by
    round-off only).
    Any ``t_end``, ``dt``, ``rho_inf`` or ``tolerance`` reuses one compiled chunk for the
    same structure and chunk length; ``progress(t, t_end)`` is called after every chunk;
    the run stops at the first failed step and the returned trajectory ends there.
    A KeyboardInterrupt after the first chunk (in ``progress`` or while a chunk runs)
    stops the run too: the trajectory holds the completed chunks, with converged False,
    status ``INTERRUPTED`` and failed_at the last computed time (one during the first
    chunk is raised: nothing was computed; one after a failed chunk keeps the failure).
    ``compiled`` may be a dict used as a cache of compiled chunks.
    Returns ``(Trajectory, compile_seconds)`` with all saved states concatenated.
    """
    _check_viscosity(model)
    if not 0.0 < dt <= t_end:
        raise ValueError(f"solver.dt: must be in (0, t_end = {t_end:g}], got {dt:g}")
    steps = step_count(t_end, dt)
    save_every = min(save_every, steps)
    total_saves = steps // save_every
    per_chunk = _chunk_saves(total_saves, save_every)
    chunk_steps = per_chunk * save_every
    settings = as_traced(DynamicSettings(
        dt=float(dt), steps=chunk_steps, rho_inf=float(rho_inf),
        save_every=save_every, tolerance=float(tolerance), max_iterations=int(max_iterations),
        tangent=tangent))
    compiled = {} if compiled is None else compiled
    key = compile_key(model, settings)
    start = time.perf_counter()
    state = jax.block_until_ready(_initial_state(model))
    if key not in compiled:
        compiled[key] = _simulate.lower(model, settings, state).compile()
    compile_seconds = time.perf_counter() - start
    chunks = []
    try:
        for _ in range(total_saves // per_chunk):
            traj = compiled[key](model, settings, state)
            chunks.append(traj if not chunks else traj._replace(
                time=traj.time[1:], R=traj.R[1:], p=traj.p[1:], v=traj.v[1:]))
            state = traj.final
            if progress is not None:
                progress(float(state.t), t_end)
            if not bool(traj.converged):
                break
        remaining = t_end - float(state.t)  # exact for t in [t_end/2, 2 t_end] (Sterbenz)
        if bool(chunks[-1].converged) and remaining > 1e-9 * dt:
            closing = settings.replace(dt=jnp.asarray(remaining / chunk_steps, jnp.float64))
            traj = compiled[key](model, closing, state)
            chunks.append(_tail(traj, bool(traj.converged)))
            state = traj.final
            if progress is not None:
                progress(float(state.t), t_end)
    except KeyboardInterrupt:
        if not chunks:
            raise
        if bool(chunks[-1].converged):
            return _interrupted(chunks, state), compile_seconds
    last = chunks[-1]
    traj = _concatenate(chunks, state)
    if bool(last.converged) and abs(float(traj.time[-1]) - t_end) <= 1e-9 * dt:
        traj = traj._replace(time=traj.time.at[-1].set(t_end))  # round-off of the sum of h
    if not bool(last.converged):  # saved states after the failure repeat the last good one
        keep = int(jnp.searchsorted(traj.time, last.failed_at, side="left")) + 1
        traj = traj._replace(time=traj.time[:keep], R=traj.R[:keep], p=traj.p[:keep],
                             v=traj.v[:keep])
    return traj, compile_seconds
