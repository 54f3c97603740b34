"""Scene parsing of rigid obstacles (``[[obstacles]]``) and of the ``[contact]`` table, and
their model tables: plain Python + NumPy, errors naming the key path (contract in
``docs/scene-format.md``; the physics in :mod:`simsoft_jax.terms.contact`)."""
from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from ._validate import (SpecBase, check_keys, choice, fail, index, integer, join, number,
                        positive, readonly, require, string, table, vector)

OBSTACLE_KEYS = {"plane": ("point", "normal"), "sphere": ("center", "radius"),
                 "capsule": ("a", "b", "radius"), "cylinder": ("axis_point", "axis", "radius"),
                 "tube": ("axis_point", "axis", "radius")}
KINDS = tuple(OBSTACLE_KEYS)      # obstacle kinds (simsoft_jax.obstacles)
CONTACT_KEYS = ("radius", "self", "stiffness", "slip_velocity", "quadrature_points",
                "self_exclusion", "max_pairs")
STIFFNESS_FACTOR = 1.0e3       # default penalty: 1e3 EI / h^4 per element
SLIP_VELOCITY = 1.0e-3         # m/s, default slip-velocity scale of the friction
QUADRATURE_POINTS = 4
SELF_NAME = "rods"             # the rod-rod entry of the result's contacts
MAX_PAIRS = 8                  # default capacity of the rod-rod narrow phase (element pairs)


@dataclass(frozen=True, eq=False)
class ObstacleSpec(SpecBase):
    name: str
    kind: str                  # one of obstacles.KINDS
    params: np.ndarray         # (7,) parameter row (simsoft_jax.obstacles)
    friction: float            # Coulomb coefficient, >= 0


@dataclass(frozen=True, eq=False)
class ContactSpec(SpecBase):
    radius: float | None = None           # m; None: per rod, or the section's outer radius
    stiffness: float | None = None        # N/m^2; None: STIFFNESS_FACTOR EI / h^4
    slip_velocity: float = SLIP_VELOCITY  # m/s
    quadrature_points: int = QUADRATURE_POINTS
    self_contact: bool = False            # rod-rod and self contact ([contact] self)
    self_exclusion: float | None = None   # m; None: 2 pi max(contact radius)
    max_pairs: int = MAX_PAIRS            # element pairs the narrow phase holds


def parameter_row(kind: str, values: dict) -> list:
    """The parameter row (7,) of an obstacle (layout in :mod:`simsoft_jax.obstacles`): its
    first point, its second point or direction (zeros for a sphere), its radius (0 for a
    plane), from the validated ``values`` by key."""
    keys = OBSTACLE_KEYS[kind]
    vectors = [list(values[k]) for k in keys if k != "radius"] + [[0.0, 0.0, 0.0]]
    return vectors[0] + vectors[1] + [values.get("radius", 0.0)]


def parse_obstacles(items: list) -> tuple:
    """``[[obstacles]]`` -> ObstacleSpec tuple (keys per kind: ``OBSTACLE_KEYS``; normals
    and axes non-zero, a capsule's ends apart, radii > 0, friction >= 0, names unique)."""
    out, names = [], set()
    for i, item in enumerate(items):
        path = index("obstacles", i)
        kind = choice(require(item, path, "kind"), join(path, "kind"), KINDS)
        keys = OBSTACLE_KEYS[kind]
        check_keys(item, path, ("name", "kind", "friction", *keys), required=("name", *keys))
        name = string(item["name"], join(path, "name"))
        if not name or name in names:
            fail(join(path, "name"), f"must be a unique non-empty name, got {name!r}")
        names.add(name)
        values = {}
        for key in keys:
            kpath = join(path, key)
            values[key] = positive(item[key], kpath) if key == "radius" else vector(item[key],
                                                                                     kpath)
            if key in ("normal", "axis") and not np.any(values[key]):
                fail(kpath, "must be a non-zero vector")
        if kind == "capsule" and np.array_equal(values["a"], values["b"]):
            fail(join(path, "b"), "must differ from a (a capsule's two ends)")
        friction = number(item.get("friction", 0.0), join(path, "friction"))
        if friction < 0.0:
            fail(join(path, "friction"), f"must be >= 0, got {friction}")
        out.append(ObstacleSpec(name, kind, readonly(np.asarray(parameter_row(kind, values),
                                                                float)), friction))
    return tuple(out)


