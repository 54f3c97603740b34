"""A solver for the cosseratbench rod benchmark (``pip install 'simsoft_jax[bench]'``).

cosseratbench finds it through the entry point ``simsoft_jax`` of the group
``cosseratbench.solvers`` (see pyproject.toml): ``cosseratbench run cantilever -s simsoft_jax``.
Each benchmark scenario is written as a scene of this project (:class:`~simsoft_jax.Scene`)
and solved through the public API:

* **Rods.** One rod per benchmark rod, ``rod<i>``: a straight stress-free shape of the rod's
  unstretched length, a solid circular section of its radius, its Young's and shear
  moduli and density. The start configuration is the benchmark's material points
  (``Rod.nodes``, evenly spaced by unstretched arc length, so a rod given with
  ``rest_arc_length`` starts stretched) as ``initial.points``, one per node; the section
  axes follow the points from a base frame whose ``x`` is the first segment and whose
  ``y`` is the rod's ``normal`` (the benchmark's director ``d1``).
* **Ends.** pinned -> ``pin``; clamped -> ``clamp``; clamped with a motion -> ``drive``
  (its times, displacements and rotation vectors, and ``slides_along``). End point loads
  -> world-frame nodal forces; gravity -> ``[gravity]``.
* **Quasi-static scenarios** whose ends do not move: one static solve (exact
  equilibrium, load continuation); the trajectory is the start frame followed by the
  equilibrium. If the supports leave a rigid motion free (two pins leave the twist about
  the line through them), or an end is driven, the scenario runs as damped dynamics
  instead: mass-proportional damping (:mod:`simsoft_jax.physics.terms.mass_damping`) with
  ``c = 2 omega_slow`` (critical for the slowest mode, whose angular frequency
  ``omega_slow`` is the benchmark's ``Scenario.slowest_frequency``; every mode then decays
  as ``exp(-omega_slow t)``).
* **Dynamic scenarios**: generalized-alpha, ``rho_inf = 0.9``, no damping.
* **Time step** (stated by :meth:`SimsoftJaxSolver.settings`): the frame interval
  ``T_f = duration / (n_frames - 1)`` divided into ``k = ceil(T_f / dt_max)`` equal steps,
  ``dt_max = time_step_scale * 2 pi / (N omega_slow)`` (and no more than the spacing of a
  driven end's motion samples), with ``N = 200`` steps per slowest
  period in dynamic scenarios (generalized-alpha's period error ~ (omega dt)^2 / 12, about
  8e-5 there) and ``N = 40`` in quasi-static ones. The scheme is implicit, so the step is
  set by accuracy, not by a stability limit.

Contact (rods with each other, with themselves, with cylinders or planes) is not modelled:
those capabilities are not declared, so cosseratbench reports such experiments as
unsupported; a scenario with obstacles raises ``NotImplementedError``. Self-contact
requested by a scenario without obstacles (``Scenario.self_contact``) is ignored: the
benchmark's overlap observation shows where rods pass through themselves.
"""
from __future__ import annotations

import math
import warnings

import jax
import numpy as np

from .. import __version__
from ..solvers.dynamics import DynamicSettings, initial_state, simulate
from ..math.lie import log_so3
from ..model.model import build_model
from ..scene.scene import Scene
from ..solvers.statics import solve_static

try:  # the extra: without it, importing this module fails with the missing package named
    from cosseratbench import Capability, Diverged, End, EndCondition, Trajectory
except ImportError as error:  # pragma: no cover - exercised only without the extra
    raise ImportError("simsoft_jax.apps.cosseratbench_solver needs the 'bench' extra: "
                      "pip install 'simsoft_jax[bench]'", name=error.name) from error

RHO_INF = 0.9
STEPS_PER_PERIOD = {True: 40, False: 200}  # keyed by Scenario.quasi_static
_initial_state = jax.jit(initial_state)


def _base_rotation(nodes, normal):
    """Base frame (3,3) of a rod: columns x along the first segment, y the rod's normal
    made perpendicular to it (the benchmark's first director), z = x cross y."""
    x = nodes[1] - nodes[0]
    x = x / np.linalg.norm(x)
    y = np.asarray(normal, float) - np.dot(normal, x) * x
    if np.linalg.norm(y) < 1e-12:
        raise NotImplementedError("a rod's normal is parallel to its first segment")
    y = y / np.linalg.norm(y)
    return np.stack([x, y, np.cross(x, y)], axis=1)


