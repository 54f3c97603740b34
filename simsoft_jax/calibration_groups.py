"""Calibration of sectional parameters by groups of elements, against observations
(positions, displacements, rotations of points, relative to reference cases).

A group scales one parameter of :data:`~simsoft_jax.calibration.PARAMETERS` (``EIy``,
``GJ``, ``E``...) on a set of elements by ``exp(x_j)``: all elements (``EIy``), an
element range of every rod (``EIy@0-5``, or ``EIy@seg0-5``; inclusive, indices within the
rod, negative from the end) or of one rod (``EIy@wing:0-5``). Groups may carry bounds on
the scale (``EIy@0-5=0.5:2``). A small TOML file gives the same::

    [[groups]]
    param = "EIy"           # required
    rod = "wing"            # optional: every rod
    elements = [0, 5]       # optional: every element (inclusive range)
    bounds = [0.5, 2.0]     # optional: scale bounds
    name = "EIy root"       # optional label

The residual of row k is ``(predicted_k - value_k) / std_k``
(:func:`simsoft_jax.measurements.read_observations`); predictions come from the static
equilibria of all scenes (solved per structure in one vmapped call, gradients by the
implicit function theorem); the fit is :func:`simsoft_jax.calibration.minimize`.
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

from . import lie
from ._xla import jit
from .calibration import PARAMETERS, minimize, scale_stiffness
from .measurements import ObservationSet
from .statics import StaticSettings, solve_static

_GROUP = re.compile(r"^([A-Za-z]+)(?:@(?:([A-Za-z_][\w.-]*):)?(?:seg)?(-?\d+)(?:-(-?\d+))?)?"
                    r"(?:=([^:]+):(.+))?$")


class Group(NamedTuple):
    """A parameter scaled on a set of elements: label, param (a :data:`PARAMETERS`
    name), rod (None: every rod), first/last element (inclusive, None: every element),
    bounds (lo, hi) on the scale or None."""
    label: str
    param: str
    rod: str | None = None
    first: int | None = None
    last: int | None = None
    bounds: tuple | None = None


def _check_group(g: Group, where: str) -> Group:
    if g.param not in PARAMETERS or g.param == "viscosity":
        allowed = [p for p in PARAMETERS if p != "viscosity"]
        raise ValueError(f"{where}: unknown parameter {g.param!r} (choose from {allowed})")
    if g.bounds is not None:
        lo, hi = g.bounds
        if not (math.isfinite(lo) and math.isfinite(hi) and 0.0 < lo < hi):
            raise ValueError(f"{where}: bounds must satisfy 0 < lo < hi, got {lo}:{hi}")
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
        unknown = set(item) - {"param", "rod", "elements", "bounds", "name"}
        if unknown:
            raise ValueError(f"{where}.{sorted(unknown)[0]}: unknown key (allowed: param, "
                             "rod, elements, bounds, name)")
        if "param" not in item:
            raise ValueError(f"{where}.param: required key missing")
        elements = item.get("elements")
        if elements is not None and (not isinstance(elements, list) or len(elements) != 2
                                     or not all(isinstance(e, int) for e in elements)):
            raise ValueError(f"{where}.elements: must be [first, last] (integers)")
        bounds = item.get("bounds")
        if bounds is not None and (not isinstance(bounds, list) or len(bounds) != 2):
            raise ValueError(f"{where}.bounds: must be [lo, hi]")
        label = item.get("name") or item["param"] + (
            "" if elements is None else f"@{elements[0]}-{elements[1]}")
        out.append(_check_group(Group(str(label), item["param"], item.get("rod"),
                                      *(elements or (None, None)),
                                      None if bounds is None else tuple(map(float, bounds))),
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


def predict_rows(obs: ObservationSet, R, p, R0, p0, base):
    """Predicted value (n,) of every observation row from the equilibria: ``R, p``
    (sum of nodes, 3, 3)/(.., 3) of all models concatenated, their start states ``R0,
    p0``, ``base`` (S,) the first node of each model in the concatenation."""
    base = jnp.asarray(base)
    gi = base[obs.model] + obs.node
    c = jnp.asarray(obs.offset)
    Ri = R[gi]
    xi = p[gi] + jnp.einsum("nij,nj->ni", Ri, c)
    has_ref = jnp.asarray(obs.ref_model >= 0)
    gr = base[np.maximum(obs.ref_model, 0)] + obs.ref_node
    Rr = jnp.where(has_ref[:, None, None], R[gr], R0[gi])
    pr = jnp.where(has_ref[:, None], p[gr], p0[gi])
    xr = pr + jnp.einsum("nij,nj->ni", Rr, c)
    position = jnp.where(has_ref[:, None], xi - xr, xi)
    rotation = jax.vmap(lambda a, b: lie.log_so3(a.T @ b))(Rr, Ri)
    tilt = _incline(Ri) - _incline(Rr)
    values = jnp.stack([position, xi - xr, rotation, tilt], axis=1)  # (n, 4 kinds, 3)
    n = len(obs.kind)
    return values[jnp.arange(n), obs.kind, obs.component]


def residual_fn(obs: ObservationSet, groups: Sequence[Group],
                settings: StaticSettings = StaticSettings()):
    """``x -> (r (n,), ok)`` with ``r = (predicted - value) / std`` for group log scales x."""
    by_structure: dict = {}
    for i, model in enumerate(obs.models):
        by_structure.setdefault(model.structure, []).append(i)
    packs = [(idx, _stack([obs.models[i] for i in idx]),
              jnp.asarray(element_masks(groups, structure)))
             for structure, idx in by_structure.items()]
    sizes = [m.structure.n_nodes for m in obs.models]
    base = np.concatenate([[0], np.cumsum(sizes)[:-1]]).astype(int)
    R0 = jnp.concatenate([m.R0 for m in obs.models])
    p0 = jnp.concatenate([m.p0 for m in obs.models])
    value, std = jnp.asarray(obs.value), jnp.asarray(obs.std)

    def fn(x):
        R, p, ok = [None] * len(sizes), [None] * len(sizes), jnp.array(True)
        for idx, stacked, masks in packs:
            eq = jax.vmap(lambda m: solve_static(apply_group_scales(m, masks, x), settings))(
                stacked)
            ok = ok & jnp.all(eq.converged)
            for k, i in enumerate(idx):
                R[i], p[i] = eq.R[k], eq.p[k]
        pred = predict_rows(obs, jnp.concatenate(R), jnp.concatenate(p), R0, p0, base)
        return (pred - value) / std, ok

    return fn


def predict(obs: ObservationSet, groups: Sequence[Group], scale=None,
            settings: StaticSettings = StaticSettings()) -> np.ndarray:
    """Predicted values (n,) of the rows with the groups' scales (default 1)."""
    x = np.zeros(len(groups)) if scale is None else np.log(np.asarray(scale, float))
    r, ok = jit(residual_fn(obs, groups, settings))(jnp.asarray(x))
    if not bool(ok):
        raise RuntimeError("predict: a static solve did not converge")
    return np.asarray(r) * obs.std + obs.value


