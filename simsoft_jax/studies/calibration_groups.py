"""Calibration of sectional parameters by groups of elements, against observations
(positions, displacements, rotations of points, relative to reference cases).

A group scales one parameter of :data:`~simsoft_jax.studies.calibration.PARAMETERS` (``EIy``,
``GJ``, ``E``...) on a set of elements by ``exp(x_j)``: all elements (``EIy``), an
element range of every rod (``EIy@0-5``, or ``EIy@seg0-5``; inclusive, indices within the
rod, negative from the end) or of one rod (``EIy@wing:0-5``). Groups may carry bounds on
the scale (``EIy@0-5=0.5:2``). A small TOML file gives the same::

    [[groups]]
    param = "EIy"           # required
    rod = "wing"            # optional: every rod
    elements = [0, 5]       # optional: every element (inclusive range)
    bounds = [0.5, 2.0]     # optional: scale bounds
    prior = [1.0, 0.2]      # optional: Gaussian prior on log(scale): [scale, log std]
    name = "EIy root"       # optional label

The residual of row k is ``(predicted_k - value_k) / std_k``
(:func:`simsoft_jax.studies.measurements.read_observations`); predictions come from the static
equilibria of the scenes the rows use (solved per structure and solver settings in one
vmapped call, compiled once per layout and reused; gradients by the implicit function
theorem); the fit is projected Levenberg-Marquardt
(:func:`simsoft_jax.studies.least_squares.least_squares`) with optional Gaussian priors per group
and a smoothness prior between neighbouring groups (:func:`prior_rows`); uncertainty and
identifiability: :mod:`simsoft_jax.studies.calibration_report`.
"""
from __future__ import annotations

import math
import re
import sys
from pathlib import Path
from typing import NamedTuple, Sequence

import jax
import jax.numpy as jnp
import numpy as np

from ..math import lie
from ..math.xla import jit
from .calibration import PARAMETERS, scale_stiffness
from .calibration_report import determined, information
from .least_squares import Outcome, least_squares
from .measurements import ObservationSet
from ..solvers.statics import StaticSettings, as_traced, solve_static
from ..solvers.status import describe

_GROUP = re.compile(r"^([A-Za-z]+)(?:@(?:([A-Za-z_][\w.-]*):)?(?:seg)?(-?\d+)(?:-(-?\d+))?)?"
                    r"(?:=([^:]+):(.+))?$")


class Group(NamedTuple):
    """A parameter scaled on a set of elements: label, param (a :data:`PARAMETERS`
    name), rod (None: every rod), first/last element (inclusive, None: every element),
    bounds (lo, hi) on the scale or None, prior (scale, log_std) or None: a Gaussian
    prior on the log scale, mean ``log(scale)`` and standard deviation ``log_std``
    (e.g. ``(1.0, 0.1)``: the scenes' value, give or take 10 %)."""
    label: str
    param: str
    rod: str | None = None
    first: int | None = None
    last: int | None = None
    bounds: tuple | None = None
    prior: tuple | None = None


def _check_group(g: Group, where: str) -> Group:
    if g.param not in PARAMETERS or g.param == "viscosity":
        allowed = [p for p in PARAMETERS if p != "viscosity"]
        raise ValueError(f"{where}: unknown parameter {g.param!r} (choose from {allowed})")
    if g.bounds is not None:
        lo, hi = g.bounds
        if not (math.isfinite(lo) and math.isfinite(hi) and 0.0 < lo < hi):
            raise ValueError(f"{where}: bounds must satisfy 0 < lo < hi, got {lo}:{hi}")
    if g.prior is not None:
        if len(g.prior) != 2 or not all(isinstance(v, (int, float)) and math.isfinite(v)
                                        and v > 0 for v in g.prior):
            raise ValueError(f"{where}: prior must be [scale, log_std], both > 0, got "
                             f"{list(g.prior)}")
    return g


