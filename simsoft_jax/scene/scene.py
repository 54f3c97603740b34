"""Scene schema: parse, validate, load and save scene files (TOML / JSON / dict).

Plain Python + NumPy (this module never imports JAX): every bad input is rejected here
with ONE ``ValueError`` whose message starts with the offending key path, e.g.
``rods[0].section.width: must be > 0, got -1``.  The file contract is
``shared/spec/scene-format.md``.
"""

from __future__ import annotations

import copy
import dataclasses
import json
import sys
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from .key_checks import (MAX_DEPTH, SpecBase, check_depth, check_keys, choice, describe,
                        fail, index, integer, join, matrix, number, plain, positive,
                        read_table, readable, readonly, require, rotation_vector, short_key,
                        string, table, toml_document, vector)
from .scene_actuators import parse_chambers, parse_tendons
from .scene_attachments import parse_masses, parse_offset
from .scene_contact import check_self_contact, parse_contact, parse_obstacles
from .scene_fields import check_fluid_rods, parse_fluid, parse_magnetic_field
from .scene_mechanisms import check_mechanism, parse_bodies, parse_joints
from .scene_rods import parse_materials, parse_rod
from .scene_limits import (MAX_ELEMENTS, MAX_ITERATIONS, MAX_LOAD_STEPS, MAX_STEPS,
                           MAX_STEPS_LIMIT, check_loads_on_held_nodes,
                           check_point_loads_in_elements, warn_short_features)
from .scene_start import check_start
from .scene_specs import (ConstraintSpec, GeometrySpec, InitialVelocitySpec, LoadSpec,
                          ProfileSpec, RodSpec, SolverSettings)
from .supports import AXES

__all__ = ["SolverSettings", "GeometrySpec", "RodSpec", "ConstraintSpec", "ProfileSpec",
           "LoadSpec", "InitialVelocitySpec", "Scene", "load_scene", "save_scene"]


# ----------------------------------------------------------------------------- scene

@dataclass(frozen=True, eq=False)
class Scene(SpecBase):
    name: str | None
    solver: SolverSettings
    gravity: np.ndarray | None
    rods: tuple[RodSpec, ...]
    constraints: tuple[ConstraintSpec, ...]
    loads: tuple[LoadSpec, ...]
    initial_velocity: tuple[InitialVelocitySpec, ...]
    source: str | None = None
    raw: dict = dataclasses.field(default_factory=dict)
    masses: tuple = ()                # MassSpec per [[masses]] entry
    bodies: tuple = ()                # BodySpec per [[bodies]] entry
    joints: tuple = ()                # JointSpec per [[joints]] entry
    tendons: tuple = ()               # TendonSpec per [[tendons]] entry
    chambers: tuple = ()              # ChamberSpec per [[chambers]] entry
    obstacles: tuple = ()             # ObstacleSpec per [[obstacles]] entry
    contact: object = None            # ContactSpec of [contact] (None: defaults)
    magnetic_field: object = None     # MagneticFieldSpec of [magnetic_field] (None: no field)
    fluid: object = None              # FluidSpec of [fluid] (None: no fluid)

    @classmethod
    def from_dict(cls, d: dict, base_dir: str | Path | None = None) -> "Scene":
        """Validate a scene dictionary; ``base_dir`` resolves table profile files."""
        return _parse_scene(d, Path(base_dir) if base_dir is not None else Path.cwd())

    def to_dict(self) -> dict:
        """The validated input (profile files inlined); ``from_dict`` gives it back."""
        return copy.deepcopy(self.raw)

    def rod(self, name: str) -> RodSpec:
        for rod in self.rods:
            if rod.name == name:
                return rod
        raise ValueError(f"rod {name!r}: no such rod (known: "
                         f"{', '.join(r.name for r in self.rods)})")

    def replace(self, **changes: Any) -> "Scene":
        """``dataclasses.replace``; not re-validated, and ``raw`` / ``to_dict`` keep
        describing the original input."""
        return dataclasses.replace(self, **changes)


# ----------------------------------------------------------------------------- parsing

