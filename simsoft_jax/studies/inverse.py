"""Inverse statics: actuation values that bring chosen nodes (positions, optionally frames)
to targets.

Given an actuation map ``actuate(model, u) -> Model`` (u (P,): tensions, pressures, moments,
forces, drive values; :func:`simsoft_jax.studies.actuation.leaf_actuation` builds the usual one),
:func:`solve_inverse` minimises the weighted squared target error

    0.5 |r(u)|^2,  r = [w_m (p_m(u) - p*_m) ; w_rot L_c w_m log(R*_m^T R_m(u))]_m,

over the box ``lower <= u <= upper``, where ``(R_m, p_m)`` is the static equilibrium frame
of node m (:func:`simsoft_jax.solve_static`) and ``L_c`` the model's ``char_length`` (m per
rad). The Jacobian ``dr/du`` comes by forward mode (P tangents) through the solve's
implicit-function-theorem derivative, never through Newton's iterations. The minimiser
(:mod:`simsoft_jax.studies.least_squares`) is projected Levenberg-Marquardt (default) or optax
L-BFGS with a projected line search; a batch of targets is solved together (vmapped), one
compiled program per model structure, actuation map and batch size (``chunk`` fixes the
size, so that batches of any size share one program).

The result says per target whether the target was reached (largest point error, position
in m and rotation angle times ``w_rot L_c``, at most ``tolerance`` times the rods' total
length), whether it is unreachable (the error stalled above the tolerance at a stationary
point of the cost, bounds included: the target lies out of the robot's reach or needs
actuation outside the bounds; the method is local, so a local minimum reads the same),
and whether a static solve failed (with the cause, never a silent NaN).
"""
from __future__ import annotations

import functools
import time
from typing import Callable, NamedTuple, Sequence

import jax
import jax.numpy as jnp
import numpy as np

from ..math import lie
from ..math.xla import jit
from .least_squares import Outcome, Solution, least_squares
from ..model.model import Model
from ..solvers.statics import StaticSettings, as_traced, solve_static
from ..solvers.status import describe


class InverseResult(NamedTuple):
    """Result of :func:`solve_inverse`, one row per target (B targets, P actuators).

    u (B,P): actuation found (units of the actuated arrays). error (B,): largest point
    error (m, times the node's weight; rotation targets count ``angle * rotation_weight * char_length``; NaN
    where ``solve_failed``: there is no equilibrium to measure).
    relative_error (B,): error / length. length: total reference length of the rods (m).
    reached (B,): error <= tolerance * length. unreachable (B,): not reached and the cost
    is stationary (or no step lowers it) on the box. solve_failed (B,): the static solve
    failed at the start point, so nothing was tried. outcome (B,):
    :class:`~simsoft_jax.studies.least_squares.Outcome` codes. messages: one sentence per target.
    iterations (B,), solves (B,): optimizer iterations and forward solves (each with its
    Jacobian). failed_trials (B,): trial points whose static solve failed (rejected, the
    search went on). active (B,P): bounds active at u. gradient_norm (B,): projected
    gradient of the cost at u. positions (B,M,3): node positions at u (m; NaN where
    ``solve_failed``). seconds:
    wall time of the whole batch (s, compilation included on a first call).
    """
    u: np.ndarray
    error: np.ndarray
    relative_error: np.ndarray
    length: float
    reached: np.ndarray
    unreachable: np.ndarray
    solve_failed: np.ndarray
    outcome: np.ndarray
    messages: list
    iterations: np.ndarray
    solves: np.ndarray
    failed_trials: np.ndarray
    active: np.ndarray
    gradient_norm: np.ndarray
    positions: np.ndarray
    seconds: float


def node_indices(model: Model, nodes: Sequence) -> tuple:
    """Model-wide node indices of ``nodes``: each an int (model-wide, negative from the
    end) or ``(rod_name, node)`` (negative from the rod's end). ValueError naming
    ``nodes`` for an unknown rod or a node out of range."""
    s = model.structure
    if len(nodes) == 0:
        raise ValueError("nodes: name at least one target node")
    out = []
    for k, node in enumerate(nodes):
        if isinstance(node, (tuple, list)):
            rod, i = node
            names = [r.name for r in s.rods]
            if rod not in names:
                raise ValueError(f"nodes[{k}]: unknown rod {rod!r} (rods: {names})")
            info = s.rod(rod)
            first, count = info.first_node, info.nodes
        else:
            rod, i, first, count = None, node, 0, s.n_nodes
        if not isinstance(i, (int, np.integer)) or not -count <= i < count:
            where = f"rod {rod!r}" if rod is not None else "the model"
            raise ValueError(f"nodes[{k}]: unknown node {i!r}: {where} has nodes 0..{count - 1}"
                             f" (or -{count}..-1)")
        out.append(first + int(i) % count)
    return tuple(out)


