"""The Princeton beam experiment (the paper's "Experimental validation"; spec algorithm.md §7.1).

An Al 7075 strip (L = 0.508 m, b = 3.2024 mm along local y, h = 12.377 mm along local z)
is clamped with its root pitched by ``theta`` about the beam axis; a weight hangs from the
tip and gravity acts on the beam. Both are vertical in the laboratory, so in the root
section's axes (the frame this module works in: beam along +x, the unpitched section
axes y, z) they point along ``(0, -sin theta, -cos theta)``:

* theta = 0 loads the stiff direction (edgewise, ``EI_y``: motion in x-z);
* theta = 90 deg loads the flexible direction (flapwise, ``EI_z``: motion in x-y).

The paper's 25 load cases (f0 = 4.448 N = 1 lbf) are :data:`LOAD_CASES`. Deflections are the
displacements ``(y, z)`` of the centroid at stations ``r_i`` along the beam, in the root
section's axes, either absolute or relative to the self-weight state (the paper does not say
which one the experiment reports; spec §7.1). All cases are solved in one compiled,
vmapped call (:func:`replay`).

Error measure (the paper's eq. 112): ``e_i = (|y(r_i) - y_ei| + |z(r_i) - z_ei|) / r_i * 100 %``;
per case ``e_mu`` and ``e_sigma`` are the mean and standard deviation of the four ``e_i`` and
the tip error is ``e_i`` at ``r = L`` (:func:`errors`).

Measured data are read by :func:`read_measurements` from a CSV file with the columns

    theta_deg, load_N, station_m, y_m, z_m [, y_neg_theta_m, z_neg_theta_m]

(header required, one row per case and station, deflections in metres in the root
section's axes). ``y_m, z_m`` are the deflections measured with the root pitched by
+theta. The optional ``*_neg_theta_m`` columns are the raw deflections measured at -theta,
each in that run's own root axes; the -theta set-up is the mirror image (y -> -y) of the
+theta one, so the averaged deflections used by eq. (112) are
``y_e = (y - y_neg) / 2`` and ``z_e = (z + z_neg) / 2`` (the paper's "averaged experimental
deflections"; its Fig. 15 shows both signs).
"""
from __future__ import annotations

import csv
from pathlib import Path
from typing import NamedTuple, Sequence

import jax
import jax.numpy as jnp
import numpy as np

from ..analysis import kinematics
from ..model.model import Model, build_model
from ..scene.scene import Scene
from ..solvers.statics import StaticSettings
from ..studies.sweeps import grid, static_sweep

LENGTH = 0.508             # m (20 in)
WIDTH = 3.2024e-3          # m, b, along local y
HEIGHT = 12.377e-3         # m, h, along local z
SHEAR_COEFFICIENTS = (0.590, 0.833)   # k_y, k_z (the paper's eq. 110, its ref. 60)
F0 = 4.448                 # N (1 lbf)
GRAVITY = 9.81             # m/s^2
DEFAULT_STATIONS = (0.25, 0.5, 0.75, 1.0)   # r_i / L (spec §7.1: not stated in the paper)

# (theta in degrees, load in units of f0): theta = 0, 15, 30: f0..4 f0; 45: f0..3 f0;
# 60: f0/2..2 f0; 75, 90: f0/2..3/2 f0 (the paper's "Experimental setup"; 25 cases)
LOAD_CASES = tuple(
    [(th, k) for th in (0.0, 15.0, 30.0) for k in (1.0, 2.0, 3.0, 4.0)]
    + [(45.0, k) for k in (1.0, 2.0, 3.0)]
    + [(60.0, k) for k in (0.5, 1.0, 1.5, 2.0)]
    + [(th, k) for th in (75.0, 90.0) for k in (0.5, 1.0, 1.5)])


def seed_cases() -> tuple[np.ndarray, np.ndarray]:
    """The paper's 25 load cases: ``(theta_deg (25,), load_N (25,))``."""
    cases = np.array(LOAD_CASES)
    return cases[:, 0], cases[:, 1] * F0