_TOP_KEYS = ("name", "solver", "gravity", "materials", "rods", "constraints", "loads",
             "initial_velocity", "masses", "bodies", "joints", "tendons", "chambers",
             "obstacles", "contact", "magnetic_field", "fluid")
_SOLVER_KEYS = ("kind", "tolerance", "max_iterations", "load_steps", "level_tolerance",
                "max_load_step", "t_end", "dt", "rho_inf", "save_every", "inertia", "tangent",
                "max_steps")
_PROFILE_KEYS = {"constant": (), "ramp": ("t0", "t1"), "smoothstep": ("t0", "t1"),
                 "linear": ("rate",), "table": ("t", "scale", "file")}


def _array_of_tables(d: dict, key: str) -> list[dict]:
    items = d.get(key, [])
    if not isinstance(items, list):
        fail(key, f"must be an array of tables, got {type(items).__name__}")
    for i, item in enumerate(items):
        table(item, index(key, i))
    return items


def _parse_scene(d: Any, base_dir: Path) -> Scene:
    check_depth(d)
    raw = plain(table(d, "", "a scene table (dict)"))
    check_keys(raw, "", _TOP_KEYS, required=("solver", "rods"))
    name = string(raw["name"], "name") if "name" in raw else None
    solver = _parse_solver(raw["solver"])
    gravity = None
    if "gravity" in raw:
        g = table(raw["gravity"], "gravity")
        check_keys(g, "gravity", ("vector",), required=("vector",))
        gravity = readonly(vector(g["vector"], "gravity.vector"))

    materials = parse_materials(_array_of_tables(raw, "materials"))
    rod_items = _array_of_tables(raw, "rods")
    if not rod_items:
        fail("rods", "must contain at least one rod")
    rods: dict[str, RodSpec] = {}
    for i, item in enumerate(rod_items):
        rod = parse_rod(item, index("rods", i), materials, base_dir)
        if rod.name in rods:
            fail(index("rods", i) + ".name", f"duplicate rod name {rod.name!r}")
        rods[rod.name] = rod
        total = sum(r.elements for r in rods.values())
        if total > MAX_ELEMENTS:
            fail(index("rods", i) + ".elements", f"the scene's rods have {total} elements "
                 f"in all, more than the limit {MAX_ELEMENTS}")

    constraints = _parse_constraints(_array_of_tables(raw, "constraints"), rods)
    loads = tuple(_parse_load(item, index("loads", i), rods, base_dir)
                  for i, item in enumerate(_array_of_tables(raw, "loads")))
    velocities = _parse_velocities(_array_of_tables(raw, "initial_velocity"), rods)
    masses = parse_masses(_array_of_tables(raw, "masses"), rods, _node)
    bodies = parse_bodies(_array_of_tables(raw, "bodies"), rods)
    joints = parse_joints(_array_of_tables(raw, "joints"), rods, bodies, _node)
    check_mechanism(solver.kind, bodies, joints, constraints)
    profile = lambda value, path: _parse_profile(value, path, base_dir)  # noqa: E731
    tendons = parse_tendons(_array_of_tables(raw, "tendons"), rods, joints, profile)
    chambers = parse_chambers(_array_of_tables(raw, "chambers"), rods, profile)
    obstacles = parse_obstacles(_array_of_tables(raw, "obstacles"), profile,
                                solver.kind == "dynamic")
    contact = parse_contact(raw["contact"]) if "contact" in raw else None
    magnetic_field = (parse_magnetic_field(raw["magnetic_field"], profile)
                      if "magnetic_field" in raw else None)
    fluid = parse_fluid(raw["fluid"]) if "fluid" in raw else None
    check_fluid_rods(fluid, rods.values())
    check_self_contact(contact, [o.name for o in obstacles])
    if solver.kind == "dynamic":
        warn_short_features(loads, constraints, solver.dt)
    check_loads_on_held_nodes(raw.get("loads", []), loads, constraints)
    check_point_loads_in_elements(raw.get("loads", []), loads)
    if solver.kind == "static":
        for i, c in enumerate(constraints):
            if c.kind == "drive" and (np.any(c.displacement) or np.any(c.rotation)):
                fail(index("constraints", i), "a static solve cannot follow a drive's "
                     "displacement or rotation (it would hold the node where it starts); "
                     "use a clamp at the driven pose (base or initial), or solver.kind = "
                     "\"dynamic\"")
    scene = Scene(name=name, solver=solver, gravity=gravity, rods=tuple(rods.values()),
                  constraints=constraints, loads=loads, initial_velocity=velocities,
                  source=None, raw=raw, masses=masses, bodies=bodies, joints=joints,
                  tendons=tendons, chambers=chambers, obstacles=obstacles, contact=contact,
                  magnetic_field=magnetic_field, fluid=fluid)
    check_start(scene)
    return scene