def _end_constraint(rod, name, end, node):
    """The scene constraint of one rod end, or None for a free end."""
    condition, motion = rod.condition(end), rod.motion(end)
    if condition is EndCondition.FREE:
        return None
    if condition is EndCondition.PINNED:
        return {"kind": "pin", "rod": name, "node": node}
    if motion is None:
        return {"kind": "clamp", "rod": name, "node": node}
    drive = {"kind": "drive", "rod": name, "node": node, "times": list(motion.times),
             "displacement": [list(d) for d in motion.displacement],
             "rotation": [list(r) for r in motion.rotation]}
    if motion.slides_along is not None:
        drive["slides_along"] = list(motion.slides_along)
    return drive


def _scene_dict(scenario, n_elements, damping=0.0, dt=None):
    """The scene (a dict, see docs/scene-format.md) of a benchmark scenario: static when
    ``dt`` is None, else dynamic with time step ``dt`` (s) and mass damping ``damping`` (1/s)."""
    if scenario.obstacles:
        raise NotImplementedError("simsoft_jax does not model contact with obstacles")
    rods, constraints, loads = [], [], []
    for i, rod in enumerate(scenario.rods):
        name = f"rod{i}"
        nodes = rod.nodes(n_elements)
        Rb = _base_rotation(nodes, rod.normal)
        m = rod.material
        if m.youngs_modulus / (2.0 * m.shear_modulus) - 1.0 > 0.5 + 1e-9:
            raise NotImplementedError("a shear modulus below E/3 (Poisson's ratio above 0.5) "
                                      "is outside simsoft_jax's isotropic material")
        material = {"E": m.youngs_modulus, "G": m.shear_modulus, "density": m.density}
        if damping:
            material["mass_damping"] = damping
        rods.append({
            "name": name, "material": material, "elements": n_elements,
            "section": {"shape": "circle", "diameter": 2.0 * rod.radius},
            "geometry": {"kind": "straight", "length": rod.length},
            "base": {"position": nodes[0].tolist(),
                     "rotation": np.asarray(log_so3(Rb)).tolist()},
            "initial": {"points": ((nodes - nodes[0]) @ Rb).tolist()}})
        for end, node in ((End.START, 0), (End.END, -1)):
            c = _end_constraint(rod, name, end, node)
            if c is not None:
                constraints.append(c)
        for load in rod.loads:
            loads.append({"kind": "force", "rod": name, "frame": "world",
                          "node": 0 if load.at is End.START else -1,
                          "vector": list(load.force)})
    scene = {"name": "cosseratbench", "rods": rods, "constraints": constraints,
             "loads": loads}
    if dt is None:
        scene["solver"] = {"kind": "static"}
    else:
        scene["solver"] = {"kind": "dynamic", "t_end": scenario.duration, "dt": dt,
                           "rho_inf": RHO_INF}
    if any(scenario.gravity):
        scene["gravity"] = {"vector": list(scenario.gravity)}
    return scene


def _directors(R, p):
    """The benchmark's director d1 of each element (T,E,3): the mean section ``y`` axis of
    its two nodes, made perpendicular to the element's chord and normalised."""
    y = 0.5 * (R[:, :-1, :, 1] + R[:, 1:, :, 1])
    chord = np.diff(p, axis=1)
    chord = chord / np.linalg.norm(chord, axis=2, keepdims=True)
    y = y - np.sum(y * chord, axis=2, keepdims=True) * chord
    return y / np.linalg.norm(y, axis=2, keepdims=True)


def _trajectory(model, times, R, p):
    """A cosseratbench Trajectory from saved states R (T,N,3,3), p (T,N,3)."""
    R, p = np.asarray(R), np.asarray(p)
    positions, directors = [], []
    for info in model.structure.rods:
        nodes = slice(info.first_node, info.first_node + info.nodes)
        positions.append(p[:, nodes])
        directors.append(_directors(R[:, nodes], p[:, nodes]))
    return Trajectory(np.asarray(times), tuple(positions), tuple(directors))


def _moves(scenario):
    return any(rod.start_motion is not None or rod.end_motion is not None
               for rod in scenario.rods)