def scene(elements: int = 16, gravity: bool = True, stiffness=None) -> Scene:
    """The beam in its root section's axes with a placeholder tip force.

    ``stiffness``: optional ``[EA, GAy, GAz, GJ, EIy, EIz]`` replacing the paper's section
    values (eq. 110, from the rectangle, Al 7075 and k = (0.590, 0.833)). The load and
    gravity directions of a case are set by :func:`case_model`, so one compiled solver
    serves every case.
    """
    rod = {"name": "beam", "material": "aluminum_7075",
           "section": {"shape": "rectangle", "width": WIDTH, "height": HEIGHT},
           "shear_coefficients": list(SHEAR_COEFFICIENTS), "elements": int(elements),
           "geometry": {"kind": "straight", "length": LENGTH}}
    if stiffness is not None:
        names = ("EA", "GAy", "GAz", "GJ", "EIy", "EIz")
        rod["stiffness"] = dict(zip(names, map(float, np.asarray(stiffness, float))))
    data = {"name": "princeton", "solver": {"kind": "static"},
            "rods": [rod], "constraints": [{"kind": "clamp", "rod": "beam", "node": 0}],
            "loads": [{"kind": "force", "rod": "beam", "node": -1,
                       "vector": [0.0, 0.0, -1.0], "frame": "world"}]}
    if gravity:
        data["gravity"] = {"vector": [0.0, 0.0, -GRAVITY]}
    return Scene.from_dict(data)


def case_model(model: Model, theta_deg, load_N) -> Model:
    """``model`` with the tip weight ``load_N`` (N) and gravity of the pitch ``theta_deg``
    (gravity only when the model was built with it, :func:`scene`).

    Both act along ``(0, -sin theta, -cos theta)`` in the root section's axes (module
    docstring). Traceable: ``theta_deg`` and ``load_N`` may be batched with ``jax.vmap``.
    """
    th = jnp.deg2rad(jnp.asarray(theta_deg, jnp.float64))
    down = jnp.stack([0.0 * th, -jnp.sin(th), -jnp.cos(th)])
    nodal = jnp.zeros_like(model.nodal_dead).at[-1, :3].set(load_N * down)
    if model.gravity is None:
        return model.replace(nodal_dead=nodal)
    return model.replace(nodal_dead=nodal, gravity=GRAVITY * down)


def station_locations(model: Model, stations_m) -> tuple[np.ndarray, np.ndarray]:
    """Element index and fraction of each station (m along the reference centreline)."""
    stations = np.asarray(stations_m, float)
    ends = np.cumsum(np.asarray(model.length))
    if np.any(stations <= 0.0) or np.any(stations > ends[-1] * (1 + 1e-12)):
        raise ValueError(f"stations: must lie in (0, {ends[-1]:.6g}] m, got {stations.tolist()}")
    index = np.minimum(np.searchsorted(ends, stations * (1 - 1e-12)), len(ends) - 1)
    starts = np.concatenate([[0.0], ends[:-1]])
    return index, (stations - starts[index]) / np.asarray(model.length)[index]


def station_deflections(R, p, index, fraction):
    """Centroid displacement ``(y, z)`` (m) at stations given by :func:`station_locations`.

    ``index`` (S,) element of each station, ``fraction`` (S,) position in it; the centroid
    follows the element's helix (the paper's eq. 27), the reference centroid is ``(r, 0, 0)``
    (root at the origin). Returns shape ``(S, 2)``.
    """
    index = np.asarray(index)
    d = kinematics.element_twists(R, p)[index]
    _, ps = jax.vmap(kinematics.frame_in_element)(R[index], p[index], d, jnp.asarray(fraction))
    return ps[:, 1:]


class Replay(NamedTuple):
    """Simulated Princeton deflections. theta_deg, load_N (C,); stations_m (S,);
    deflection (C, S, 2): (y, z) in m; converged (C,) bool; iterations (C,) Newton
    iterations; relative: deflections measured from the self-weight state."""
    theta_deg: np.ndarray
    load_N: np.ndarray
    stations_m: np.ndarray
    deflection: np.ndarray
    converged: np.ndarray
    iterations: np.ndarray
    relative: bool


# The solver settings of the load cases: increments may grow to the whole load
# (``max_load_step=1``), so an easy case takes fewer than ``load_steps`` levels. The first
# increment is a quarter of the load, a level is given up (and its increment halved)
# after 15 Newton steps, and the intermediate levels, which only start the next one, are
# solved to 0.1 of the load scale (one Newton step each, mostly; the last level is solved
# to ``tolerance`` as always). 1000 random cases: 3 levels and 10.6 Newton steps per case
# instead of 5 and 14.4, about 30 % less time, all converged, the equilibria within
# 3e-13 m of a solve at tolerance 1e-13 (benchmarks/README.md, "Fewer load levels for
# the Princeton cases").
CASE_SETTINGS = StaticSettings(max_load_step=1.0, load_steps=4, max_iterations=15,
                               level_tolerance=0.1)


