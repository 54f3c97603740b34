"""Run a scene and hold its result in the layout of the scene-file contract.

``run(scene)`` builds the Model, compiles the solver once per model structure (kept in
a cache, so running the same structure with other numbers does not recompile; and in
JAX's persistent compilation cache, :mod:`.compile_cache`) and returns a
:class:`Result` holding NumPy arrays (copied from the device once). ``Result.to_dict()`` is exactly the JSON layout of
``scene-format.md``; ``Result.save(path)`` writes ``.json`` or ``.npz``.
"""
from __future__ import annotations

import functools

import time
import warnings
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from ..couplings import coupling
from ..solvers import compile_cache
from ..analysis import contacts
from ..model.built_models import Lru, forget_models, model_of, scene_of
from ..solvers.dynamics import Trajectory, rollout
from ..model.model import Model
from ..atomic_files import write_atomic
from .output import count_nonfinite, finite_or_none, write_json
from ..solvers.programs import PROGRAMS, compiled_static_solver
from ..scene.scene import Scene
from ..scene.supports import advice
from ..solvers.statics import as_traced, settings_from_scene
from ..solvers.status import Status


class _StaticRuns:
    """What the static runs of one built model keep (:func:`_static_runs`): the model
    (held: its id stays its own), the arrays to hand the compiled program (its host arrays
    at the first run: the program transfers them, ~0.15 ms, against ~1 ms for a separate
    transfer of its ~60 arrays; a device copy from the second run on: no transfer at later
    calls, ~0.1 ms of a 3.5 ms Princeton solve) and, per settings, the compiled solver and
    the traced settings (looking the program up by structure costs ~0.05 ms)."""

    def __init__(self, model: Model):
        self.model, self.device, self.solvers = model, None, {}

    def arrays(self) -> Model:
        if self.device is None:
            self.device = False          # the next run gets a device copy
            return self.model
        if self.device is False:
            self.device = jax.device_put(self.model)
        return self.device

    def solver(self, settings) -> tuple:
        """``(compiled solver, traced settings, seconds spent compiling it now)``."""
        if settings in self.solvers:
            return self.solvers[settings] + (0.0,)
        solver, seconds = compiled_static_solver(self.model, settings)
        self.solvers[settings] = (solver, as_traced(settings))
        return self.solvers[settings] + (seconds,)


_STATIC_RUNS = Lru(size=8)   # id(model) -> _StaticRuns


def forget_programs() -> None:
    """Drop what :func:`run` keeps between calls in this process: the compiled programs
    (:data:`~simsoft_jax.solvers.programs.PROGRAMS`), the static runs per model and the
    built models (:func:`~simsoft_jax.model.built_models.forget_models`). Frees their
    memory; the next call builds and compiles again (or loads from the cache folder)."""
    PROGRAMS.clear()
    _STATIC_RUNS.clear()
    forget_models()


def _static_runs(model: Model) -> _StaticRuns:
    runs = _STATIC_RUNS.get(id(model))
    if runs is None or runs.model is not model:
        runs = _STATIC_RUNS[id(model)] = _StaticRuns(model)
    return runs