def _batch(name: str, value, shape: tuple):
    """``value`` as a float array (B, *shape), accepting one (shape) or a batch."""
    a = np.asarray(value, float)
    if a.shape == shape:
        return a[None]
    if a.ndim == len(shape) + 1 and a.shape[1:] == shape:
        return a
    raise ValueError(f"{name}: expected shape {shape} or (batch, *{shape}), got {a.shape}")


@functools.lru_cache(maxsize=16)
def target_evaluator(actuate: Callable, nodes: tuple, with_rotations: bool):
    """Jitted ``(model, settings, U, P*, R*, w, w_rot) -> (r, J, ok, status, cause,
    level, residual)`` vmapped over the batch (U, P*, R*): residuals, their Jacobians
    dr/du and the static solves' outcomes."""
    idx = np.array(nodes)

    def residual(model, settings, u, target_p, target_R, weights, w_rot):
        eq = solve_static(actuate(model, u), settings)
        parts = [(weights[:, None] * (eq.p[idx] - target_p)).ravel()]
        if with_rotations:
            rot = jax.vmap(lambda Rt, R: lie.log_so3(Rt.T @ R))(target_R, eq.R[idx])
            parts.append((w_rot * model.char_length * weights[:, None] * rot).ravel())
        r = jnp.concatenate(parts)
        return r, (r, eq.converged, eq.status, eq.cause, eq.load_level, eq.residual_norm)

    def one(model, settings, u, target_p, target_R, weights, w_rot):
        J, (r, *info) = jax.jacfwd(residual, argnums=2, has_aux=True)(
            model, settings, u, target_p, target_R, weights, w_rot)
        return (r, J, *info)

    return jit(jax.vmap(one, in_axes=(None, None, 0, 0, 0, None, None)))


def point_errors(r, points: int):
    """Largest point error (B,) from residuals r (B,n): position distances and weighted
    rotation angles of the ``points`` target nodes (weights included)."""
    parts = r.reshape(len(r), -1, points, 3)
    return np.max(np.linalg.norm(parts, axis=-1), axis=(1, 2))