def parse_groups(spec: str | Sequence[str]) -> tuple[Group, ...]:
    """Groups from ``"EIy@0-5=0.5:2,GJ"`` (comma separated) or a list of such items."""
    items = [s.strip() for s in spec.split(",")] if isinstance(spec, str) else list(spec)
    out = []
    for item in filter(None, items):
        m = _GROUP.match(item)
        if not m:
            raise ValueError(f"params: cannot read group {item!r} (e.g. EIy, EIy@0-5, "
                             "EIy@wing:0-5, EIy@0-5=0.5:2)")
        param, rod, first, last, lo, hi = m.groups()
        first = None if first is None else int(first)
        last = first if (first is not None and last is None) else (
            None if last is None else int(last))
        try:
            bounds = None if lo is None else (float(lo), float(hi))
        except ValueError:
            raise ValueError(f"params: group {item!r}: bounds must be numbers lo:hi") from None
        label = item.split("=")[0]
        out.append(_check_group(Group(label, param, rod, first, last, bounds),
                                f"params: group {item!r}"))
    if not out:
        raise ValueError("params: name at least one parameter")
    return tuple(out)


def load_groups(path) -> tuple[Group, ...]:
    """Groups from a TOML file (module docstring); errors name the file and the key."""
    import tomllib
    path = Path(path)
    try:
        data = tomllib.loads(path.read_text())
    except (OSError, ValueError) as err:
        raise ValueError(f"groups: cannot read {path}: {err}") from None
    items = data.get("groups")
    if not isinstance(items, list) or not items or set(data) - {"groups"}:
        raise ValueError(f"groups: {path.name} must hold a non-empty [[groups]] array only")
    out = []
    for i, item in enumerate(items):
        where = f"groups: {path.name} groups[{i}]"
        unknown = set(item) - {"param", "rod", "elements", "bounds", "prior", "name"}
        if unknown:
            raise ValueError(f"{where}.{sorted(unknown)[0]}: unknown key (allowed: param, "
                             "rod, elements, bounds, prior, name)")
        if "param" not in item:
            raise ValueError(f"{where}.param: required key missing")
        elements = item.get("elements")
        if elements is not None and (not isinstance(elements, list) or len(elements) != 2
                                     or not all(isinstance(e, int) for e in elements)):
            raise ValueError(f"{where}.elements: must be [first, last] (integers)")
        bounds = item.get("bounds")
        if bounds is not None and (not isinstance(bounds, list) or len(bounds) != 2):
            raise ValueError(f"{where}.bounds: must be [lo, hi]")
        prior = item.get("prior")
        if prior is not None and (not isinstance(prior, list) or len(prior) != 2):
            raise ValueError(f"{where}.prior: must be [scale, log_std]")
        label = item.get("name") or item["param"] + (
            "" if elements is None else f"@{elements[0]}-{elements[1]}")
        out.append(_check_group(Group(str(label), item["param"], item.get("rod"),
                                      *(elements or (None, None)),
                                      None if bounds is None else tuple(map(float, bounds)),
                                      None if prior is None else tuple(prior)),
                                where))
    return tuple(out)


def element_masks(groups: Sequence[Group], structure) -> np.ndarray:
    """(P, E, 6) 0/1: where group j scales (elements x stiffness columns). Raises when a
    group selects nothing or two groups scale the same entry."""
    masks = np.zeros((len(groups), structure.n_elements, 6))
    for j, g in enumerate(groups):
        columns = list(PARAMETERS[g.param][1])
        for rod in structure.rods:
            if g.rod is not None and rod.name != g.rod:
                continue
            first = 0 if g.first is None else g.first % rod.elements
            last = rod.elements - 1 if g.last is None else g.last % rod.elements
            if g.first is not None and not -rod.elements <= g.first < rod.elements or (
                    g.last is not None and not -rod.elements <= g.last < rod.elements):
                raise ValueError(f"params: group {g.label!r}: rod {rod.name!r} has elements "
                                 f"0..{rod.elements - 1}")
            rows = np.arange(rod.first_element + first, rod.first_element + last + 1)
            masks[j, rows[:, None], columns] = 1.0
        if not masks[j].any():
            raise ValueError(f"params: group {g.label!r} selects no element (rods: "
                             f"{[r.name for r in structure.rods]})")
    overlap = masks.sum(axis=0) > 1
    if overlap.any():
        e, c = np.argwhere(overlap)[0]
        both = [g.label for j, g in enumerate(groups) if masks[j, e, c]]
        raise ValueError(f"params: groups {both} both scale element {e}, column {c}")
    return masks


