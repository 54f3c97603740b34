"""Run a scene and hold its result in the layout of the scene-file contract.

``run(scene)`` builds the Model, compiles the solver once per model structure (kept in
a cache, so running the same structure with other numbers does not recompile) and returns
a :class:`Result`. ``Result.to_dict()`` is exactly the JSON layout of
``scene-format.md``; ``Result.save(path)`` writes ``.json`` or ``.npz``.
"""
from __future__ import annotations

import json
import time
from pathlib import Path

import jax
import numpy as np

from .model import Model, build_model
from .scene import Scene, load_scene
from .statics import Equilibrium, settings_from_scene, solve_static

_COMPILED: dict = {}


def compiled_static_solver(model: Model, settings):
    """The compiled static solver for ``model``'s structure, and the seconds spent compiling
    it now (0.0 when it was already compiled in this process)."""
    key = (model.structure, settings)
    if key in _COMPILED:
        return _COMPILED[key], 0.0
    start = time.perf_counter()
    compiled = solve_static.lower(model, settings).compile()
    _COMPILED[key] = compiled
    return compiled, time.perf_counter() - start


class Result:
    """Outcome of :func:`run`. Static results only (dynamic scenes: see :func:`run`).

    Attributes: name, kind ("static"), converged (bool), newton_iterations (int),
    residual_norm (N, weighted), load_level (fraction of the loads reached), wall_time_s
    (solve, after compilation), compile_time_s, model (the Model), equilibrium (the raw
    :class:`~simsoft_jax.statics.Equilibrium`).
    """

    def __init__(self, scene: Scene, model: Model, equilibrium: Equilibrium,
                 wall_time_s: float, compile_time_s: float):
        self.name = scene.name
        self.kind = scene.solver.kind
        self.model = model
        self.equilibrium = equilibrium
        self.converged = bool(equilibrium.converged)
        self.newton_iterations = int(equilibrium.iterations)
        self.residual_norm = float(equilibrium.residual_norm)
        self.load_level = float(equilibrium.load_level)
        self.wall_time_s = wall_time_s
        self.compile_time_s = compile_time_s
        self.time = None
        self._R = np.asarray(equilibrium.R)
        self._p = np.asarray(equilibrium.p)

    def _nodes(self, rod: str) -> slice:
        info = self.model.structure.rod(rod)
        return slice(info.first_node, info.first_node + info.nodes)

    def positions(self, rod: str) -> np.ndarray:
        """Node positions of ``rod`` in world coordinates (m), shape (nodes, 3)."""
        return self._p[self._nodes(rod)].copy()

    def rotations(self, rod: str) -> np.ndarray:
        """Section frames of ``rod`` (nodes, 3, 3); columns are the local axes in world."""
        return self._R[self._nodes(rod)].copy()

    def to_dict(self) -> dict:
        """The result-file layout of the scene-format contract (plain Python types)."""
        d = {"name": self.name, "kind": self.kind, "converged": self.converged,
             "newton_iterations": self.newton_iterations,
             "residual_norm": self.residual_norm, "wall_time_s": self.wall_time_s,
             "compile_time_s": self.compile_time_s,
             "rods": {r.name: {"positions": self.positions(r.name).tolist(),
                               "rotations": self.rotations(r.name).tolist()}
                      for r in self.model.structure.rods}}
        if not self.converged:
            d["failed_at"] = {"load_level": self.load_level,
                              "residual_norm": self.residual_norm}
        return d

    def save(self, path) -> Path:
        """Write the result as ``.json`` (contract layout) or ``.npz`` (same keys;
        per-rod arrays as ``<rod>/positions`` and ``<rod>/rotations``)."""
        path = Path(path)
        if path.suffix == ".json":
            path.write_text(json.dumps(self.to_dict(), indent=1))
        elif path.suffix == ".npz":
            d = self.to_dict()
            arrays = {k: np.asarray(v) for k, v in d.items()
                      if k not in ("rods", "failed_at") and v is not None}
            for rod in d["rods"]:
                arrays[f"{rod}/positions"] = self.positions(rod)
                arrays[f"{rod}/rotations"] = self.rotations(rod)
            np.savez(path, **arrays)
        else:
            raise ValueError(f"output: unsupported suffix {path.suffix!r} (use .json or .npz)")
        return path


def run(scene) -> Result:
    """Solve a scene (a :class:`Scene`, a dict or a path to a .toml/.json file).

    Static scenes are solved by :func:`~simsoft_jax.statics.solve_static`. Dynamic scenes
    raise ``NotImplementedError`` until the dynamics module lands.
    """
    if isinstance(scene, (str, Path)):
        scene = load_scene(scene)
    elif isinstance(scene, dict):
        scene = Scene.from_dict(scene)
    if scene.solver.kind != "static":
        raise NotImplementedError("solver.kind: dynamic scenes are not supported yet "
                                  "(only static solves are implemented)")
    model = build_model(scene)
    settings = settings_from_scene(scene.solver)
    solver, compile_time = compiled_static_solver(model, settings)
    start = time.perf_counter()
    equilibrium = jax.block_until_ready(solver(model))
    wall = time.perf_counter() - start
    return Result(scene, model, equilibrium, wall, compile_time)