def _parse_solver(value: Any) -> SolverSettings:
    s = table(value, "solver")
    check_keys(s, "solver", _SOLVER_KEYS, required=("kind",))
    kind = choice(s["kind"], "solver.kind", ("static", "dynamic"))
    out: dict[str, Any] = {"kind": kind}
    if "tolerance" in s:
        out["tolerance"] = positive(s["tolerance"], "solver.tolerance")
        if out["tolerance"] >= 1.0:
            fail("solver.tolerance", f"must be < 1 (a relative tolerance), got {s['tolerance']}")
    for key, most in (("max_iterations", MAX_ITERATIONS), ("load_steps", MAX_LOAD_STEPS),
                      ("save_every", MAX_STEPS_LIMIT)):
        if key in s:
            out[key] = integer(s[key], join("solver", key), minimum=1, maximum=most)
    if "level_tolerance" in s:
        out["level_tolerance"] = number(s["level_tolerance"], "solver.level_tolerance")
        if not 0.0 <= out["level_tolerance"] < 1.0:
            fail("solver.level_tolerance", "must be in [0, 1) (a relative tolerance), got "
                 f"{s['level_tolerance']}")
    if "max_load_step" in s:
        out["max_load_step"] = positive(s["max_load_step"], "solver.max_load_step")
        if out["max_load_step"] > 1.0:
            fail("solver.max_load_step", "must be in (0, 1] (a fraction of the full loads), "
                 f"got {s['max_load_step']}")
    for key in ("t_end", "dt"):
        if key in s:
            out[key] = positive(s[key], join("solver", key))
        elif kind == "dynamic":
            require(s, "solver", key)
    if "dt" in out and "t_end" in out and out["dt"] > out["t_end"]:
        fail("solver.dt", f"must be <= solver.t_end ({out['t_end']}), got {out['dt']}")
    limit = integer(s.get("max_steps", MAX_STEPS), "solver.max_steps", minimum=1,
                    maximum=MAX_STEPS_LIMIT)
    if "dt" in out and "t_end" in out and out["t_end"] / out["dt"] > limit:
        fail("solver.dt", f"t_end / dt = {out['t_end'] / out['dt']:.4g} time steps, more "
             f"than solver.max_steps ({limit}); increase dt, or raise solver.max_steps "
             "to allow the run (its time and memory grow with the steps)")
    if "rho_inf" in s:
        out["rho_inf"] = number(s["rho_inf"], "solver.rho_inf")
        if not 0.0 <= out["rho_inf"] <= 1.0:
            fail("solver.rho_inf", f"must be in [0, 1], got {out['rho_inf']}")
    if "inertia" in s:
        out["inertia"] = choice(s["inertia"], "solver.inertia", ("consistent", "lumped"))
    if "tangent" in s:
        out["tangent"] = choice(s["tangent"], "solver.tangent", ("closed_form", "autodiff"))
    return SolverSettings(**out)


def _rod_of(item: dict, path: str, rods: dict[str, RodSpec]) -> RodSpec:
    name = string(require(item, path, "rod"), join(path, "rod"))
    if name not in rods:
        fail(join(path, "rod"), f"no rod named {name!r} (known: {', '.join(rods)})")
    return rods[name]