def apply_group_scales(model, masks, x):
    """``model`` with stiffness entries scaled by ``exp(sum_j x_j masks_j)`` (masks (P,E,6))."""
    factors = jnp.exp(jnp.einsum("j,jec->ec", x, masks))
    return model.replace(stiffness=scale_stiffness(model.stiffness, factors))


def _stack(trees):
    return jax.tree.map(lambda *leaves: jnp.stack(leaves), *trees)


def _incline(R):
    """Angles (rad) of the section axes above the world x-y plane, (n,3) from R (n,3,3):
    ``asin`` of each axis's world z component."""
    return jnp.arcsin(jnp.clip(R[:, 2, :], -1.0, 1.0))


def predict_rows(rows: dict, R, p, R0, p0):
    """Predicted value (n,) of every observation row from the equilibria ``R, p``
    (sum of nodes, 3, 3)/(.., 3) of all models concatenated and their start states ``R0,
    p0``; ``rows``: per row (n,) ``node`` and ``ref_node`` (indices in the
    concatenation), ``has_ref``, ``kind``, ``component``, ``offset`` (n,3) (see
    :class:`~simsoft_jax.studies.measurements.ObservationSet`)."""
    gi, gr, has_ref, c = rows["node"], rows["ref_node"], rows["has_ref"], rows["offset"]
    Ri = R[gi]
    xi = p[gi] + jnp.einsum("nij,nj->ni", Ri, c)
    Rr = jnp.where(has_ref[:, None, None], R[gr], R0[gi])
    pr = jnp.where(has_ref[:, None], p[gr], p0[gi])
    xr = pr + jnp.einsum("nij,nj->ni", Rr, c)
    position = jnp.where(has_ref[:, None], xi - xr, xi)
    rotation = jax.vmap(lambda a, b: lie.log_so3(a.T @ b))(Rr, Ri)
    tilt = _incline(Ri) - _incline(Rr)
    values = jnp.stack([position, xi - xr, rotation, tilt], axis=1)  # (n, 4 kinds, 3)
    return values[jnp.arange(gi.shape[0]), rows["kind"], rows["component"]]


class Problem(NamedTuple):
    """An observation set and groups laid out for the compiled residual: data (a pytree
    of arrays: per pack of scenes with one structure and one set of solver settings,
    the stacked models, the group masks and the settings; the rows), order (S,) the
    scene index (in ``obs.names``) of each solved scene, in the concatenation order."""
    data: dict
    order: np.ndarray


