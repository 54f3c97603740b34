"""Gradient-based calibration of sectional parameters from measured positions.

The unknowns are log scale factors ``x_j`` of sectional quantities relative to the
nominal values in the scenes (positivity by the log transform): parameter ``j`` multiplies
its columns of the stiffness diagonal ``K = [EA, GAy, GAz, GJ, EIy, EIz]`` (or of the
viscosity diagonal) of every element by ``exp(x_j)`` (:data:`PARAMETERS`).

The loss is the least-squares misfit ``0.5 * sum_k r_k^2`` of measured position
components (m); its gradient goes through the static solves by the implicit function
theorem (:func:`simsoft_jax.solve_static`) or through rollouts step by step
(:func:`simsoft_jax.simulate` with ``differentiable=True``). The minimiser is an optax
optimizer (default: L-BFGS directions with a backtracking line search). At the optimum the Gauss-Newton covariance of the
log scales is ``C = s^2 (J^T J)^-1`` with ``J = dr/dx`` (the sensitivity matrix, by forward
mode) and ``s^2 = 2 loss / (n - P)`` (or the given measurement noise variance); the
standard deviation of a fitted value ``v = v0 exp(x)`` is ``v sqrt(C_jj)`` (delta method).
"""
from __future__ import annotations

from typing import Callable, NamedTuple, Sequence

import jax
import jax.numpy as jnp
import numpy as np
import optax

from ..math.xla import jit
from ..solvers.dynamics import DynamicSettings, simulate
from ..model.model import Model
from ..solvers.statics import StaticSettings, solve_static

STIFFNESS_NAMES = ("EA", "GAy", "GAz", "GJ", "EIy", "EIz")
# parameter -> (Model field, columns it scales)
PARAMETERS = {name: ("stiffness", (i,)) for i, name in enumerate(STIFFNESS_NAMES)}
PARAMETERS.update({"E": ("stiffness", (0, 4, 5)), "G": ("stiffness", (1, 2, 3)),
                   "viscosity": ("viscosity", (0, 1, 2, 3, 4, 5))})


def check_parameters(names: Sequence[str] | str, dynamic: bool = False) -> tuple[str, ...]:
    """Validated parameter names (a list or a comma-separated string)."""
    if isinstance(names, str):
        names = [n.strip() for n in names.split(",") if n.strip()]
    names = tuple(names)
    if not names:
        raise ValueError("params: name at least one parameter")
    allowed = tuple(PARAMETERS) if dynamic else tuple(n for n in PARAMETERS if n != "viscosity")
    seen = {}
    for name in names:
        if name not in allowed:
            raise ValueError(f"params: unknown parameter {name!r} (choose from {list(allowed)})")
        field, columns = PARAMETERS[name]
        for c in columns:
            if (field, c) in seen:
                raise ValueError(f"params: {name!r} and {seen[(field, c)]!r} both scale "
                                 f"{field} column {c}")
            seen[(field, c)] = name
    return names


def apply_scales(model: Model, names: Sequence[str], log_scale) -> Model:
    """``model`` with the columns of each parameter multiplied by ``exp(log_scale[j])``.
    A ValueError names a parameter of a part the model was built without (viscosity of a
    scene without viscosity: :mod:`simsoft_jax.model.parts`)."""
    factors = {"stiffness": jnp.zeros(6), "viscosity": jnp.zeros(6)}
    for j, name in enumerate(names):
        field, columns = PARAMETERS[name]
        if getattr(model, field) is None:
            raise ValueError(f"params: {name!r}: the model was built without {field} "
                             f"(build it from a scene whose materials have {field} > 0)")
        factors[field] = factors[field].at[jnp.array(columns)].add(log_scale[j])
    changes = {"stiffness": scale_stiffness(model.stiffness, jnp.exp(factors["stiffness"]))}
    if model.viscosity is not None:
        changes["viscosity"] = model.viscosity * jnp.exp(factors["viscosity"])
    return model.replace(**changes)