class GroupFit(NamedTuple):
    """Fitted groups: scale (P,), std (P,) of the scale, correlation (P,P) of the log
    scales, covariance (P,P), value_range {label: (min, max) of the fitted parameter over
    the group's elements in the first model}, residuals (n,) normalized by std, rms of the
    unnormalized residuals, loss_history, converged, iterations."""
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

    def to_dict(self) -> dict:
        """JSON-ready (``simsoft-jax predict --fitted`` reads it back)."""
        return {"groups": [g._asdict() for g in self.groups],
                "scale": self.scale.tolist(), "std_scale": self.std.tolist(),
                "correlation": self.correlation.tolist(),
                "covariance_log_scale": self.covariance.tolist(),
                "value_range": {k: list(v) for k, v in self.value_range.items()},
                "residuals_normalized": self.residuals.tolist(), "rms": self.rms,
                "loss_history": self.loss_history.tolist(), "converged": self.converged,
                "iterations": self.iterations}


def groups_from_dict(d: dict) -> tuple[tuple[Group, ...], np.ndarray]:
    """(groups, scale) from :meth:`GroupFit.to_dict`."""
    try:
        groups = tuple(Group(**{**g, "bounds": None if g.get("bounds") is None
                                else tuple(g["bounds"])}) for g in d["groups"])
        return groups, np.asarray(d["scale"], float)
    except (KeyError, TypeError) as err:
        raise ValueError(f"fitted: not a calibration result with groups ({err})") from None


def fit_groups(obs: ObservationSet, groups: Sequence[Group], max_steps: int = 100,
               gradient_tolerance: float = 1e-8,
               settings: StaticSettings = StaticSettings()) -> GroupFit:
    """Fit the groups' scales to the observations (bounds as given). The covariance
    takes the rows' std as the noise (``(J^T J)^-1``) when the file gives them, else the
    residual variance."""
    groups = tuple(groups)
    lo = np.array([-np.inf if g.bounds is None else np.log(g.bounds[0]) for g in groups])
    hi = np.array([np.inf if g.bounds is None else np.log(g.bounds[1]) for g in groups])
    given_std = bool(np.any(obs.std != 1.0))
    x, history, r, converged, steps, _, cov, _ = minimize(
        residual_fn(obs, groups, settings), np.clip(np.zeros(len(groups)), lo, hi), None,
        max_steps, gradient_tolerance, 1.0 if given_std else None, (lo, hi))
    scale = np.exp(x)
    sd = np.sqrt(np.maximum(np.diag(cov), 0.0))
    corr = cov / np.maximum(np.outer(sd, sd), 1e-300)
    model = obs.models[0]
    masks = element_masks(groups, model.structure)
    K = np.asarray(model.stiffness)
    diag = np.einsum("eii->ei", K) if K.ndim == 3 else K
    ranges = {}
    for j, g in enumerate(groups):
        cols = list(PARAMETERS[g.param][1])
        vals = diag[masks[j, :, cols[0]] > 0, cols[0]] * scale[j]
        ranges[g.label] = (float(vals.min()), float(vals.max()))
    return GroupFit(groups, scale, scale * sd, cov, corr, ranges, np.asarray(r),
                    float(np.sqrt(np.mean((np.asarray(r) * obs.std) ** 2))),
                    np.asarray(history), bool(converged), int(steps))


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