class Result:
    """Outcome of :func:`run`.

    Attributes: name, kind ("static" | "dynamic"), converged (bool), status (short code:
    "converged", "max_iterations", "nonfinite", "step_too_small", "off_branch",
    "max_attempts", "interrupted"), message (one sentence: how the solve ended and where),
    newton_iterations (int, total), residual_norm (static: N, weighted; dynamic: at the
    failed step, None when converged), load_level (static: fraction of the loads
    reached), failed_at (dynamic: time of the failed step or None),
    time ((T,) s, dynamic only), wall_time_s (after compilation; static: with the
    stability check), compile_time_s (compiling or loading the program and one
    throw-away execution of it, 0 when it was ready), model (read-only NumPy arrays: ``build_model(scene,
    device=False)``, shared by the runs of equal scenes:
    :func:`~simsoft_jax.model.built_models.model_of`),
    raw (the :class:`~simsoft_jax.solvers.statics.Equilibrium` or
    :class:`~simsoft_jax.solvers.dynamics.Trajectory`), stability (static only, None when not
    checked (not converged, or ``run(..., stability=False)``):
    ``{"negative_eigenvalues": n, "stable": n == 0}``,
    :mod:`simsoft_jax.solvers.stability`), slack_tendons (names of displacement-controlled
    tendons whose solved tension is negative: they would have to push; also warned and
    noted in ``message``), contacts (None without obstacles; else per obstacle
    name the total normal force (N), the total force (3,) (N, world), the largest
    penetration (m) and the nodes in contact ``{rod: [nodes]}``, each with a leading time
    axis in dynamics: :func:`simsoft_jax.analysis.contacts.report`).
    """

    def __init__(self, scene: Scene, model: Model, raw, wall_time_s: float,
                 compile_time_s: float, stability: dict | None = None):
        self.name = scene.name
        self.kind = scene.solver.kind
        self.stability = stability
        self.model = model
        self.raw = raw
        self.converged = bool(raw.converged)
        self.status = Status(int(raw.status)).code
        self.message = raw.message()
        if self.status == Status.UNRESTRAINED.code:   # name the motions left free
            self.message += "".join(
                f"; rod {name!r}: its supports leave {words} (to hold it: {advice(words)})"
                for name, words in model.structure.settling)
        self.newton_iterations = int(np.sum(raw.iterations))
        self.wall_time_s = wall_time_s
        self.compile_time_s = compile_time_s
        if isinstance(raw, Trajectory):
            self.time = np.asarray(raw.time)
            self.load_level = None
            self.failed_at = None if self.converged else float(raw.failed_at)
            self.residual_norm = None if self.converged else float(raw.residual)
        else:
            self.time = None
            self.residual_norm = float(raw.residual_norm)
            self.load_level = float(raw.load_level)
            self.failed_at = None
        self._R = np.asarray(raw.R)
        self._p = np.asarray(raw.p)
        self.slack_tendons = self._slack_tendons()
        if self.slack_tendons:
            note = (f"tendon{'s' * (len(self.slack_tendons) > 1)} "
                    f"{', '.join(map(repr, self.slack_tendons))} would have to push "
                    "(negative tension): slack, the solved shape is not physical")
            self.message += f"; {note}"
            warnings.warn(note, stacklevel=2)

    def _slack_tendons(self) -> tuple:
        """Names of the displacement-controlled tendons whose solved tension is below 0
        (at any saved time of a dynamic result)."""
        s = self.model.structure
        return tuple(n for n, flag in zip(s.tendon_names, s.tendon_displaced)
                     if flag and np.min(self.tendon_tension(n)) < 0.0)

    @functools.cached_property
    def contacts(self) -> dict | None:
        """The contact report (class docstring), computed from the result's frames at
        the first read (:func:`simsoft_jax.analysis.contacts.report`): a run that never reads it
        does not pay for it."""
        return contacts.report(self.model, self._R, self._p, self.time)

    def _nodes(self, rod: str) -> slice:
        info = self.model.structure.rod(rod)
        return slice(info.first_node, info.first_node + info.nodes)

    def positions(self, rod: str) -> np.ndarray:
        """Node positions of ``rod`` in world coordinates (m): (nodes, 3), or
        (T, nodes, 3) for dynamic results."""
        return self._p[..., self._nodes(rod), :].copy()

    def rotations(self, rod: str) -> np.ndarray:
        """Section frames of ``rod``: (nodes, 3, 3) or (T, nodes, 3, 3); columns are the
        local axes in world coordinates."""
        return self._R[..., self._nodes(rod), :, :].copy()

    def velocities(self, rod: str) -> np.ndarray:
        """Body velocities ``[v; omega]`` of ``rod``'s sections in their local axes (m/s,
        rad/s), (T, nodes, 6); dynamic results only (world velocities: ``R @ v``)."""
        if self.time is None:
            raise ValueError("velocities: a static result has none (run a dynamic scene)")
        return np.asarray(self.raw.v)[:, self._nodes(rod)].copy()

    def body_pose(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """Position (3,) (m, world) and rotation (3,3) (columns: the body axes in world
        coordinates) of the rigid body ``name`` (``[[bodies]]``)."""
        nodes = dict(self.model.structure.bodies)
        if name not in nodes:
            raise ValueError(f"body: no body named {name!r} (known: "
                             f"{', '.join(nodes) or 'none'})")
        return self._p[..., nodes[name], :].copy(), self._R[..., nodes[name], :, :].copy()

    def tendon_tension(self, name: str):
        """Tension (N) of the tendon ``name``: a float for a static result, (T,) at the
        saved times for a dynamic one (its tension times its time law)."""
        s = self.model.structure
        if name not in s.tendon_names:
            raise ValueError(f"tendon_tension: no tendon named {name!r} (known: "
                             f"{', '.join(s.tendon_names) or 'none'})")
        m = s.tendon_names.index(name)
        if self.time is None:   # solved for displacement-controlled tendons
            return float(self.raw.tendon_tension[m])
        if s.tendon_displaced[m]:   # solved at every step: the rollout's multipliers
            at = coupling.tension_index(s, sum(s.tendon_displaced[:m]))
            return np.asarray(self.raw.multipliers)[:, at].copy()
        tension = float(self.model.tendon_tension[m])
        law = self.model.tendon_law
        return tension * np.asarray(jax.vmap(law.scales)(jnp.asarray(self.time)))[:, m]

    def to_dict(self) -> dict:
        """The result-file layout of the scene-format contract (plain Python types);
        dynamic results add per-rod ``velocities`` (T, nodes, 6), as :meth:`velocities`.
        Non-finite numbers (a solve that blew up) are ``None``; the message then says how
        many were replaced, so strict JSON readers accept the file."""
        d, replaced = finite_or_none(self._contents())
        d["message"] += _replaced_note(replaced)
        return d

    def _contents(self) -> dict:
        """The layout of :meth:`to_dict` with its arrays kept NumPy arrays and its
        non-finite numbers as they are."""
        rods = {}
        for r in self.model.structure.rods:
            rods[r.name] = {"positions": self.positions(r.name),
                            "rotations": self.rotations(r.name)}
            if self.time is not None:  # body velocities: a restart needs them
                rods[r.name]["velocities"] = self.velocities(r.name)
        d = {"name": self.name, "kind": self.kind, "converged": self.converged,
             "status": self.status, "message": self.message,
             "newton_iterations": self.newton_iterations,
             "residual_norm": self.residual_norm, "wall_time_s": self.wall_time_s,
             "compile_time_s": self.compile_time_s, "rods": rods}
        if self.model.structure.bodies:
            d["bodies"] = {name: dict(zip(("position", "rotation"), self.body_pose(name)))
                           for name, _ in self.model.structure.bodies}
        if self.model.structure.tendon_names:
            d["tendons"] = {name: {"tension": self.tendon_tension(name)}
                            for name in self.model.structure.tendon_names}
        if self.contacts is not None:
            d["contacts"] = self.contacts
        if self.time is not None:
            d["time"] = self.time
        else:  # static: None when not checked (not converged, or skipped)
            d["stability"] = None if self.stability is None else dict(self.stability)
        if not self.converged:
            d["failed_at"] = ({"time": self.failed_at} if self.time is not None else
                              {"load_level": self.load_level,
                               "residual_norm": self.residual_norm})
        return d

    def save(self, path) -> Path:
        """Write the result as ``.json`` (contract layout, strict JSON: no NaN/Infinity)
        or ``.npz`` (same keys; per-rod arrays as ``<rod>/positions``, ``<rod>/rotations``
        and, dynamic, ``<rod>/velocities``; tendon tensions as
        ``tendons/<name>/tension``). The file is written to a temporary name in the same
        folder and renamed: a failed or interrupted write leaves the old file (or none),
        never a partial one. An existing file is replaced."""
        path = Path(path)
        if path.suffix == ".json":   # written piece by piece (output.write_json)
            data = self._contents()
            data["message"] += _replaced_note(count_nonfinite(data))
            return write_atomic(path, lambda fh: write_json(fh, data))
        if path.suffix != ".npz":
            raise ValueError(f"output: unsupported suffix {path.suffix!r} (use .json or .npz)")
        d = self.to_dict()
        arrays = {k: np.asarray(v) for k, v in d.items()
                  if k not in ("rods", "bodies", "failed_at", "time", "stability",
                               "tendons", "contacts") and v is not None}
        for name, pose in d.get("bodies", {}).items():
            arrays[f"bodies/{name}/position"] = np.asarray(pose["position"])
            arrays[f"bodies/{name}/rotation"] = np.asarray(pose["rotation"])
        for name in self.model.structure.tendon_names:
            arrays[f"tendons/{name}/tension"] = np.asarray(self.tendon_tension(name))
        for name, c in (self.contacts or {}).items():
            for key in ("normal_force", "force", "max_penetration"):
                arrays[f"contacts/{name}/{key}"] = c[key]
            for rod, force in c.get("rod_force", {}).items():
                arrays[f"contacts/{name}/rod_force/{rod}"] = force
        if self.stability is not None:
            arrays["stability/negative_eigenvalues"] = self.stability["negative_eigenvalues"]
        if self.time is not None:
            arrays["time"] = self.time
        for rod in d["rods"]:
            arrays[f"{rod}/positions"] = self.positions(rod)
            arrays[f"{rod}/rotations"] = self.rotations(rod)
            if self.time is not None:
                arrays[f"{rod}/velocities"] = self.velocities(rod)
        return write_atomic(path, lambda fh: np.savez(fh, **arrays), binary=True)


def _replaced_note(replaced: int) -> str:
    """The note a result's message gets when ``replaced`` non-finite numbers are written
    as null ("" when none)."""
    return (f" ({replaced} non-finite value{'s' * (replaced > 1)} written as null)"
            if replaced else "")


def _run_dynamic(scene: Scene, model: Model, progress=None) -> Result:
    solver = scene.solver
    start = time.perf_counter()
    trajectory, compile_time = rollout(
        model, solver.dt, solver.t_end, solver.rho_inf, solver.save_every,
        progress=progress, compiled=PROGRAMS, tolerance=solver.tolerance,
        max_iterations=solver.max_iterations, tangent=solver.tangent)
    wall = time.perf_counter() - start - compile_time
    return Result(scene, model, trajectory, wall, compile_time)


def run(scene, progress=None, stability: bool = True) -> Result:
    """Solve a scene (a :class:`Scene`, a dict or a path to a .toml/.json file).

    Static scenes: :func:`~simsoft_jax.solvers.statics.solve_static` at full load. Dynamic scenes:
    :func:`~simsoft_jax.solvers.dynamics.rollout` from t = 0 to exactly t_end (steps of dt,
    shorter closing steps where t_end/dt or save_every does not divide), keeping every
    ``save_every``-th state and the last, in chunks of one compiled program;
    ``progress(t, t_end)`` is called after each chunk (400 steps). Compilation is cached
    per model structure: in this process, and on disk in JAX's persistent compilation
    cache for later processes (:mod:`simsoft_jax.solvers.compile_cache`; off with
    ``SIMSOFT_JAX_CACHE=0``). The Model of a scene is built once per scene content
    (:func:`~simsoft_jax.model.built_models.model_of`), and a scene file parsed once per content
    of it and of the files it reads (:func:`~simsoft_jax.model.built_models.scene_of`).
    ``stability``: count the
    negative eigenvalues of the tangent at a converged static equilibrium
    (:attr:`Result.stability`; :mod:`simsoft_jax.solvers.stability`).
    """
    compile_cache.enable()
    if isinstance(scene, (str, Path)):
        scene = scene_of(scene)
    elif isinstance(scene, dict):
        scene = Scene.from_dict(scene)
    model = model_of(scene)  # host arrays (the program transfers them), cached by content
    if scene.solver.kind == "dynamic":
        return _run_dynamic(scene, model, progress)
    runs = _static_runs(model)
    solver, settings, compile_time = runs.solver(settings_from_scene(scene.solver))
    start = time.perf_counter()
    eq, count = solver(runs.arrays(), settings, np.bool_(stability))
    wall = time.perf_counter() - start
    checked = None if count < 0 else {"negative_eigenvalues": int(count),
                                      "stable": int(count) == 0}
    return Result(scene, model, eq, wall, compile_time, checked)
