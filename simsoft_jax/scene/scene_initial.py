"""Parsing of a rod's start state, the scene key ``initial`` (plain Python + NumPy):
node points (exact when one per node, else a resampled polyline) with optional rotations,
or a restart from a result file written by :meth:`simsoft_jax.Result.save`. Every bad
input is rejected with an error naming its key (see :mod:`simsoft_jax.scene.scene`)."""
from __future__ import annotations

import json
import zipfile
from pathlib import Path
from typing import Any

import numpy as np

from .key_checks import (check_keys, fail, index, join, note_read, number, polyline,
                        proper_rotations, readonly, require, string, table)
from ..math.geometry import chords

INITIAL_KEYS = ("points", "rotations", "result", "time")


def parse_initial(value: Any, path: str, rod: str, nodes: int, base_position: np.ndarray,
                   base_rotation: np.ndarray, base_dir: Path) -> dict:
    """``initial``: points (+ rotations), base frame, or a restart from a saved result.

    Returns the RodSpec fields ``initial_points`` (P,3), ``initial_rotations`` (nodes,3,3)
    and ``initial_velocities`` (nodes,6), all in the rod's base frame (velocities are body
    velocities, frame-free). Points count == nodes: the nodes exactly; otherwise a polyline.
    """
    init = table(value, path)
    check_keys(init, path, INITIAL_KEYS)
    if "result" in init:
        for key in ("points", "rotations"):
            if key in init:
                fail(join(path, key), "give either result (a restart) or points, not both")
        return _parse_restart(init, path, rod, nodes, base_position, base_rotation, base_dir)
    if "time" in init:
        fail(join(path, "time"), "only goes with result (the saved time to restart from)")
    ppath = join(path, "points")
    points = polyline(require(init, path, "points"), ppath)
    rotations = None
    if "rotations" in init:
        rpath = join(path, "rotations")
        if len(points) != nodes:
            fail(rpath, f"needs exactly one point per node ({nodes}) in {ppath}; the "
                 f"{len(points)} points given are a polyline, resampled to the nodes")
        rotations = proper_rotations(init["rotations"], rpath)
        if len(rotations) != nodes:
            fail(rpath, f"must have one rotation per node ({nodes}), got {len(rotations)}")
    elif len(points) == nodes:  # node tangents from chords p[i+1] - p[i-1]
        for i, c in enumerate(chords(points)):
            if not np.any(c):
                fail(index(ppath, i + 1), f"equals {ppath}[{i - 1}]: node {i} has no tangent "
                     "(chord of its neighbours is zero); give initial.rotations")
    return dict(initial_points=readonly(points), initial_rotations=readonly(rotations))