def _node(item: dict, path: str, rod: RodSpec) -> int:
    """Resolve ``node`` (negative counts from the end) or ``s`` (arc length) to an index:
    the nearest node, with a warning when ``s`` is not on a node."""
    if ("node" in item) == ("s" in item):
        fail(path, "give exactly one of node, s")
    n = rod.nodes
    if "node" in item:
        node = integer(item["node"], join(path, "node"))
        if not -n <= node < n:
            fail(join(path, "node"), f"out of range for rod {rod.name!r} with {n} nodes "
                 f"(allowed {-n}..{n - 1}), got {node}")
        return node % n
    x = _arc_position(item, path, rod)
    node = int(round(x))
    if abs(x - node) > 1e-9:
        arc = rod.node_arc()
        warnings.warn(f"{join(path, 's')} = {item['s']:g} m lies between nodes; it is placed "
                      f"at the nearest node {node} (s = {arc[node]:.6g} m, "
                      f"{abs(item['s'] - arc[node]):.3g} m away). To place it exactly, put a "
                      "node there: rods[].segments with their length", stacklevel=2)
    return node


def _arc_position(item: dict, path: str, rod: RodSpec) -> float:
    """``s`` (arc length) in element units: node ``k`` plus the fraction of element ``k``
    (``s / L * elements`` when the elements are equal)."""
    s = number(item["s"], join(path, "s"))
    length = rod.geometry.arc_length
    if not -1e-12 * length <= s <= length * (1.0 + 1e-12):
        fail(join(path, "s"), f"must be in [0, {length:g}] (rod {rod.name!r} arc length), "
             f"got {s}")
    s = min(max(s, 0.0), length)
    if rod.segments and rod.segments[0].length is not None:
        return float(np.interp(s, rod.node_arc(), np.arange(rod.nodes)))
    return s / length * rod.elements


def _load_place(ld: dict, path: str, rod: RodSpec) -> dict[str, Any]:
    """Where a point load acts: ``node``, or for ``s`` between two nodes its element and
    ``xi = (s - s_A)/L_e`` (spec S38: distributed onto the element, not rounded); ``s``
    within 1e-12 (element units) of a node acts on that node."""
    if "s" not in ld or "node" in ld:
        return {"node": _node(ld, path, rod)}
    x = _arc_position(ld, path, rod)
    node = round(x)
    if abs(x - node) <= 1e-12:
        return {"node": int(node)}
    element = min(int(np.floor(x)), rod.elements - 1)
    return {"node": None, "element": element, "xi": x - element}


def _parse_constraints(items: list[dict], rods: dict[str, RodSpec]) -> tuple:
    out: list[ConstraintSpec] = []
    taken: dict[tuple[str, int], str] = {}
    for i, c in enumerate(items):
        path = index("constraints", i)
        kind = choice(require(c, path, "kind"), join(path, "kind"),
                      ("clamp", "pin", "hinge", "drive"))
        extra = (("times", "displacement", "rotation", "slides_along") if kind == "drive"
                 else ("axis",) if kind == "hinge" else ())
        check_keys(c, path, ("kind", "rod", "node", "s", *extra),
                   required=("rod", "axis") if kind == "hinge" else ("rod",))
        rod = _rod_of(c, path, rods)
        node = _node(c, path, rod)
        where = join(path, "node" if "node" in c else "s")
        if (rod.name, node) in taken:
            fail(where, f"node {node} of rod {rod.name!r} is already constrained by "
                 f"{taken[rod.name, node]}")
        taken[rod.name, node] = path
        fields: dict[str, Any] = {}
        if kind == "drive":
            fields = _parse_drive(c, path)
        elif kind == "hinge":
            fields = {"axis": choice(c["axis"], join(path, "axis"), AXES)}
        out.append(ConstraintSpec(kind=kind, rod=rod.name, node=node, **fields))
    return tuple(out)