def scale_stiffness(stiffness, factors):
    """Stiffness with its diagonal entries scaled by ``factors`` (6,) (or (E,6)): a
    diagonal table (E,6) times the factors; a coupled one (E,6,6) as ``S K S`` with
    ``S = diag(sqrt(factors))``, which scales each diagonal entry by its factor, each
    coupling by the geometric mean of its two, and keeps K symmetric positive definite."""
    if stiffness.ndim == 3:
        root = jnp.sqrt(factors)
        return stiffness * root[..., :, None] * root[..., None, :]
    return stiffness * factors


class Fit(NamedTuple):
    """Result of a calibration.

    params: parameter names (P,); scale (P,): fitted / nominal; values: {name: fitted
    value of the first element (N, N m^2 or N s...; for "E"/"G" the modulus scale)};
    std (P,): standard deviation of ``scale``; covariance (P, P): of the log scales;
    sensitivity (n, P): ``dr/dx``; loss_history (iterations + 1,): 0.5 sum r^2 (m^2);
    residuals (n,): simulated minus measured (m) at the optimum; rms (m); converged: the
    gradient fell below the tolerance; iterations: optimizer steps; gradient_norm: final.
    """
    params: tuple
    scale: np.ndarray
    values: dict
    std: np.ndarray
    covariance: np.ndarray
    sensitivity: np.ndarray
    loss_history: np.ndarray
    residuals: np.ndarray
    rms: float
    converged: bool
    iterations: int
    gradient_norm: float

    def to_dict(self) -> dict:
        """JSON-ready summary."""
        return {"params": list(self.params), "scale": self.scale.tolist(),
                "values": self.values, "std_scale": self.std.tolist(),
                "covariance_log_scale": self.covariance.tolist(),
                "loss_history": self.loss_history.tolist(),
                "residuals_m": self.residuals.tolist(), "rms_m": self.rms,
                "converged": self.converged, "iterations": self.iterations,
                "gradient_norm": self.gradient_norm}


def _lbfgs_descent():
    """L-BFGS descent directions (optax), scaled by the line search of :func:`minimize`."""
    return optax.chain(optax.scale_by_lbfgs(), optax.scale(-1.0))


def minimize(residual_fn: Callable, x0, optimizer=None, max_steps: int = 100,
             gradient_tolerance: float = 1e-6, noise_std: float | None = None,
             bounds=None):
    """Minimise ``0.5 |r(x)|^2`` with optax; ``residual_fn(x) -> (r (n,), ok)`` traceable.

    One compiled function returns ``r``, the sensitivity ``J = dr/dx`` (forward mode,
    P tangents through the implicit-function derivative of every solve) and ``ok``; the
    gradient is ``J^T r``. ``optimizer=None`` takes L-BFGS directions (optax
    ``scale_by_lbfgs``) with a backtracking (Armijo) line search; any other optax
    GradientTransformation (e.g. ``optax.adam(1e-2)``) is applied as it is. Stops when
    ``|grad| <= gradient_tolerance |grad_0|``, when the loss stops decreasing, or after
    ``max_steps``; a solve that fails to converge raises RuntimeError. Returns ``(x,
    loss_history, r, converged, steps, gradient_norm, covariance, J)``; converged: the
    gradient criterion was met (covariance as in the module docstring). ``bounds =
    (lo, hi)`` (P,) each: box on x (log scales); trial points are projected onto it and
    the stopping test uses the projected gradient (components pushing out of an active
    bound are dropped).
    """
    lo, hi = ((np.full(len(x0), -np.inf), np.full(len(x0), np.inf)) if bounds is None
              else (np.asarray(bounds[0], float), np.asarray(bounds[1], float)))

    def projected(x, grad):
        out = grad.copy()
        out[(x <= lo) & (grad > 0)] = 0.0
        out[(x >= hi) & (grad < 0)] = 0.0
        return out

    search = optimizer is None
    optimizer = _lbfgs_descent() if search else optimizer
    evaluate = jit(lambda x: (*residual_fn(x), jax.jacfwd(lambda y: residual_fn(y)[0])(x)))

    def loss_terms(x):
        r, ok, J = evaluate(x)
        if not bool(ok):
            raise RuntimeError(f"calibration: a solve did not converge at scales "
                               f"{np.exp(np.asarray(x)).tolist()}")
        r, J = np.asarray(r), np.asarray(J)
        return 0.5 * float(r @ r), r, J

    x = np.clip(np.asarray(x0, float), lo, hi)
    value, r, J = loss_terms(x)
    grad = J.T @ r
    g0 = max(float(np.linalg.norm(grad)), 1e-300)
    state = optimizer.init(jnp.asarray(x))
    history, steps = [value], 0
    while (steps < max_steps
           and np.linalg.norm(projected(x, grad)) > gradient_tolerance * g0):
        updates, state = optimizer.update(jnp.asarray(grad), state, jnp.asarray(x))
        updates = np.asarray(updates)
        alpha, slope = 1.0, float(grad @ updates)
        while True:
            trial = np.clip(x + alpha * updates, lo, hi)
            slope = float(grad @ (trial - x)) / alpha
            t_value, t_r, t_J = loss_terms(trial)
            if not search or t_value <= value + 1e-4 * alpha * slope or alpha < 1e-6:
                break
            alpha *= 0.5
        steps += 1
        if search and t_value > value:      # no descent left along L-BFGS directions
            break
        x, value, r, J = trial, t_value, t_r, t_J
        grad = J.T @ r
        history.append(value)
    dof = max(len(r) - len(x), 1)
    variance = noise_std ** 2 if noise_std is not None else float(r @ r) / dof
    covariance = variance * np.linalg.pinv(J.T @ J)
    gnorm = float(np.linalg.norm(projected(x, grad)))
    return (x, np.array(history), r, gnorm <= gradient_tolerance * g0, steps, gnorm,
            covariance, J)