def _vary_case(model: Model, point: dict) -> Model:
    """A sweep point ``{"theta": deg, "load": N}`` applied by :func:`case_model`."""
    return case_model(model, point["theta"], point["load"])


def replay(theta_deg=None, load_N=None, elements: int = 16, gravity: bool = True,
           relative: bool = False, stations=DEFAULT_STATIONS, stiffness=None,
           settings: StaticSettings = CASE_SETTINGS, chunk: int | None = None,
           warm_start: bool = False) -> Replay:
    """Solve the load cases in one compiled call (one compile per batch size).

    theta_deg, load_N: (C,) arrays (default: the paper's 25 cases, :func:`seed_cases`).
    stations: r_i / L (default 0.25, 0.5, 0.75, 1). relative: subtract the self-weight
    deflection of each angle (needs ``gravity``; the self-weight states are solved in
    the same call). stiffness: optional section diagonal (see :func:`scene`). chunk,
    warm_start: as in :func:`simsoft_jax.studies.sweeps.static_sweep` (default: the cases one
    after the other on every local device; ``warm_start`` solves them in the given
    order, each from the previous equilibrium).
    """
    if theta_deg is None and load_N is None:
        theta_deg, load_N = seed_cases()
    if theta_deg is None or load_N is None:
        raise ValueError("theta_deg, load_N: give both or neither")
    theta = np.atleast_1d(np.asarray(theta_deg, float))
    load = np.atleast_1d(np.asarray(load_N, float))
    if theta.shape != load.shape or theta.ndim != 1:
        raise ValueError(f"theta_deg, load_N: need equal 1-D shapes, got {theta.shape} and {load.shape}")
    if relative and not gravity:
        raise ValueError("relative: deflections relative to the self-weight need gravity=True")
    stations_m = np.asarray(stations, float) * LENGTH
    model = build_model(scene(elements, gravity, stiffness))
    index, fraction = station_locations(model, stations_m)
    angles = np.unique(theta) if relative else np.zeros(0)
    theta_all = np.concatenate([theta, angles])
    load_all = np.concatenate([load, np.zeros_like(angles)])
    # vmapped: pad the batch to a power of two (repeating the last case), fewer compiles
    pad = 0 if warm_start else (1 << (len(theta_all) - 1).bit_length()) - len(theta_all)
    points = {"theta": np.pad(theta_all, (0, pad), mode="edge"),
              "load": np.pad(load_all, (0, pad), mode="edge")}
    eq = static_sweep(model, _vary_case, points, settings, chunk, warm_start)
    defl = np.asarray(jax.vmap(station_deflections, in_axes=(0, 0, None, None))(
        eq.R, eq.p, index, fraction))
    ok, its = np.asarray(eq.converged), np.asarray(eq.iterations)
    C = len(theta)
    out, ok = defl[:C], ok[:C]
    if relative:
        weight = C + np.searchsorted(angles, theta)
        out, ok = out - defl[weight], ok & np.asarray(eq.converged)[weight]
    return Replay(theta, load, stations_m, out, ok, its[:C], relative)


class Measurements(NamedTuple):
    """Measured (averaged) Princeton deflections: theta_deg, load_N, station_m (rows,);
    deflection (rows, 2): (y_e, z_e) in m."""
    theta_deg: np.ndarray
    load_N: np.ndarray
    station_m: np.ndarray
    deflection: np.ndarray


_REQUIRED = ("theta_deg", "load_N", "station_m", "y_m", "z_m")
_MIRRORED = ("y_neg_theta_m", "z_neg_theta_m")