def _parse_drive(c: dict, path: str) -> dict[str, Any]:
    tpath = join(path, "times")
    times = vector(require(c, path, "times"), tpath, None, min_len=1)
    if np.any(np.diff(times) <= 0.0):
        fail(tpath, "must be strictly increasing")
    samples = len(times)
    if "displacement" not in c and "rotation" not in c:
        fail(path, "a drive needs displacement and/or rotation samples")
    disp, rot = np.zeros((samples, 3)), np.zeros((samples, 3))
    if "displacement" in c:
        disp = matrix(c["displacement"], join(path, "displacement"), 3)
    if "rotation" in c:
        rpath = join(path, "rotation")
        rows = c["rotation"]
        if not isinstance(rows, list):
            fail(rpath, "must be a list of rotations (one per time)")
        rot = np.array([rotation_vector(row, index(rpath, j)) for j, row in enumerate(rows)])
    for key, arr in (("displacement", disp), ("rotation", rot)):
        if len(arr) != samples:
            fail(join(path, key), f"must have one row per time ({samples}), got {len(arr)}")
    slides = None
    if "slides_along" in c:
        spath = join(path, "slides_along")
        slides = vector(c["slides_along"], spath)
        norm = float(np.linalg.norm(slides))
        if norm == 0.0:
            fail(spath, "must not be the zero vector")
        slides = readonly(slides / norm)
    return dict(times=readonly(times), displacement=readonly(disp),
                rotation=readonly(rot.reshape(samples, 3)), slides_along=slides)


def _parse_load(ld: dict, path: str, rods: dict[str, RodSpec], base_dir: Path) -> LoadSpec:
    kind = choice(require(ld, path, "kind"), join(path, "kind"),
                  ("force", "moment", "distributed_force"))
    where = () if kind == "distributed_force" else ("node", "s")
    check_keys(ld, path, ("kind", "rod", *where, "vector", "frame", "profile", "offset"),
               required=("rod", "vector"))
    rod = _rod_of(ld, path, rods)
    place = {"node": None} if kind == "distributed_force" else _load_place(ld, path, rod)
    vec = vector(ld["vector"], join(path, "vector"))
    frame = choice(ld.get("frame", "world"), join(path, "frame"), ("world", "local"))
    profile = _parse_profile(ld.get("profile", {"kind": "constant"}), join(path, "profile"),
                             base_dir)
    if profile.kind == "table" and "file" in ld.get("profile", {}):
        ld["profile"] = {"kind": "table", "t": profile.t.tolist(),
                         "scale": profile.scale.tolist()}  # keep raw self-contained
    offset = parse_offset(ld, path, kind, frame, profile.kind, place.get("element") is not None)
    return LoadSpec(kind=kind, rod=rod.name, vector=readonly(vec), frame=frame,
                    profile=profile, offset=readonly(offset), **place)


def _parse_profile(value: Any, path: str, base_dir: Path) -> ProfileSpec:
    p = table(value, path)
    kind = choice(require(p, path, "kind"), join(path, "kind"), tuple(_PROFILE_KEYS))
    check_keys(p, path, ("kind", *_PROFILE_KEYS[kind]))
    if kind in ("ramp", "smoothstep"):
        t0 = number(p.get("t0", 0.0), join(path, "t0"))
        if t0 < 0.0:
            fail(join(path, "t0"), f"must be >= 0, got {t0}")
        t1 = number(require(p, path, "t1"), join(path, "t1"))
        if t1 <= t0:
            fail(join(path, "t1"), f"must be > t0 ({t0}), got {t1}")
        return ProfileSpec(kind, t0=t0, t1=t1)
    if kind == "linear":
        return ProfileSpec(kind, rate=number(require(p, path, "rate"), join(path, "rate")))
    if kind == "constant":
        return ProfileSpec(kind)
    if "file" in p:
        if "t" in p or "scale" in p:
            fail(join(path, "file"), "give either file or t and scale, not both")
        t, scale = read_table(p["file"], join(path, "file"), base_dir)
        tpath = join(path, "file")
    else:
        require(p, path, "t")
        require(p, path, "scale")
        tpath = join(path, "t")
        t = vector(p["t"], tpath, None, min_len=1)
        scale = vector(p["scale"], join(path, "scale"), None, min_len=1)
        if len(scale) != len(t):
            fail(join(path, "scale"), f"must have as many entries as t ({len(t)}), "
                 f"got {len(scale)}")
    if np.any(np.diff(t) <= 0.0):
        fail(tpath, "must be strictly increasing" if tpath.endswith(".t")
             else "the t column must be strictly increasing")
    return ProfileSpec(kind, t=readonly(t), scale=readonly(scale))