def _make_fit(names, model: Model, result) -> Fit:
    """A :class:`Fit` from :func:`minimize`'s result; values relative to ``model``'s first
    element."""
    x, history, r, converged, steps, gnorm, covariance, J = result
    first = np.asarray(model.stiffness[0])
    nominal = {"stiffness": np.diag(first) if first.ndim == 2 else first,
               "viscosity": None if model.viscosity is None else np.asarray(model.viscosity[0])}
    scale = np.exp(x)
    std = scale * np.sqrt(np.maximum(np.diag(covariance), 0.0))
    values = {}
    for j, name in enumerate(names):
        field, columns = PARAMETERS[name]
        values[name] = (float(nominal[field][columns[0]] * scale[j]) if len(columns) == 1
                        else float(scale[j]))
    return Fit(tuple(names), scale, values, std, covariance, J, history, r,
               float(np.sqrt(np.mean(r ** 2))), converged, steps, gnorm)


class StaticTarget(NamedTuple):
    """Measured positions of one static model: nodes (M,) global node indices;
    positions (M, 3) world coordinates (m); mask (M, 3) True where measured; settings:
    the solver settings of its scene (its ``[solver]`` table,
    :func:`simsoft_jax.solvers.statics.settings_from_scene`; None: the defaults)."""
    model: Model
    nodes: np.ndarray
    positions: np.ndarray
    mask: np.ndarray
    settings: StaticSettings | None = None


def _stack(trees):
    return jax.tree.map(lambda *leaves: jnp.stack(leaves), *trees)


def static_residual_fn(targets: Sequence[StaticTarget], names: Sequence[str],
                       settings: StaticSettings | None = None):
    """``x -> (r, ok)``: simulated minus measured components (m), target by target.

    Each target is solved with its own ``settings`` (its scene's ``[solver]`` table;
    the defaults when it has none), or with ``settings`` for all when given. Targets that
    share a model structure (the Structure and which optional parts are None: the pytree
    structure) and settings are solved in one vmapped call (one compile per structure
    and integer settings); measurement rows are padded within a group and masked out.
    """
    groups: dict = {}
    for t in targets:
        own = settings if settings is not None else (
            t.settings if t.settings is not None else StaticSettings())
        groups.setdefault((jax.tree_util.tree_structure(t.model), own), []).append(t)
    packed = []
    for members in groups.values():
        rows = max(len(t.nodes) for t in members)
        nodes = np.zeros((len(members), rows), int)
        pos = np.zeros((len(members), rows, 3))
        mask = np.zeros((len(members), rows, 3), bool)
        for i, t in enumerate(members):
            nodes[i, :len(t.nodes)], pos[i, :len(t.nodes)], mask[i, :len(t.nodes)] = (
                t.nodes, t.positions, t.mask)
        packed.append((_stack([t.model for t in members]), nodes, pos, mask, own))
    # position of each target's measured components in the concatenated group vectors
    offsets, start = {}, 0
    for (_, _, _, mask, _), members in zip(packed, groups.values()):
        for i, t in enumerate(members):
            offsets[id(t)] = start + i * mask[i].size
        start += mask.size
    order = np.concatenate([offsets[id(t)] + np.flatnonzero(np.asarray(t.mask).ravel())
                            for t in targets])

    def residual_fn(x):
        parts, ok = [], jnp.array(True)
        for models, nodes, pos, _, own in packed:
            def one(model, idx, own=own):
                eq = solve_static(apply_scales(model, names, x), own)
                return eq.p[idx], eq.converged
            p, conv = jax.vmap(one)(models, jnp.asarray(nodes))
            parts.append((p - pos).ravel())
            ok = ok & jnp.all(conv)
        return jnp.concatenate(parts)[order], ok
    return residual_fn