def problem(obs: ObservationSet, groups: Sequence[Group],
            settings: StaticSettings | None = None) -> Problem:
    """Lay out ``obs`` for :func:`evaluate_problem`: the scenes grouped by structure and
    solver settings (each scene's own ``[solver]`` table, or ``settings`` for all), one
    vmapped solve per pack."""
    packs: dict = {}
    for i, model in enumerate(obs.models):
        own = obs.settings[i] if settings is None else settings
        # the pytree structure: the Structure and which optional parts are None
        packs.setdefault((jax.tree_util.tree_structure(model), own), []).append(i)
    order = np.array([i for idx in packs.values() for i in idx], int)
    sizes = np.array([obs.models[i].structure.n_nodes for i in order])
    start = np.concatenate([[0], np.cumsum(sizes)[:-1]]).astype(int)
    base = np.empty(len(obs.models), int)
    base[order] = start
    has_ref = obs.ref_model >= 0
    rows = {"node": base[obs.model] + obs.node,
            "ref_node": np.where(has_ref, base[np.maximum(obs.ref_model, 0)] + obs.ref_node, 0),
            "has_ref": has_ref, "kind": obs.kind, "component": obs.component,
            "offset": obs.offset, "value": obs.value, "std": obs.std}
    data = {"packs": tuple((_stack([obs.models[i] for i in idx]),
                            jnp.asarray(element_masks(groups, obs.models[idx[0]].structure)),
                            as_traced(own))
                           for (_, own), idx in packs.items()),
            "R0": jnp.concatenate([obs.models[i].R0 for i in order]),
            "p0": jnp.concatenate([obs.models[i].p0 for i in order]),
            "rows": {k: jnp.asarray(v) for k, v in rows.items()}}
    return Problem(data, order)


def _residuals(data, x):
    """``(r, solves)``: normalized residuals (n,) and the solves' outcome per scene."""
    R, p, solves = [], [], []
    for models, masks, own in data["packs"]:
        eq = jax.vmap(lambda m: solve_static(apply_group_scales(m, masks, x), own))(models)
        R.append(eq.R.reshape(-1, 3, 3))
        p.append(eq.p.reshape(-1, 3))
        solves.append((eq.converged, eq.status, eq.cause, eq.load_level, eq.residual_norm))
    rows = data["rows"]
    pred = predict_rows(rows, jnp.concatenate(R), jnp.concatenate(p), data["R0"], data["p0"])
    solves = tuple(jnp.concatenate(parts) for parts in zip(*solves))
    return (pred - rows["value"]) / rows["std"], solves


@jit
def _residual_program(data, x):
    return _residuals(data, x)


@jit
def _jacobian_program(data, x):
    r, tangent, solves = jax.linearize(lambda y: _residuals(data, y), x, has_aux=True)
    return r, jax.vmap(tangent, out_axes=1)(jnp.eye(x.shape[0], dtype=x.dtype)), solves


def _check_solves(prob: Problem, names: Sequence[str], solves, what: str, x):
    """Raise ``RuntimeError`` naming every scene whose solve failed, how and where."""
    converged, status, cause, level, residual = (np.asarray(a) for a in solves)
    if converged.all():
        return
    bad = [f"{names[prob.order[k]]}: " + describe("static", status[k], cause[k],
                                                   float(level[k]), float(residual[k]))
           for k in np.flatnonzero(~converged)]
    raise RuntimeError(f"{what}: {len(bad)} static solve(s) failed at scales "
                       f"{np.round(np.exp(np.clip(np.asarray(x), -700, 700)), 6).tolist()}: "
                       + "; ".join(bad))


def evaluate_problem(prob: Problem, names: Sequence[str], x, jacobian: bool = True,
                     what: str = "calibration"):
    """``(r (n,), J (n,P))`` (``J`` None unless ``jacobian``) at log scales ``x`` (P,):
    normalized residuals ``(predicted - value) / std`` and ``dr/dx`` (forward mode through
    the implicit-function derivative of every solve). The compiled programs depend only
    on the packs' structures and sizes, so later calls (another fit, a prediction, a
    subset of the same shape) reuse them. A failed solve raises ``RuntimeError`` naming
    the scene (``names`` = ``obs.names``), the status and the load level reached."""
    x = jnp.asarray(x, jnp.float64)
    if jacobian:
        r, J, solves = _jacobian_program(prob.data, x)
    else:
        (r, solves), J = _residual_program(prob.data, x), None
    _check_solves(prob, names, solves, what, x)
    return np.asarray(r), None if J is None else np.asarray(J)


