"""Trajectory optimization: an actuation time law that makes a node follow a target path.

The actuation u (P,) sets the time law through ``actuate(model, u) -> Model`` (e.g. the
values of a load channel's table profile at its knots, ``leaf_actuation(model,
[("channels.table_scale", (0, k)) for k in knots])``, :mod:`simsoft_jax.studies.actuation`). The
cost is the squared tracking error of the node over the saved states of a rollout,

    0.5 |r(u)|^2,  r = [p_node(t_k; u) - p*_k]_k,  t_k = the saved times (T states),

minimised over the box ``lower <= u <= upper`` by optax L-BFGS with a projected line
search (default) or projected Levenberg-Marquardt (:mod:`simsoft_jax.studies.least_squares`). The
Jacobian ``dr/du`` comes by forward mode through the rollout with every time step's Newton
solve differentiated by the implicit function theorem (``simulate(...,
differentiable=True)``); a rollout with a failed step has no derivative and is rejected.
"""
from __future__ import annotations

import functools
import time
from typing import Callable, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from ..math.xla import jit
from ..solvers.dynamics import DynamicSettings, simulate
from .inverse import node_indices
from .least_squares import Outcome, least_squares
from ..model.model import Model
from ..solvers.statics import as_traced


class TrackingResult(NamedTuple):
    """Result of :func:`track_path`. u (P,): time-law values found. rms_initial, rms (m):
    root-mean-square distance of the node from the path over the T saved states at u0
    and at u. improvement: rms_initial / rms. outcome:
    :class:`~simsoft_jax.studies.least_squares.Outcome` code; message: in words. iterations,
    rollouts: optimizer iterations, rollouts (each with its Jacobian). path (T,3): the
    node's positions at u (m). seconds: wall time (s, compilation included)."""
    u: np.ndarray
    rms_initial: float
    rms: float
    improvement: float
    outcome: int
    message: str
    iterations: int
    rollouts: int
    path: np.ndarray
    seconds: float


@functools.lru_cache(maxsize=8)
def tracking_residual(actuate: Callable, node: int):
    """Jitted ``(model, settings, u (P,), path (T,3)) -> (r (3T,), J (3T,P), ok, p (T,3))``:
    the node's path minus the target path over a differentiable rollout, its Jacobian by
    forward mode, and whether every step converged."""
    def residual(model, settings, u, path):
        traj = simulate(actuate(model, u), settings, differentiable="forward")
        p = traj.p[:, node]
        r = (p - path).ravel()
        return r, (r, traj.converged, p)

    def evaluate(model, settings, u, path):
        J, (r, ok, p) = jax.jacfwd(residual, argnums=2, has_aux=True)(model, settings, u,
                                                                       path)
        return r, J, ok, p

    return jit(evaluate)


def track_path(model: Model, actuate: Callable, settings: DynamicSettings, node, path, u0,
               *, lower=None, upper=None, method: str = "lbfgs", max_steps: int = 50,
               tolerance: float = 1e-8) -> TrackingResult:
    """Time-law values u that make ``node`` follow ``path`` (see the module docstring).

    model, settings: the robot and the rollout (``settings.steps // settings.save_every +
    1`` saved states, the initial one first). actuate: ``(model, u (P,)) -> Model``.
    node: an int (model-wide) or ``(rod, node)``. path: (T,3) target positions (m) at the
    saved times. u0: (P,) start values; lower, upper: (P,) bounds (default none).
    method: ``"lbfgs"`` (optax) or ``"levenberg_marquardt"``. tolerance: stop when the
    largest distance from the path is below ``tolerance`` times the rods' total length.
    ValueError naming the argument for a path of the wrong shape, an unknown node, bounds
    with lower > upper.
    """
    start = time.perf_counter()
    (idx,) = node_indices(model, [node])
    T = settings.steps // settings.save_every + 1
    path = np.asarray(path, float)
    if path.shape != (T, 3):
        raise ValueError(f"path: expected shape ({T}, 3) (one target per saved state), got "
                         f"{path.shape}")
    u0 = np.asarray(u0, float)
    P = getattr(actuate, "size", len(u0))
    if u0.shape != (P,):
        raise ValueError(f"u0: expected shape ({P},), got {u0.shape}")
    lo = np.full(P, -np.inf) if lower is None else np.asarray(lower, float)
    hi = np.full(P, np.inf) if upper is None else np.asarray(upper, float)
    for name, b in (("lower", lo), ("upper", hi)):
        if b.shape != (P,):
            raise ValueError(f"{name}: expected shape ({P},), got {b.shape}")
    if np.any(lo > hi):
        k = int(np.flatnonzero(lo > hi)[0])
        raise ValueError(f"lower: lower[{k}] = {lo[k]} exceeds upper[{k}] = {hi[k]}")
    evaluate_one = tracking_residual(actuate, idx)
    traced = as_traced(settings)

    def evaluate(U):
        out = [evaluate_one(model, traced, jnp.asarray(u), jnp.asarray(path)) for u in U]
        return tuple(np.stack([np.asarray(o[k]) for o in out]) for k in range(3))

    length = float(np.sum(np.asarray(model.length)))
    r0, _, ok0 = evaluate(u0[None])
    sol = least_squares(evaluate, u0[None], lo, hi,
                        lambda r: np.max(np.linalg.norm(r.reshape(len(r), -1, 3), axis=-1),
                                         axis=1) / length,
                        tolerance, method=method, max_steps=max_steps)
    rms = lambda r: float(np.sqrt(np.mean(np.sum(r.reshape(-1, 3) ** 2, axis=1))))  # noqa
    before, after = rms(r0[0]), rms(sol.r[0])
    outcome = Outcome(int(sol.outcome[0]))
    message = (f"{outcome.name.lower()}: tracking error (rms) {before:.3g} m -> {after:.3g} m "
               f"in {sol.steps[0]} iterations")
    if outcome == Outcome.SOLVE_FAILED:
        message = "the rollout at u0 failed (a time step did not converge); nothing was tried"
    _, _, _, p = evaluate_one(model, traced, jnp.asarray(sol.u[0]), jnp.asarray(path))
    return TrackingResult(sol.u[0], before, after, before / max(after, 1e-300), int(outcome),
                          message, int(sol.steps[0]), int(sol.evaluations[0]), np.asarray(p),
                          time.perf_counter() - start)