class SimsoftJaxSolver:
    """cosseratbench adapter (the ``Solver`` protocol): ``run`` returns a Trajectory;
    ``settings`` states the numerical choices made for a scenario."""
    name = "simsoft_jax"
    backend_version = __version__
    capabilities = frozenset({Capability.STRETCH, Capability.SHEAR})

    def __init__(self, time_step_scale: float = 1.0) -> None:
        if not time_step_scale > 0:
            raise ValueError(f"time_step_scale: must be > 0, got {time_step_scale!r}")
        self.time_step_scale = float(time_step_scale)

    def _steps(self, scenario, n_frames):
        """Time step (s) and steps per frame (module docstring)."""
        frame = scenario.duration / (n_frames - 1)
        period = 2.0 * math.pi / scenario.slowest_frequency()
        dt_max = self.time_step_scale * period / STEPS_PER_PERIOD[scenario.quasi_static]
        samples = [np.diff(m.times).min() for rod in scenario.rods
                   for m in (rod.start_motion, rod.end_motion) if m is not None]
        dt_max = min([dt_max] + samples)
        k = max(1, math.ceil(frame / dt_max - 1e-9))
        return frame / k, k

    def _damping(self, scenario):
        """Mass-proportional damping constant (1/s): 2 omega_slow when quasi-static."""
        return 2.0 * scenario.slowest_frequency() if scenario.quasi_static else 0.0

    def _static_model(self, scenario, n_elements):
        """The static model, or None when a static solve cannot stand for the scenario
        (it is dynamic, an end is driven, or the supports leave a rigid motion free)."""
        if not scenario.quasi_static or _moves(scenario):
            return None
        scene = _scene_dict(scenario, n_elements)
        try:
            return build_model(Scene.from_dict(scene))
        except ValueError as error:
            if str(error).startswith("constraints:"):  # a rigid motion is left free
                return None
            raise

    def settings(self, scenario, *, n_elements: int, n_frames: int) -> dict:
        """The numerical choices for a run, as JSON values."""
        if self._static_model(scenario, n_elements) is not None:
            return {"method": "static equilibrium (Newton on SE(3), load continuation)",
                    "elements": "helical SE(3), two-node"}
        dt, _ = self._steps(scenario, n_frames)
        return {"method": "generalized-alpha on SE(3) (implicit)", "rho_inf": RHO_INF,
                "time_step": dt, "mass_damping": self._damping(scenario),
                "elements": "helical SE(3), two-node"}

    def run(self, scenario, *, n_elements: int, n_frames: int):
        times = np.linspace(0.0, scenario.duration, n_frames)
        model = self._static_model(scenario, n_elements)
        if model is not None:
            eq = solve_static(model)
            if not bool(eq.converged):
                raise Diverged(f"static solve failed: {eq.message()}")
            R = np.concatenate([np.asarray(model.R0)[None],
                                np.repeat(np.asarray(eq.R)[None], n_frames - 1, axis=0)])
            p = np.concatenate([np.asarray(model.p0)[None],
                                np.repeat(np.asarray(eq.p)[None], n_frames - 1, axis=0)])
            return _trajectory(model, times, R, p)
        dt, k = self._steps(scenario, n_frames)
        scene = _scene_dict(scenario, n_elements, self._damping(scenario), dt)
        with warnings.catch_warnings():
            # dt is at most the drives' sample spacing (_steps) up to round-off, which
            # the scene's "samples closer than dt" warning would report.
            warnings.filterwarnings("ignore", r"constraints\[\d+\]\.times: samples")
            model = build_model(Scene.from_dict(scene))
        # One compiled step, whatever dt and k: the benchmark's short warm-up run of the
        # same scenario compiles it, so compilation stays out of the timed run.
        settings = DynamicSettings(dt=dt, steps=1, rho_inf=RHO_INF)
        state = _initial_state(model)
        R, p = [state.R], [state.p]
        for _ in range(n_frames - 1):
            for _ in range(k):
                traj = simulate(model, settings, state)
                if not bool(traj.converged):
                    raise Diverged(f"simsoft_jax: {traj.message()}",
                                   time=float(traj.failed_at))
                state = traj.final
            R.append(state.R)
            p.append(state.p)
        return _trajectory(model, times, np.stack(R), np.stack(p))