def predict(obs: ObservationSet, groups: Sequence[Group], scale=None,
            settings: StaticSettings | None = None) -> np.ndarray:
    """Predicted values (n,) of the rows with the groups' scales (default 1); each
    scene solved with its own ``[solver]`` settings unless ``settings`` is given."""
    groups = tuple(groups)
    x = np.zeros(len(groups)) if scale is None else np.log(np.asarray(scale, float))
    r, _ = evaluate_problem(problem(obs, groups, settings), obs.names, x, jacobian=False,
                            what="predict")
    return r * obs.std + obs.value


EXACT = 1e-10   # every normalized residual below this: the data are reproduced (REACHED)


class GroupFit(NamedTuple):
    """Fitted groups: scale (P,), std (P,) of the scale (inf for a group the data
    cannot identify), correlation (P,P) and covariance (P,P) of the log scales
    (:mod:`simsoft_jax.studies.calibration_report`, priors included), value_range {label: (min,
    max) of the fitted parameter over the group's elements in the first model},
    residuals (n,) of the data rows normalized by std, rms of the unnormalized
    residuals, loss_history (accepted steps, 0.5 |r|^2 with the prior rows), converged
    (the minimization settled: the data reproduced or the projected gradient vanished),
    iterations, outcome (how the minimization ended, a
    :class:`~simsoft_jax.studies.least_squares.Outcome` name, or ``UNIDENTIFIED`` when it left
    combinations the data cannot determine where they stood), unidentified (labels of the
    groups the data cannot determine), message (why, "" if none), eigenvalues of the
    scaled information matrix, evaluations (solves of every scene, Jacobians included)."""
    groups: tuple
    scale: np.ndarray
    std: np.ndarray
    covariance: np.ndarray
    correlation: np.ndarray
    value_range: dict
    residuals: np.ndarray
    rms: float
    loss_history: np.ndarray
    converged: bool
    iterations: int
    outcome: str = ""
    unidentified: tuple = ()
    message: str = ""
    eigenvalues: np.ndarray | None = None
    evaluations: int = 0

    def to_dict(self) -> dict:
        """JSON-ready (``simsoft-jax predict --fitted`` reads it back)."""
        finite = lambda a: [float(v) if np.isfinite(v) else None for v in a]  # noqa: E731
        return {"groups": [g._asdict() for g in self.groups],
                "scale": self.scale.tolist(), "std_scale": finite(self.std),
                "correlation": self.correlation.tolist(),
                "covariance_log_scale": self.covariance.tolist(),
                "value_range": {k: list(v) for k, v in self.value_range.items()},
                "residuals_normalized": self.residuals.tolist(), "rms": self.rms,
                "loss_history": self.loss_history.tolist(), "converged": self.converged,
                "iterations": self.iterations, "outcome": self.outcome,
                "unidentified": list(self.unidentified), "message": self.message}


def groups_from_dict(d: dict) -> tuple[tuple[Group, ...], np.ndarray]:
    """(groups, scale) from :meth:`GroupFit.to_dict`."""
    try:
        groups = tuple(Group(**{**g, "bounds": None if g.get("bounds") is None
                                else tuple(g["bounds"]),
                                "prior": None if g.get("prior") is None
                                else tuple(g["prior"])}) for g in d["groups"])
        return groups, np.asarray(d["scale"], float)
    except (KeyError, TypeError) as err:
        raise ValueError(f"fitted: not a calibration result with groups ({err})") from None


