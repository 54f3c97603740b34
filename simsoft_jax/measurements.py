"""Measured node positions of static scenes, read from CSV for calibration.

Layout (header required)::

    scene,rod,node,x,y,z
    princeton_0deg,beam,-1,0.5079,,-0.0107

``scene`` is a scene's ``name``; ``rod`` a rod of it; ``node`` the node index within the
rod (0 = first, negative counts from the end as in scene files); ``x, y, z`` the measured
world position (m). An empty cell means "not measured" (e.g. only the deflections
were recorded); every row needs at least one component. Every error names the file,
the line and the column.
"""
from __future__ import annotations

import csv
from pathlib import Path
from typing import Sequence

import numpy as np

from .calibration import StaticTarget
from .model import build_model

COLUMNS = ("scene", "rod", "node", "x", "y", "z")


def _fail(path: Path, line: int, column: str, message: str):
    raise ValueError(f"measurements: {path.name} line {line}, column {column}: {message}")


def read_rows(path) -> list[tuple[int, str, str, int, list]]:
    """Parsed rows ``(line, scene, rod, node, [x, y, z] with None for empty)``."""
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"measurements: no such file {str(path)!r}")
    with path.open(newline="") as handle:
        reader = csv.DictReader(handle)
        missing = [c for c in COLUMNS if c not in (reader.fieldnames or [])]
        if missing:
            raise ValueError(f"measurements: {path.name} lacks column(s) {missing} "
                             f"(need {list(COLUMNS)})")
        rows = []
        for line, row in enumerate(reader, start=2):
            for key in ("scene", "rod", "node"):
                if not (row[key] or "").strip():
                    _fail(path, line, key, "empty")
            try:
                node = int(row["node"])
            except ValueError:
                _fail(path, line, "node", f"not an integer: {row['node']!r}")
            xyz = []
            for key in "xyz":
                text = (row[key] or "").strip()
                if not text:
                    xyz.append(None)
                    continue
                try:
                    value = float(text)
                except ValueError:
                    _fail(path, line, key, f"not a number: {text!r}")
                if not np.isfinite(value):
                    _fail(path, line, key, "not finite")
                xyz.append(value)
            if all(v is None for v in xyz):
                _fail(path, line, "x,y,z", "no component measured")
            rows.append((line, row["scene"].strip(), row["rod"].strip(), node, xyz))
    if not rows:
        raise ValueError(f"measurements: {path.name} has no data rows")
    return rows


def static_targets(path, scenes: Sequence) -> list[StaticTarget]:
    """One :class:`~simsoft_jax.calibration.StaticTarget` per scene that has measurements.

    scenes: validated static :class:`~simsoft_jax.scene.Scene` objects with unique names.
    Raises ``ValueError`` for rows naming unknown scenes, rods or nodes.
    """
    path = Path(path)
    by_name = {}
    for scene in scenes:
        if scene.solver.kind != "static":
            raise ValueError(f"scenes: {scene.name!r} is a {scene.solver.kind} scene; "
                             f"calibration from positions needs static scenes")
        if scene.name in by_name:
            raise ValueError(f"scenes: two scenes are named {scene.name!r}; names must be unique")
        by_name[scene.name] = scene
    models = {}
    collected: dict = {}
    for line, scene_name, rod, node, xyz in read_rows(path):
        if scene_name not in by_name:
            _fail(path, line, "scene", f"unknown scene {scene_name!r} (given: {sorted(by_name)})")
        if scene_name not in models:
            models[scene_name] = build_model(by_name[scene_name])
        structure = models[scene_name].structure
        rods = [r.name for r in structure.rods]
        if rod not in rods:
            _fail(path, line, "rod", f"scene {scene_name!r} has no rod {rod!r} (rods: {rods})")
        info = structure.rod(rod)
        if not -info.nodes <= node < info.nodes:
            _fail(path, line, "node", f"rod {rod!r} has nodes 0..{info.nodes - 1} "
                  f"(or -{info.nodes}..-1), got {node}")
        global_node = info.first_node + node % info.nodes
        collected.setdefault(scene_name, []).append((global_node, xyz))
    targets = []
    for name, rows in collected.items():
        nodes = np.array([n for n, _ in rows])
        mask = np.array([[v is not None for v in xyz] for _, xyz in rows])
        values = np.array([[0.0 if v is None else v for v in xyz] for _, xyz in rows])
        targets.append(StaticTarget(models[name], nodes, values, mask))
    return targets
