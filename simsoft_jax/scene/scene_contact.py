"""Scene parsing of rigid obstacles (``[[obstacles]]``) and of the ``[contact]`` table, and
their model tables: plain Python + NumPy, errors naming the key path (contract in
``docs/scene-format.md``; the physics in :mod:`simsoft_jax.physics.terms.contact`)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .key_checks import (SpecBase, check_keys, choice, fail, index, integer, join, number,
                        positive, readonly, require, string, table, vector)
from .scene_specs import ProfileSpec

# slot of each key in the parameter row (simsoft_jax.physics.obstacles), per kind
SLOTS = {"plane": {"point": 0, "normal": 3}, "sphere": {"center": 0, "radius": 6},
         "capsule": {"a": 0, "b": 3, "radius": 6},
         "cylinder": {"axis_point": 0, "axis": 3, "radius": 6},
         "tube": {"axis_point": 0, "axis": 3, "radius": 6},
         "curved_tube": {"center": 0, "normal": 3, "radius": 6, "start": 7, "angle": 10}}
OBSTACLE_KEYS = {kind: tuple(slots) for kind, slots in SLOTS.items()}
KINDS = tuple(OBSTACLE_KEYS)      # obstacle kinds (simsoft_jax.physics.obstacles)
ROW = 11                          # length of an obstacle's parameter row
MOTION_KEYS = ("displacement", "profile")
CONTACT_KEYS = ("radius", "self", "stiffness", "slip_velocity", "slip_displacement",
                "quadrature_points", "self_exclusion", "max_pairs", "friction_law",
                "damping_ratio")
STIFFNESS_FACTOR = 1.0e3       # default penalty: 1e3 EI / h^4 per element
SLIP_VELOCITY = 1.0e-3         # m/s, default slip-velocity scale of the friction
SLIP_FRACTION = 1.0e-3         # default slip-displacement scale (statics) / contact radius
QUADRATURE_POINTS = 4
FRICTION_LAWS = ("regularized", "stick_slip")   # [contact] friction_law (dynamics)
SELF_NAME = "rods"             # the rod-rod entry of the result's contacts
MAX_PAIRS = 8                  # default capacity of the rod-rod narrow phase (element pairs)
MOST_QUADRATURE_POINTS = 64    # the largest contact.quadrature_points accepted
MOST_DAMPING_RATIO = 100.0     # the largest contact.damping_ratio accepted
MOST_PAIRS = 1_000             # the largest contact.max_pairs (a dense solve of 6 (2 n + 2))


@dataclass(frozen=True, eq=False)
class ObstacleSpec(SpecBase):
    name: str
    kind: str                  # one of obstacles.KINDS
    params: np.ndarray         # (ROW,) parameter row (simsoft_jax.physics.obstacles)
    friction: float            # Coulomb coefficient, >= 0
    displacement: np.ndarray | None = None   # (3,) m, world: motion at profile scale 1
    profile: object = None     # ProfileSpec of the motion (None: fixed obstacle)


@dataclass(frozen=True, eq=False)
class ContactSpec(SpecBase):
    radius: float | None = None           # m; None: per rod, or the section's outer radius
    stiffness: float | None = None        # N/m^2; None: STIFFNESS_FACTOR EI / h^4
    slip_velocity: float = SLIP_VELOCITY  # m/s
    slip_displacement: float | None = None  # m; None: SLIP_FRACTION times the radius
    quadrature_points: int = QUADRATURE_POINTS
    self_contact: bool = False            # rod-rod and self contact ([contact] self)
    self_exclusion: float | None = None   # m; None: 2 pi max(contact radius)
    max_pairs: int = MAX_PAIRS            # element pairs the narrow phase holds
    friction_law: str = "regularized"     # dynamics: "regularized" | "stick_slip"
    damping_ratio: float = 0.0            # dynamics: normal contact damping ratio zeta


def parameter_row(kind: str, values: dict) -> np.ndarray:
    """The parameter row (ROW,) of an obstacle (layout in :mod:`simsoft_jax.physics.obstacles`)
    from the validated ``values`` by key (unused slots 0)."""
    row = np.zeros(ROW)
    for key, slot in SLOTS[kind].items():
        value = np.atleast_1d(values[key])
        row[slot:slot + len(value)] = value
    return row


def _check_curved_tube(values: dict, path: str) -> None:
    """A curved tube's ``start`` off ``center``, in the plane normal to ``normal``, its
    radius below the bend radius, its ``angle`` in (0, 2 pi)."""
    r0 = np.asarray(values["start"]) - values["center"]
    bend = np.linalg.norm(r0)
    if bend == 0.0:
        fail(join(path, "start"), "must differ from center (the bend radius is |start - "
             "center|)")
    if abs(np.dot(r0, values["normal"])) > 1e-9 * bend * np.linalg.norm(values["normal"]):
        fail(join(path, "start"), "start - center must be normal to the arc's normal")
    if values["radius"] >= bend:
        fail(join(path, "radius"), f"must be below the bend radius |start - center| = "
             f"{bend:g}, got {values['radius']}")
    if not 0.0 < values["angle"] < 2.0 * np.pi:
        fail(join(path, "angle"), f"must be in (0, 2 pi) rad, got {values['angle']}")


def _parse_motion(value, path: str, profile, dynamic: bool):
    """``motion = {displacement, profile}`` -> ((3,) m, ProfileSpec); a static scene is
    rejected (a static solve cannot follow a time law)."""
    m = table(value, path)
    check_keys(m, path, MOTION_KEYS, required=MOTION_KEYS)
    if not dynamic:
        fail(path, "a static solve cannot follow an obstacle's motion; use solver.kind = "
             "\"dynamic\" (or place the obstacle where it should be)")
    return (vector(m["displacement"], join(path, "displacement")),
            profile(m["profile"], join(path, "profile")))


def parse_obstacles(items: list, profile=None, dynamic: bool = False) -> tuple:
    """``[[obstacles]]`` -> ObstacleSpec tuple (keys per kind: ``OBSTACLE_KEYS``; normals
    and axes non-zero, a capsule's ends apart, radii > 0, a curved tube's geometry
    consistent, friction >= 0, names unique; ``motion`` parsed with ``profile(value,
    path)`` (the scene's time-law parser), dynamic scenes only)."""
    out, names = [], set()
    for i, item in enumerate(items):
        path = index("obstacles", i)
        kind = choice(require(item, path, "kind"), join(path, "kind"), KINDS)
        keys = OBSTACLE_KEYS[kind]
        check_keys(item, path, ("name", "kind", "friction", "motion", *keys),
                   required=("name", *keys))
        name = string(item["name"], join(path, "name"))
        if not name or name in names:
            fail(join(path, "name"), f"must be a unique non-empty name, got {name!r}")
        names.add(name)
        values = {}
        for key in keys:
            kpath = join(path, key)
            values[key] = (positive(item[key], kpath) if key in ("radius", "angle")
                           else vector(item[key], kpath))
            if key in ("normal", "axis") and not np.any(values[key]):
                fail(kpath, "must be a non-zero vector")
        if kind == "capsule" and np.array_equal(values["a"], values["b"]):
            fail(join(path, "b"), "must differ from a (a capsule's two ends)")
        if kind == "curved_tube":
            _check_curved_tube(values, path)
        friction = number(item.get("friction", 0.0), join(path, "friction"))
        if friction < 0.0:
            fail(join(path, "friction"), f"must be >= 0, got {friction}")
        motion = (_parse_motion(item["motion"], join(path, "motion"), profile, dynamic)
                  if "motion" in item else (None, None))
        out.append(ObstacleSpec(name, kind, readonly(parameter_row(kind, values)), friction,
                                *motion))
    return tuple(out)


def parse_contact(value) -> ContactSpec:
    """``[contact]`` -> ContactSpec (``self``: a bool; ``self_exclusion`` > 0,
    ``max_pairs`` >= 1 only with ``self = true``; ``damping_ratio`` in [0, 100])."""
    c = table(value, "contact")
    check_keys(c, "contact", CONTACT_KEYS)
    args = {"self_contact": c.get("self", False)}
    if not isinstance(args["self_contact"], bool):
        fail("contact.self", f"must be true or false, got {c['self']!r}")
    for key in ("self_exclusion", "max_pairs"):
        if key in c and not args["self_contact"]:
            fail(join("contact", key), "only with contact.self = true")
    for key in ("radius", "stiffness", "slip_velocity", "slip_displacement", "self_exclusion"):
        if key in c:
            args[key] = positive(c[key], join("contact", key))
    if "damping_ratio" in c:
        args["damping_ratio"] = number(c["damping_ratio"], "contact.damping_ratio")
        if not 0.0 <= args["damping_ratio"] <= MOST_DAMPING_RATIO:
            fail("contact.damping_ratio", f"must be in [0, {MOST_DAMPING_RATIO:g}] (the "
                 f"damping ratio of the normal contact), got {c['damping_ratio']}")
    if "friction_law" in c:
        args["friction_law"] = choice(c["friction_law"], "contact.friction_law",
                                      FRICTION_LAWS)
    for key, most in (("quadrature_points", MOST_QUADRATURE_POINTS),
                      ("max_pairs", MOST_PAIRS)):
        if key in c:
            args[key] = integer(c[key], join("contact", key), minimum=1, maximum=most)
    return ContactSpec(**args)


def check_self_contact(contact, obstacle_names) -> None:
    """Rod-rod contact's result entry ``contacts.rods`` must not clash with an obstacle's
    name."""
    if contact is None or not contact.self_contact:
        return
    if SELF_NAME in obstacle_names:
        fail("contact.self", f"an obstacle is named {SELF_NAME!r}, the name of the "
             "rod-rod entry of the result's contacts")


def _section_radius(rod) -> float | None:
    section = rod.section
    if section is None or section.shape not in ("circle", "tube"):
        return None
    dims = section.dimensions
    return 0.5 * dims.get("diameter", dims.get("outer_diameter"))


def contact_radius(rod, spec) -> float | None:
    """Contact radius (m) of a RodSpec: its ``contact_radius``, else ``[contact].radius``
    (``spec``, a ContactSpec), else its circular section's; None when none applies."""
    return getattr(rod, "contact_radius", None) or spec.radius or _section_radius(rod)


def check_contact_radius(rods, spec, obstacles: bool) -> None:
    """With obstacles or self-contact, every rod (RodSpecs, scene order) needs a contact
    radius (:func:`contact_radius`); ``spec`` the ContactSpec or None (defaults)."""
    spec = spec or ContactSpec()
    if not (obstacles or spec.self_contact):
        return
    for i, rod in enumerate(rods):
        if contact_radius(rod, spec) is None:
            fail("contact.radius", f"required: rod {rod.name!r} has no circular section to "
                 f"take it from (or set rods[{i}].contact_radius)")


def default_stiffness(EI, length):
    """The default penalty stiffness ``STIFFNESS_FACTOR EI / h^4`` (N/m^2) of elements of
    bending stiffness ``EI`` (N m^2) and length ``h = length`` (m) (arrays or floats)."""
    return STIFFNESS_FACTOR * EI / np.asarray(length) ** 4


def contact_tables(scene, stiffness, length):
    """Model tables of the contact: per element radius (E,) m, penalty stiffness (E,)
    N/m^2 and slip-displacement scale of static friction (E,) m, obstacle rows (K,ROW),
    friction (K,), the normal damping ratio () (None when 0: no damping), motion
    displacements (K,3) m (zeros for fixed obstacles; their time
    laws: :func:`motion_profiles`) and velocities (K,3) (zeros: at rest until
    :func:`simsoft_jax.model.loads.loads_at` moves them), the self-contact exclusion arclength
    () m, from the scene's rods, ``[contact]`` and obstacles; ``stiffness`` (E,6) or
    (E,6,6) and ``length`` (E,) the element tables (the default penalty is
    ``STIFFNESS_FACTOR max(EIy, EIz) / h^4``, the default slip scale ``SLIP_FRACTION``
    times the radius)."""
    spec = getattr(scene, "contact", None) or ContactSpec()
    obstacles = getattr(scene, "obstacles", ())
    radius = []
    for rod in scene.rods:   # every rod has one where it is needed (scene reading)
        radius += [contact_radius(rod, spec) or 0.0] * rod.elements
    K = np.asarray(stiffness)
    EI = np.maximum(K[:, 4, 4], K[:, 5, 5]) if K.ndim == 3 else np.maximum(K[:, 4], K[:, 5])
    k = (np.full(len(length), spec.stiffness) if spec.stiffness is not None
         else default_stiffness(EI, length))
    rows = np.reshape([o.params for o in obstacles], (-1, ROW))
    shift = np.reshape([np.zeros(3) if o.displacement is None else o.displacement
                        for o in obstacles], (-1, 3))
    exclusion = (spec.self_exclusion if spec.self_exclusion is not None
                 else 2.0 * np.pi * max(radius, default=0.0))
    radius = np.asarray(radius, float)
    slip = (np.full(len(length), spec.slip_displacement) if spec.slip_displacement
            is not None else SLIP_FRACTION * radius)
    return dict(contact_radius=radius, contact_stiffness=k, slip_displacement=slip,
                self_exclusion=exclusion,
                contact_damping=spec.damping_ratio if spec.damping_ratio > 0.0 else None,
                obstacles=rows, obstacle_friction=np.array([o.friction for o in
                                                            obstacles], float),
                obstacle_shift=shift, obstacle_velocity=np.zeros_like(shift),
                slip_velocity=spec.slip_velocity)


def motion_profiles(obstacles: tuple) -> list:
    """The time law (ProfileSpec) of each obstacle's motion; a fixed obstacle's is the
    constant law (with a zero displacement it does not move)."""
    return [o.profile or ProfileSpec("constant") for o in obstacles]