def prior_rows(groups: Sequence[Group], smoothness: float | None = None):
    """``(A (m,P), b (m,))``: the prior residual rows ``A x - b`` on the log scales x:
    one per group with a prior, ``(x_j - log scale_j) / log_std_j``, and with
    ``smoothness`` (a log std) one per pair of neighbouring groups of the same parameter
    and rod (ordered by first element), ``(x_j - x_k) / smoothness``: a random-walk prior
    that ties per-section factors to their neighbours."""
    P = len(groups)
    A, b = [], []
    for j, g in enumerate(groups):
        if g.prior is not None:
            A.append(np.eye(P)[j] / g.prior[1])
            b.append(np.log(g.prior[0]) / g.prior[1])
    if smoothness is not None:
        if not (math.isfinite(smoothness) and smoothness > 0):
            raise ValueError(f"smoothness: must be a log std > 0, got {smoothness}")
        chains: dict = {}
        for j, g in enumerate(groups):
            if g.first is not None:
                chains.setdefault((g.param, g.rod), []).append((g.first, j))
        for chain in chains.values():
            chain.sort()
            for (_, j), (_, k) in zip(chain, chain[1:]):
                A.append((np.eye(P)[j] - np.eye(P)[k]) / smoothness)
                b.append(0.0)
    return np.reshape(A, (len(A), P)), np.asarray(b, float)