def _parse_restart(init: dict, path: str, rod: str, nodes: int, base_position: np.ndarray,
                   base_rotation: np.ndarray, base_dir: Path) -> dict:
    """``initial = { result = "file", time = t }``: the saved state of the rod ``rod``."""
    rpath, tpath = join(path, "result"), join(path, "time")
    name = string(init["result"], rpath)
    file = Path(name) if Path(name).is_absolute() else base_dir / name
    saved = _read_result(file, rpath)
    note_read(file)
    init["result"] = str(file.absolute())  # raw / to_dict stay valid from any folder
    if rod not in saved["rods"]:
        fail(rpath, f"{file.name} has no rod named {rod!r} "
             f"(it has: {', '.join(saved['rods']) or 'none'})")
    entry = saved["rods"][rod]
    dynamic = saved["time"] is not None
    lead = (len(saved["time"]),) if dynamic else ()
    velocities = entry.get("velocities") if dynamic else None
    for key, shape in (("positions", (3,)), ("rotations", (3, 3)), ("velocities", (6,))):
        arr = entry.get(key)
        if arr is None:
            if key != "velocities":
                fail(rpath, f"{file.name}: rods.{rod}.{key} missing")
            continue
        if arr.ndim != len(lead) + 1 + len(shape) or arr.shape[:len(lead)] != lead \
                or arr.shape[len(lead) + 1:] != shape:
            fail(rpath, f"{file.name}: rods.{rod}.{key} has shape {arr.shape}, expected "
                 f"{(*lead, nodes, *shape)}")
        if arr.shape[len(lead)] != nodes:
            fail(rpath, f"{file.name}: rod {rod!r} has {arr.shape[len(lead)]} nodes, this "
                 f"scene's rod has {nodes} (the element counts must match)")
        if not np.all(np.isfinite(arr)):
            fail(rpath, f"{file.name}: rods.{rod}.{key} holds non-finite values")
    positions, rotations = entry["positions"], entry["rotations"]
    where = ""
    if dynamic:
        times = saved["time"]
        k = len(times) - 1
        if "time" in init:
            t = number(init["time"], tpath)
            scale = max(abs(t), float(np.abs(times).max()))
            k = int(np.argmin(np.abs(times - t)))
            if abs(times[k] - t) > 1e-9 * scale:
                fail(tpath, f"no state saved at t = {t:g} s in {file.name} (saved: "
                     f"{len(times)} times from {times[0]:g} to {times[-1]:g} s)")
        positions, rotations = positions[k], rotations[k]
        velocities = None if velocities is None else velocities[k]
        where = f" at t = {times[k]:g} s"
    elif "time" in init:
        fail(tpath, f"{file.name} is a static result (no time axis); remove time")
    try:
        rotations = proper_rotations(rotations.tolist(), f"rods.{rod}.rotations")
    except ValueError as err:
        fail(rpath, f"{file.name}{where}: {err}")
    Rb, pb = np.asarray(base_rotation, float), np.asarray(base_position, float)
    return dict(initial_points=readonly((positions - pb) @ Rb),
                initial_rotations=readonly(np.einsum("ji,njk->nik", Rb, rotations)),
                initial_velocities=readonly(velocities))


def _read_result(file: Path, path: str) -> dict:
    """A result file of ``Result.save`` (.json or .npz) -> ``{"time": (T,) or None,
    "rods": {name: {"positions", "rotations"[, "velocities"]: arrays}}}``."""
    suffix = file.suffix.lower()
    if suffix not in (".json", ".npz"):
        fail(path, f"must name a .json or .npz result file (Result.save), got {file.name!r}")
    try:
        if suffix == ".json":
            data = json.loads(file.read_text(encoding="utf-8"))
            if not isinstance(data, dict) or not isinstance(data.get("rods"), dict):
                fail(path, f"{file.name}: not a result file (no rods table)")
            kind, time = data.get("kind"), data.get("time")
            rods = {}
            for rod, entry in data["rods"].items():
                if not isinstance(entry, dict):
                    fail(path, f"{file.name}: rods.{rod} must be a table")
                rods[rod] = {key: np.asarray(entry[key], dtype=float)
                             for key in ("positions", "rotations", "velocities")
                             if key in entry}
        else:
            with np.load(file, allow_pickle=False) as z:
                kind = str(z["kind"]) if "kind" in z.files else None
                time = z["time"] if "time" in z.files else None
                rods = {}
                for key in z.files:
                    rod, _, field = key.rpartition("/")
                    if rod and field in ("positions", "rotations", "velocities"):
                        rods.setdefault(rod, {})[field] = np.asarray(z[key], dtype=float)
    except OSError as err:
        fail(path, f"cannot read {str(file)!r}: {err.strerror or err}")
    except (zipfile.BadZipFile, EOFError, KeyError) as err:  # a damaged .npz archive
        fail(path, f"{file.name}: not a readable result file (a damaged .npz archive: "
             f"{err})")
    except (ValueError, TypeError) as err:  # bad JSON / npz, ragged arrays
        if str(err).startswith(path + ":"):
            raise
        fail(path, f"{file.name}: not a readable result file: {err}")
    if time is not None:
        time = np.asarray(time, dtype=float)
        if time.ndim != 1 or not len(time) or not np.all(np.isfinite(time)):
            fail(path, f"{file.name}: time must be a non-empty list of finite numbers")
    if kind is not None and kind not in ("static", "dynamic"):
        fail(path, f"{file.name}: kind must be 'static' or 'dynamic', got {kind!r}")
    if kind is not None and (kind == "dynamic") != (time is not None):
        fail(path, f"{file.name}: a {kind} result with" + ("out a" if time is None else " a")
             + " time axis")
    return {"time": time, "rods": rods}