def warn_static_friction(obstacles: tuple, kind: str) -> None:
    """A static scene with friction > 0: a warning that statics ignores it (regularized
    Coulomb acts in dynamic runs; quasi-static friction is not supported yet)."""
    if kind != "static":
        return
    for i, o in enumerate(obstacles):
        if o.friction > 0.0:
            warnings.warn(f"obstacles[{i}].friction: static solves ignore friction (it acts "
                          "in dynamic runs only)", stacklevel=3)


def parse_contact(value) -> ContactSpec:
    """``[contact]`` -> ContactSpec (``self``: a bool; ``self_exclusion`` > 0,
    ``max_pairs`` >= 1 only with ``self = true``)."""
    c = table(value, "contact")
    check_keys(c, "contact", CONTACT_KEYS)
    args = {"self_contact": c.get("self", False)}
    if not isinstance(args["self_contact"], bool):
        fail("contact.self", f"must be true or false, got {c['self']!r}")
    for key in ("self_exclusion", "max_pairs"):
        if key in c and not args["self_contact"]:
            fail(join("contact", key), "only with contact.self = true")
    for key in ("radius", "stiffness", "slip_velocity", "self_exclusion"):
        if key in c:
            args[key] = positive(c[key], join("contact", key))
    for key in ("quadrature_points", "max_pairs"):
        if key in c:
            args[key] = integer(c[key], join("contact", key), minimum=1)
    return ContactSpec(**args)


def check_self_contact(contact, kind: str, mechanisms: bool, obstacle_names) -> None:
    """Rod-rod contact is solved in static scenes without joints or bodies; its result
    entry ``contacts.rods`` must not clash with an obstacle's name."""
    if contact is None or not contact.self_contact:
        return
    if kind != "static":
        fail("contact.self", "rod-rod contact is supported in static solves only")
    if mechanisms:
        fail("contact.self", "rod-rod contact is not supported with joints or bodies")
    if SELF_NAME in obstacle_names:
        fail("contact.self", f"an obstacle is named {SELF_NAME!r}, the name of the "
             "rod-rod entry of the result's contacts")


def _section_radius(rod) -> float | None:
    section = rod.section
    if section is None or section.shape not in ("circle", "tube"):
        return None
    dims = section.dimensions
    return 0.5 * dims.get("diameter", dims.get("outer_diameter"))


def contact_tables(scene, stiffness, length):
    """Model tables of the contact: per element radius (E,) m and penalty stiffness (E,)
    N/m^2, obstacle rows (K,7) and friction (K,), the self-contact exclusion arclength
    () m, from the scene's rods, ``[contact]`` and
    obstacles; ``stiffness`` (E,6) or (E,6,6) and ``length`` (E,) the element tables (the
    default penalty is ``STIFFNESS_FACTOR max(EIy, EIz) / h^4``)."""
    spec = getattr(scene, "contact", None) or ContactSpec()
    obstacles = getattr(scene, "obstacles", ())
    radius = []
    for i, rod in enumerate(scene.rods):
        r = getattr(rod, "contact_radius", None) or spec.radius or _section_radius(rod)
        if r is None and (obstacles or spec.self_contact):
            fail("contact.radius", f"required: rod {rod.name!r} has no circular section to "
                 f"take it from (or set rods[{i}].contact_radius)")
        radius += [r or 0.0] * rod.elements
    K = np.asarray(stiffness)
    EI = np.maximum(K[:, 4, 4], K[:, 5, 5]) if K.ndim == 3 else np.maximum(K[:, 4], K[:, 5])
    k = (np.full(len(length), spec.stiffness) if spec.stiffness is not None
         else STIFFNESS_FACTOR * EI / np.asarray(length) ** 4)
    rows = np.reshape([o.params for o in obstacles], (-1, 7))
    exclusion = (spec.self_exclusion if spec.self_exclusion is not None
                 else 2.0 * np.pi * max(radius, default=0.0))
    return dict(self_exclusion=exclusion, contact_radius=np.asarray(radius, float), contact_stiffness=k,
                obstacles=rows, obstacle_friction=np.array([o.friction for o in
                                                            obstacles], float),
                slip_velocity=spec.slip_velocity)