def fit_groups(obs: ObservationSet, groups: Sequence[Group], max_steps: int = 50,
               gradient_tolerance: float = 1e-8, settings: StaticSettings | None = None,
               smoothness: float | None = None, cost_tolerance: float = 1e-10) -> GroupFit:
    """Fit the groups' scales to the observations by projected Levenberg-Marquardt
    (:func:`simsoft_jax.studies.least_squares.least_squares`) within the groups' bounds, with
    their priors and the optional ``smoothness`` prior (:func:`prior_rows`). Each scene
    is solved with its own ``[solver]`` settings unless ``settings`` is given; the
    scenes of one structure and settings in one vmapped call, compiled once and reused
    by later fits and predictions of the same layout. Uncertainty and identifiability:
    :func:`simsoft_jax.studies.calibration_report.information` (the rows' std as the noise when
    the file gives them, else the residual variance); a group the data cannot determine
    is named in ``unidentified`` with a ``message``. The steps change the log scales
    only along the combinations the data (and priors) determine
    (:func:`simsoft_jax.studies.calibration_report.determined`, re-evaluated at every step; for
    rows without a std, only the combinations no prediction depends on are left out); the
    others stay where they stand (the start, the scenes' values, unless the data
    determined them earlier on the way), so that an unidentifiable group does not run off:
    such a fit ends with outcome ``UNIDENTIFIED`` and a message naming the combinations
    left undetermined. The fit ends when every normalized residual is below :data:`EXACT` (the
    data reproduced), when the gradient vanishes (``gradient_tolerance``) or when a
    Gauss-Newton step could lower the cost by less than ``cost_tolerance`` of it. A solve
    that fails at the start raises ``RuntimeError`` naming the scene; failed trial steps
    are rejected."""
    groups = tuple(groups)
    if not groups:
        raise ValueError("params: name at least one parameter")
    P = len(groups)
    lo = np.array([-np.inf if g.bounds is None else np.log(g.bounds[0]) for g in groups])
    hi = np.array([np.inf if g.bounds is None else np.log(g.bounds[1]) for g in groups])
    A, b = prior_rows(groups, smoothness)
    prob = problem(obs, groups, settings)
    history, failure = [], []

    def evaluate(U):
        try:
            r, J = evaluate_problem(prob, obs.names, U[0])
        except RuntimeError as err:
            failure.append(str(err))
            n = len(obs.value) + len(b)
            return np.full((1, n), np.nan), np.full((1, n, P), np.nan), np.array([False])
        r = np.concatenate([r, A @ U[0] - b])
        cost = 0.5 * float(r @ r)
        if not history or cost < history[-1]:
            history.append(cost)
        return r[None], np.concatenate([J, A])[None], np.array([True])

    n = len(obs.value)
    given_std = bool(np.any(obs.std != 1.0))

    # without the rows' std the noise is known only at the end: steps then leave out only
    # the combinations no prediction depends on (a misfit far from the optimum would
    # otherwise make every group look loose)
    step_noise = 1.0 if given_std else 0.0

    def subspace(U, R, Js):
        return np.stack([determined(j, step_noise)[0] for j in Js])

    x0 = np.clip(np.zeros(P), lo, hi)
    sol = least_squares(evaluate, x0[None], lo[None], hi[None],
                        lambda r: np.max(np.abs(r), axis=1), EXACT,
                        "levenberg_marquardt", max_steps, gradient_tolerance, cost_tolerance,
                        subspace=subspace)
    outcome = Outcome(int(sol.outcome[0]))
    if outcome == Outcome.SOLVE_FAILED:
        raise RuntimeError(failure[0])
    x, r, J = sol.u[0], sol.r[0], sol.J[0]
    variance = 1.0 if given_std else float(r[:n] @ r[:n]) / max(n - P, 1)
    info = information(J, variance, [g.label for g in groups])
    settled = outcome in (Outcome.REACHED, Outcome.STATIONARY)
    status = outcome.name
    frozen = determined(J, step_noise)[1]
    message = info.message
    if frozen.shape[1]:
        status = "UNIDENTIFIED"
        combos = "; ".join("(" + ", ".join(f"{v:+.2f} {g.label}" for v, g in zip(col, groups)
                                           if abs(v) > 0.1) + ")" for col in frozen.T)
        message = ((message + "; ") if message else "") + (
            f"the fit moves the log scales only along the combinations the data determine "
            f"and left {combos} where it stood when the data stopped determining it "
            f"(scales {np.round(np.exp(x), 4).tolist()}): "
            + (f"it settled in {int(sol.steps[0])} steps" if settled else
               f"{outcome.name} after {int(sol.steps[0])} steps"))
    elif info.unidentified and not settled:
        message += (f"; the minimization did not settle ({outcome.name} after "
                    f"{int(sol.steps[0])} steps) because of them: the cost keeps falling "
                    f"slowly as they run off (scales {np.round(np.exp(x), 4).tolist()})")
    scale = np.exp(x)
    model = obs.models[0]
    masks = element_masks(groups, model.structure)
    K = np.asarray(model.stiffness)
    diag = np.einsum("eii->ei", K) if K.ndim == 3 else K
    ranges = {}
    for j, g in enumerate(groups):
        cols = list(PARAMETERS[g.param][1])
        vals = diag[masks[j, :, cols[0]] > 0, cols[0]] * scale[j]
        ranges[g.label] = (float(vals.min()), float(vals.max()))
    return GroupFit(groups, scale, scale * info.std_log, info.covariance, info.correlation,
                    ranges, r[:n], float(np.sqrt(np.mean((r[:n] * obs.std) ** 2))),
                    np.asarray(history), settled,
                    int(sol.steps[0]), status, info.unidentified, message,
                    info.eigenvalues, int(sol.evaluations[0]))


def print_fit(fit: GroupFit, out=None):
    """Each group's fitted scale +- std and value range, then the correlations (to
    ``out``, default stdout)."""
    out = sys.stdout if out is None else out
    for j, g in enumerate(fit.groups):
        lo, hi = fit.value_range[g.label]
        unit = "" if g.param in ("E", "G") else f" {g.param} "
        span = (f"modulus x {fit.scale[j]:.5g}" if g.param in ("E", "G")
                else f"{lo:.6g}" + ("" if lo == hi else f" .. {hi:.6g}"))
        print(f"{g.label:>14s}: scale {fit.scale[j]:.5f} +- {fit.std[j]:.5f};{unit}"
              f"{span}", file=out)
    if len(fit.groups) > 1:
        print("correlations (log scales):", file=out)
        for j, g in enumerate(fit.groups):
            print(f"{g.label:>14s}  " + " ".join(f"{c:+.3f}" for c in fit.correlation[j]),
                  file=out)
    if fit.unidentified:
        print(f"NOT IDENTIFIED: {', '.join(fit.unidentified)}: {fit.message}", file=out)
    elif not fit.converged:
        print(f"the minimization ended without a stationary point ({fit.outcome} after "
              f"{fit.iterations} steps)", file=out)