def solve_inverse(model: Model, actuate: Callable, nodes: Sequence, positions, u0, *,
                  lower=None, upper=None, rotations=None, weights=None,
                  rotation_weight: float = 1.0, tolerance: float = 1e-7,
                  method: str = "levenberg_marquardt", max_steps: int = 50,
                  chunk: int | None = None,
                  settings: StaticSettings = StaticSettings()) -> InverseResult:
    """Actuation u that brings ``nodes`` to ``positions`` (and ``rotations``); see the
    module docstring for the cost, the method and what the result reports.

    model: the robot (its actuated arrays are overwritten by ``actuate``). actuate:
    ``(model, u (P,)) -> Model``, traceable and differentiable in u; its attribute
    ``size`` (P), where it has one, checks the shapes of u0 and the bounds. nodes: M
    target nodes, ints (model-wide) or ``(rod, node)``. positions: (M,3) or (B,M,3) world targets (m).
    u0: (P,) or (B,P) start values. lower, upper: (P,) bounds (default unbounded; ``-inf``
    / ``inf`` entries allowed). rotations: None or (M,3,3) / (B,M,3,3) target frames
    (columns: local axes in world coordinates). weights: (M,) per-node weights (default
    1). rotation_weight: scales ``char_length`` as the length (m) one radian counts for.
    tolerance: reached when the largest point error is at most ``tolerance`` times the
    rods' total length. method: ``"levenberg_marquardt"`` or ``"lbfgs"`` (optax).
    max_steps: optimizer iterations per target. chunk: targets per compiled batch (None:
    all B at once); with a chunk, batches of any size run as chunks of that size (the last
    padded by repeating its last target) in one compiled program. settings: of every
    static solve.

    Returns an :class:`InverseResult` (rows for a batch of B targets; B = 1 for one).
    ValueError naming the argument for bad shapes, bounds with lower > upper, an unknown
    node, or non-finite targets.
    """
    start = time.perf_counter()
    idx = node_indices(model, nodes)
    m = len(idx)
    P_t = _batch("positions", positions, (m, 3))
    B = len(P_t)
    u0 = np.asarray(u0, float)
    P = getattr(actuate, "size", u0.shape[-1] if u0.ndim else 0)
    U0 = _batch("u0", u0, (P,))
    if len(U0) not in (1, B):
        raise ValueError(f"u0: batch of {len(U0)} start values for {B} targets")
    U0 = np.broadcast_to(U0, (B, P)).copy()
    lo = _bound("lower", lower, P, -np.inf)
    hi = _bound("upper", upper, P, np.inf)
    bad = np.flatnonzero(lo > hi)
    if bad.size:
        raise ValueError(f"lower: lower[{bad[0]}] = {lo[bad[0]]} exceeds "
                         f"upper[{bad[0]}] = {hi[bad[0]]}")
    if rotations is not None:
        R_t = _batch("rotations", rotations, (m, 3, 3))
        if len(R_t) not in (1, B):
            raise ValueError(f"rotations: a batch of {len(R_t)} for {B} targets")
        R_t = np.broadcast_to(R_t, (B, m, 3, 3))
    else:
        R_t = np.broadcast_to(np.eye(3), (B, m, 3, 3))
    w = np.ones(m) if weights is None else np.asarray(weights, float)
    if w.shape != (m,) or np.any(w <= 0):
        raise ValueError(f"weights: expected {m} positive weights, got {w}")
    for name, a in (("positions", P_t), ("rotations", R_t), ("u0", U0)):
        if not np.all(np.isfinite(a)):
            raise ValueError(f"{name}: contains non-finite values")
    chunk = B if chunk is None else chunk
    if not isinstance(chunk, (int, np.integer)) or chunk < 1:
        raise ValueError(f"chunk: expected a positive int (targets per compiled batch), "
                         f"got {chunk!r}")
    evaluate_all = target_evaluator(actuate, idx, rotations is not None)
    traced = as_traced(settings)
    length = float(np.sum(np.asarray(model.length)))
    error = lambda r: point_errors(r, m)  # noqa: E731

    def solve_chunk(rows):
        """Solution and start-point solve outcomes of targets ``rows``, padded to
        ``chunk`` rows by repeating the last one (same shapes: the same program)."""
        pad = lambda a: np.concatenate([a[rows], np.repeat(a[rows][-1:],  # noqa: E731
                                                           chunk - len(a[rows]), axis=0)])
        P_c, R_c, start = pad(P_t), pad(R_t), []

        def evaluate(U):
            out = [np.asarray(x) for x in evaluate_all(
                model, traced, jnp.asarray(U), jnp.asarray(P_c), jnp.asarray(R_c),
                jnp.asarray(w), jnp.asarray(float(rotation_weight)))]
            if not start:
                start.extend(out[3:7])
            return out[:3]

        sol = least_squares(evaluate, pad(U0), lo, hi, lambda r: error(r) / length,
                            tolerance, method=method, max_steps=max_steps)
        n = len(P_t[rows])
        return [x[:n] for x in sol], [x[:n] for x in start]

    parts = [solve_chunk(slice(k, k + chunk)) for k in range(0, B, chunk)]
    sol = Solution(*(np.concatenate(x) for x in zip(*(p[0] for p in parts))))
    start_info = [np.concatenate(x) for x in zip(*(p[1] for p in parts))]
    err = np.where(sol.outcome == Outcome.SOLVE_FAILED, np.nan, error(sol.r))
    # the reached positions from the position residuals w (p - p*)
    positions_at = sol.r[:, :3 * m].reshape(B, m, 3) / w[:, None] + P_t
    positions_at[sol.outcome == Outcome.SOLVE_FAILED] = np.nan
    messages = [_message(k, sol, err, length, start_info) for k in range(B)]
    unreachable = np.isin(sol.outcome, (Outcome.STATIONARY, Outcome.STALLED))
    return InverseResult(
        u=sol.u, error=err, relative_error=err / length, length=length,
        reached=sol.outcome == Outcome.REACHED, unreachable=unreachable,
        solve_failed=sol.outcome == Outcome.SOLVE_FAILED, outcome=sol.outcome,
        messages=messages, iterations=sol.steps, solves=sol.evaluations,
        failed_trials=sol.failed_trials, active=sol.active, gradient_norm=sol.gradient_norm,
        positions=positions_at, seconds=time.perf_counter() - start)


def _bound(name: str, value, P: int, default: float):
    if value is None:
        return np.full(P, default)
    a = np.asarray(value, float)
    if a.shape != (P,):
        raise ValueError(f"{name}: expected shape ({P},) (one bound per actuator), got "
                         f"{a.shape}")
    if np.any(np.isnan(a)):
        raise ValueError(f"{name}: contains NaN")
    return a


def _message(k: int, sol, err, length: float, start_info) -> str:
    """One sentence on how target k ended."""
    outcome = Outcome(int(sol.outcome[k]))
    rel = f"error {err[k]:.3g} m ({err[k] / length:.3g} of the length)"
    if outcome == Outcome.REACHED:
        return f"reached: {rel} after {sol.steps[k]} iterations"
    if outcome == Outcome.SOLVE_FAILED:
        status, cause, level, res = (x[k] for x in start_info)
        return ("static solve failed at the start point u0: "
                + describe("static", status, cause, float(level), float(res)))
    bounds = np.flatnonzero(sol.active[k])
    why = (f" with bounds active on actuators {bounds.tolist()}" if bounds.size else "")
    if outcome == Outcome.MAX_STEPS:
        return f"not reached after {sol.steps[k]} iterations (max_steps): {rel}{why}"
    return (f"unreachable: the error stalled at {rel}{why} (projected gradient "
            f"{sol.gradient_norm[k]:.3g})")