def read_measurements(path) -> Measurements:
    """Read a measured-deflection CSV (layout in the module docstring)."""
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"measurements: no such file {str(path)!r}")
    with path.open(newline="") as handle:
        reader = csv.DictReader(handle)
        columns = reader.fieldnames or []
        missing = [c for c in _REQUIRED if c not in columns]
        if missing:
            raise ValueError(f"measurements: {path.name} lacks column(s) {missing} "
                             f"(need {list(_REQUIRED)}, optional {list(_MIRRORED)})")
        mirrored = [c for c in _MIRRORED if c in columns]
        if len(mirrored) == 1:
            raise ValueError(f"measurements: {path.name} has {mirrored[0]} without its partner")
        rows = []
        for line, row in enumerate(reader, start=2):
            values = []
            for key in _REQUIRED + tuple(mirrored):
                try:
                    value = float(row[key])
                except (TypeError, ValueError):
                    raise ValueError(f"measurements: {path.name} line {line}, column {key}: "
                                     f"not a number: {row[key]!r}") from None
                if not np.isfinite(value):
                    raise ValueError(f"measurements: {path.name} line {line}, column {key}: "
                                     f"not finite")
                values.append(value)
            if values[2] <= 0.0 or values[2] > LENGTH * (1 + 1e-9):
                raise ValueError(f"measurements: {path.name} line {line}, column station_m: "
                                 f"{values[2]} is not in (0, {LENGTH}]")
            rows.append(values)
    if not rows:
        raise ValueError(f"measurements: {path.name} has no data rows")
    data = np.array(rows)
    y, z = data[:, 3], data[:, 4]
    if mirrored:
        y, z = 0.5 * (y - data[:, 5]), 0.5 * (z + data[:, 6])
    return Measurements(data[:, 0], data[:, 1], data[:, 2], np.stack([y, z], axis=1))


def read_published_tip(path, source_prefix: str = "ANSYS_solid") -> Measurements:
    """Tip deflections of a published model as Princeton measurements at ``r = L``.

    path: ``data_path("princeton", "model_predictions_tip.csv")`` (:mod:`simsoft_jax.data_files`) (its README: model output,
    no gravity, dead tip force, unsigned flap and edge deflections); rows whose
    ``source_id`` starts with ``source_prefix``. The flap deflection becomes ``-y`` and
    the edge deflection ``-z`` (the loads of :func:`case_model` point along
    ``(0, -sin theta, -cos theta)``).
    """
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"path: no such file {str(path)!r}")
    with path.open(newline="") as handle:
        rows = [r for r in csv.DictReader(handle)
                if r.get("source_id", "").startswith(source_prefix)]
    if not rows:
        raise ValueError(f"source_prefix: no rows of {path.name} start with {source_prefix!r}")
    theta = np.array([float(r["theta_deg"]) for r in rows])
    load = np.array([float(r["load_N"]) for r in rows])
    defl = -np.array([[float(r["flap_deflection_m"]), float(r["edge_deflection_m"])] for r in rows])
    return Measurements(theta, load, np.full(len(rows), LENGTH), defl)


def calibration_targets(measured: Measurements, model: Model) -> list:
    """One :class:`~simsoft_jax.studies.calibration.StaticTarget` per measured case of ``model``
    (built by :func:`scene`): the (y, z) deflections at the stations, which must be
    nodes; x is not measured."""
    from ..studies.calibration import StaticTarget
    ends = np.concatenate([[0.0], np.cumsum(np.asarray(model.length))])
    cases, stations, table = _case_table(measured)
    nodes = np.array([int(np.argmin(np.abs(ends - r))) for r in stations])
    off = np.abs(ends[nodes] - stations) > 1e-9 * LENGTH
    if off.any():
        raise ValueError(f"stations: {stations[off].tolist()} m are not nodes of the "
                         f"{len(ends) - 1}-element mesh")
    mask = np.tile([False, True, True], (len(nodes), 1))
    return [StaticTarget(case_model(model, th, f), nodes,
                         np.concatenate([np.zeros((len(nodes), 1)), table[c]], axis=1), mask)
            for c, (th, f) in enumerate(cases)]


class Errors(NamedTuple):
    """The paper's eq. (112) per load case. theta_deg, load_N (C,); stations_m (S,);
    e (C, S) in %; e_mu, e_sigma, tip (C,) in %; by_angle: {theta: (mean of e_mu,
    std of e_mu, mean tip error, std of tip errors)} (Figs. 17-18); replay: the
    simulated deflections at the measured cases and stations; measured (C, S, 2)."""
    theta_deg: np.ndarray
    load_N: np.ndarray
    stations_m: np.ndarray
    e: np.ndarray
    e_mu: np.ndarray
    e_sigma: np.ndarray
    tip: np.ndarray
    by_angle: dict
    replay: Replay
    measured: np.ndarray