def evaluate(targets: Sequence[StaticTarget], params, scale=None,
             settings: StaticSettings | None = None) -> np.ndarray:
    """Residuals (simulated minus measured, m) of ``targets`` with the parameters
    multiplied by ``scale`` (P,) (default 1: the scenes' values) — e.g. held-out error
    before and after a fit (``scale=fit.scale``). Each target is solved with its own
    settings unless ``settings`` is given (:func:`static_residual_fn`)."""
    names = check_parameters(params)
    x = np.zeros(len(names)) if scale is None else np.log(np.asarray(scale, float))
    r, ok = jit(static_residual_fn(targets, names, settings))(jnp.asarray(x))
    if not bool(ok):
        raise RuntimeError("calibration: a solve did not converge while evaluating targets")
    return np.asarray(r)


def fit_static(targets: Sequence[StaticTarget], params, x0=None, optimizer=None,
               max_steps: int = 100, gradient_tolerance: float = 1e-6,
               noise_std: float | None = None,
               settings: StaticSettings | None = None) -> Fit:
    """Fit ``params`` (names in :data:`PARAMETERS`) to measured static positions.

    x0: initial log scales (default 0: start from the scenes' values). The residual
    vector lists the measured components target by target, row by row (x, y, z). Each
    target is solved with its own settings (its scene's ``[solver]`` table, see
    :func:`simsoft_jax.studies.measurements.static_targets`) unless ``settings`` is given for all.
    """
    names = check_parameters(params)
    if not targets:
        raise ValueError("targets: no measurements given")
    x0 = np.zeros(len(names)) if x0 is None else np.asarray(x0, float)
    result = minimize(static_residual_fn(targets, names, settings), x0, optimizer, max_steps,
                      gradient_tolerance, noise_std)
    return _make_fit(names, targets[0].model, result)


def fit_trajectory(model: Model, settings: DynamicSettings, node: int,
                   measured, params=("viscosity",), x0=None,
                   optimizer=None, max_steps: int = 100, gradient_tolerance: float = 1e-6,
                   noise_std: float | None = None) -> Fit:
    """Fit ``params`` to a measured trajectory of one node (dynamic identification).

    measured: (T, 3) world positions (m) at the saved times of ``simulate(model,
    settings)`` (T = steps // save_every + 1, the initial state first). Gradients go
    through every step by the implicit function theorem (checkpointed rollout).
    """
    names = check_parameters(params, dynamic=True)
    measured = np.asarray(measured, float)
    expected = settings.steps // settings.save_every + 1
    if measured.shape != (expected, 3):
        raise ValueError(f"measured: expected shape ({expected}, 3) for {settings.steps} "
                         f"steps saved every {settings.save_every}, got {measured.shape}")

    def residual_fn(x):
        traj = simulate(apply_scales(model, names, x), settings, differentiable="forward")
        return (traj.p[:, node] - measured).ravel(), traj.converged

    x0 = np.zeros(len(names)) if x0 is None else np.asarray(x0, float)
    result = minimize(residual_fn, x0, optimizer, max_steps, gradient_tolerance, noise_std)
    return _make_fit(names, model, result)