def _parse_velocities(items: list[dict], rods: dict[str, RodSpec]) -> tuple:
    out: list[InitialVelocitySpec] = []
    seen: set[str] = set()
    for i, v in enumerate(items):
        path = index("initial_velocity", i)
        check_keys(v, path, ("rod", "linear", "angular"), required=("rod",))
        rod = _rod_of(v, path, rods)
        if rod.name in seen:
            fail(join(path, "rod"), f"rod {rod.name!r} already has an initial velocity")
        seen.add(rod.name)
        if rod.initial_velocities is not None:
            fail(join(path, "rod"), f"rod {rod.name!r} restarts with the velocities saved in "
                 "its initial.result; give one or the other")
        linear = vector(v.get("linear", [0.0, 0.0, 0.0]), join(path, "linear"))
        angular = vector(v.get("angular", [0.0, 0.0, 0.0]), join(path, "angular"))
        out.append(InitialVelocitySpec(rod.name, readonly(linear), readonly(angular)))
    return tuple(out)


# ----------------------------------------------------------------------------- files

def _unique_keys(pairs: list) -> dict:
    """A JSON object from its ``(key, value)`` pairs, refusing a key given twice (the
    TOML reader refuses it too; JSON readers would keep the last value silently)."""
    out = {}
    for key, value in pairs:
        if key in out:
            raise ValueError(f"the key {short_key(key)!r} appears twice in one object "
                             "(give each key once)")
        out[key] = value
    return out


def load_scene(path: str | Path) -> Scene:
    """Read and validate a ``.toml`` or ``.json`` scene file."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in (".toml", ".json"):
        raise ValueError(readable(f"{path}: unsupported scene file type {path.suffix!r} "
                                  "(use .toml or .json)"))
    try:
        if suffix == ".json":
            with open(path, encoding="utf-8") as fh:
                data = json.load(fh, object_pairs_hook=_unique_keys)
        else:
            if sys.version_info >= (3, 11):
                import tomllib
            else:  # pragma: no cover
                import tomli as tomllib
            with open(path, "rb") as fh:
                data = tomllib.load(fh)
    except OSError as err:
        raise ValueError(readable(f"{path}: cannot read scene file: "
                                  f"{err.strerror or err}")) from None
    except ValueError as err:  # JSONDecodeError and TOMLDecodeError are ValueErrors
        raise ValueError(readable(f"{path}: not valid {suffix[1:].upper()}: {err}")) from None
    except RecursionError:  # the parsers recurse per nesting level
        raise ValueError(readable(f"{path}: nested too deeply to read (a scene may nest "
                                  f"tables and arrays at most {MAX_DEPTH} levels deep)")) \
            from None
    if not isinstance(data, dict):
        raise ValueError(readable(f"{path}: must hold a scene table (an object of keys), "
                                  f"got {describe(data)}"))
    scene = Scene.from_dict(data, base_dir=path.parent)
    return dataclasses.replace(scene, source=str(path))


def save_scene(scene: Scene, path: str | Path) -> None:
    """Write ``scene.to_dict()`` as ``.json`` or ``.toml``."""
    path = Path(path)
    suffix = path.suffix.lower()
    data = scene.to_dict()
    if suffix == ".json":
        path.write_text(json.dumps(data, indent=2) + "\n", encoding="utf-8")
    elif suffix == ".toml":
        path.write_text(toml_document(data), encoding="utf-8")
    else:
        raise ValueError(f"{path}: unsupported scene file type {path.suffix!r} "
                         "(use .toml or .json)")