def _case_table(measured: Measurements):
    """Cases (theta, load) and stations of the measurements, and the (C, S, 2) table."""
    keys = np.round(np.stack([measured.theta_deg, measured.load_N], axis=1), 9)
    cases, case_of = np.unique(keys, axis=0, return_inverse=True)
    stations, station_of = np.unique(np.round(measured.station_m, 12), return_inverse=True)
    table = np.full((len(cases), len(stations), 2), np.nan)
    table[case_of.ravel(), station_of.ravel()] = measured.deflection
    if np.isnan(table).any():
        c, s = np.argwhere(np.isnan(table[..., 0]))[0]
        raise ValueError(f"measurements: case theta={cases[c, 0]:g} deg, load={cases[c, 1]:g} N "
                         f"has no row for station {stations[s]:g} m (every case needs every station)")
    return cases, stations, table


def errors(measured: Measurements, elements: int = 16, gravity: bool = True,
           relative: bool = False, stiffness=None,
           settings: StaticSettings = CASE_SETTINGS) -> Errors:
    """Simulate the measured cases at the measured stations and apply eq. (112)."""
    cases, stations, table = _case_table(measured)
    sim = replay(cases[:, 0], cases[:, 1], elements, gravity, relative,
                 stations / LENGTH, stiffness, settings)
    if not np.all(sim.converged):
        bad = [(float(t), float(f)) for t, f, ok in zip(*cases.T, sim.converged) if not ok]
        raise RuntimeError(f"Princeton replay: static solve not converged for (theta, load) {bad}")
    e = 100.0 * np.abs(sim.deflection - table).sum(axis=2) / stations[None, :]
    e_mu, e_sigma, tip = e.mean(axis=1), e.std(axis=1), e[:, -1]
    by_angle = {}
    for th in np.unique(cases[:, 0]):
        sel = cases[:, 0] == th
        by_angle[float(th)] = (float(e_mu[sel].mean()), float(e_mu[sel].std()),
                               float(tip[sel].mean()), float(tip[sel].std()))
    return Errors(cases[:, 0], cases[:, 1], stations, e, e_mu, e_sigma, tip, by_angle, sim, table)


def load_angle_sweep(theta_deg: Sequence[float], load_N: Sequence[float], elements: int = 16,
                     gravity: bool = True, settings: StaticSettings = CASE_SETTINGS,
                     warm_start: bool = True):
    """Tip deflection over a load-angle x load-magnitude grid in one compiled call.

    ``warm_start`` (default): the points are solved in grid order, each from its
    neighbour's equilibrium (:func:`simsoft_jax.studies.sweeps.static_sweep`); otherwise all at
    once with ``jax.vmap``. Returns ``(tip (A, F, 2) (y, z) in m, converged (A, F))`` for
    ``A`` angles and ``F`` loads.
    """
    shape = (len(theta_deg), len(load_N))
    points = grid(theta=theta_deg, load=load_N)
    # boustrophedon order (loads up, then down at the next angle): neighbours stay close
    order = np.arange(points["theta"].size).reshape(shape)
    order[1::2] = order[1::2, ::-1]
    order = order.ravel()
    sim = replay(points["theta"][order], points["load"][order], elements, gravity,
                 stations=(1.0,), settings=settings, warm_start=warm_start)
    tip = np.empty((order.size, 2))
    tip[order] = sim.deflection[:, 0]
    converged = np.empty(order.size, bool)
    converged[order] = sim.converged
    return tip.reshape(shape + (2,)), converged.reshape(shape)


def write_table(path, replay: Replay, errors: Errors | None = None) -> Path:
    """CSV of simulated deflections per case and station (m), with eq. (112) errors (%)
    when ``errors`` is given (its replay is written then)."""
    path = Path(path)
    sim = errors.replay if errors is not None else replay
    with path.open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(["theta_deg", "load_N", "station_m", "y_m", "z_m", "converged"]
                        + (["y_measured_m", "z_measured_m", "error_percent"] if errors else []))
        for c in range(len(sim.theta_deg)):
            for s, r in enumerate(sim.stations_m):
                row = [f"{sim.theta_deg[c]:g}", f"{sim.load_N[c]:.6g}", f"{r:.6g}",
                       f"{sim.deflection[c, s, 0]:.9g}", f"{sim.deflection[c, s, 1]:.9g}",
                       str(bool(sim.converged[c]))]
                if errors is not None:
                    row += [f"{errors.measured[c, s, 0]:.9g}", f"{errors.measured[c, s, 1]:.9g}",
                            f"{errors.e[c, s]:.6g}"]
                writer.writerow(row)
    return path
