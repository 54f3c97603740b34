"""Scene parsing of rigid bodies (``[[bodies]]``) and joints (``[[joints]]``): plain Python
+ NumPy, errors naming the key path (:mod:`simsoft_jax.scene.scene` calls these; contract in
``docs/scene-format.md``). The mechanics is in :mod:`simsoft_jax.physics.terms.joints` and
:mod:`simsoft_jax.couplings.mechanisms`."""
from __future__ import annotations

import numpy as np

from .key_checks import (check_keys, fail, index, join, number, readonly, rodrigues,
                        rotation_vector, string, table, vector)
from .scene_attachments import parse_inertia
from .scene_specs import BodySpec, JointEnd, JointSpec

BODY_KEYS = ("name", "mass", "inertia", "position", "rotation")
JOINT_KEYS = ("kind", "a", "b")
JOINT_KINDS = ("weld", "ball")


def parse_bodies(items: list, rods: dict) -> tuple:
    """``[[bodies]]`` -> :class:`~simsoft_jax.scene.scene_specs.BodySpec` tuple: ``name``
    (unique, not a rod's), ``mass`` (kg, >= 0, default 0), ``inertia`` (3x3, kg m^2,
    about the body origin, body frame, default 0), ``position`` (m, world, default 0),
    ``rotation`` (rotation vector or ``{axis, angle_deg}``, default none)."""
    out, names = [], set()
    for i, item in enumerate(items):
        path = index("bodies", i)
        check_keys(item, path, BODY_KEYS, required=("name",))
        name = string(item["name"], join(path, "name"))
        if name in names or name in rods:
            fail(join(path, "name"), f"{name!r} is already the name of a "
                 f"{'body' if name in names else 'rod'}")
        names.add(name)
        mass = number(item.get("mass", 0.0), join(path, "mass"))
        if mass < 0.0:
            fail(join(path, "mass"), f"must be >= 0, got {mass}")
        inertia = (parse_inertia(item["inertia"], join(path, "inertia")) if "inertia" in item
                   else np.zeros((3, 3)))
        position = vector(item.get("position", [0.0, 0.0, 0.0]), join(path, "position"))
        rotation = (rodrigues(rotation_vector(item["rotation"], join(path, "rotation")))
                    if "rotation" in item else np.eye(3))
        out.append(BodySpec(name=name, mass=mass, inertia=readonly(inertia),
                            position=readonly(position), rotation=readonly(rotation)))
    return tuple(out)


def _end(value, path: str, rods: dict, bodies: dict, node_of) -> JointEnd:
    t = table(value, path)
    check_keys(t, path, ("rod", "node", "s", "body", "offset"))
    if ("rod" in t) == ("body" in t):
        fail(path, "give exactly one of rod (with node or s), body")
    offset = readonly(vector(t.get("offset", [0.0, 0.0, 0.0]), join(path, "offset")))
    if "body" in t:
        name = t["body"]
        if not isinstance(name, str) or name not in bodies:
            fail(join(path, "body"), f"no body named {name!r} (known: "
                 f"{', '.join(bodies) or 'none'})")
        for key in ("node", "s"):
            if key in t:
                fail(join(path, key), "a body end has no node (use offset)")
        return JointEnd(rod=None, node=None, body=name, offset=offset)
    name = t["rod"]
    if not isinstance(name, str) or name not in rods:
        fail(join(path, "rod"), f"no rod named {name!r} (known: {', '.join(rods)})")
    return JointEnd(rod=name, node=node_of(t, path, rods[name]), body=None, offset=offset)


def parse_joints(items: list, rods: dict, bodies: tuple, node_of) -> tuple:
    """``[[joints]]`` -> :class:`~simsoft_jax.scene.scene_specs.JointSpec` tuple: ``kind``
    ("weld" | "ball"), ends ``a`` and ``b`` (each ``{rod, node | s}`` or ``{body}``, with an
    optional ``offset`` in that end's frame, m). ``node_of(item, path, rod)`` resolves
    ``node``/``s``. The two ends must differ."""
    by_name = {b.name: b for b in bodies}
    out = []
    for i, item in enumerate(items):
        path = index("joints", i)
        check_keys(item, path, JOINT_KEYS, required=JOINT_KEYS)
        kind = item["kind"]
        if kind not in JOINT_KINDS:
            fail(join(path, "kind"), f"must be one of {', '.join(JOINT_KINDS)}, got {kind!r}")
        a = _end(item["a"], join(path, "a"), rods, by_name, node_of)
        b = _end(item["b"], join(path, "b"), rods, by_name, node_of)
        if (a.rod, a.node, a.body) == (b.rod, b.node, b.body):
            fail(path, "a joint needs two different ends (rod node or body)")
        out.append(JointSpec(kind=kind, a=a, b=b))
    return tuple(out)


def jointed_rods(joints: tuple) -> set:
    """Names of the rods that have a joint."""
    return {end.rod for j in joints for end in (j.a, j.b) if end.rod is not None}


def check_mechanism(kind: str, bodies: tuple, joints: tuple, constraints: tuple = ()) -> None:
    """Every body needs a joint (bodies act on rods only through joints; a free body has
    no static equilibrium). In dynamics a body that is not welded needs a mass and a
    positive definite inertia (a ball joint leaves its rotation to its own inertia), and
    joints do not combine with drives that slide (``slides_along``)."""
    attached = {end.body for j in joints for end in (j.a, j.b)}
    welded = {end.body for j in joints if j.kind == "weld" for end in (j.a, j.b)}
    for i, body in enumerate(bodies):
        if body.name not in attached:
            fail(index("bodies", i), f"body {body.name!r} has no joint (bodies act on rods "
                 "only through joints, and a free body has no static equilibrium)")
        if kind == "dynamic" and body.name not in welded:
            if body.mass <= 0.0:
                fail(join(index("bodies", i), "mass"), "a body without a weld needs a mass "
                     "> 0 in a dynamic scene (nothing else sets its acceleration)")
            if np.any(np.linalg.eigvalsh(0.5 * (body.inertia + body.inertia.T)) <= 0.0):
                fail(join(index("bodies", i), "inertia"), "a body without a weld needs a "
                     "positive definite inertia in a dynamic scene (its rotation is free)")
    ends = {(end.rod, end.node) for j in joints for end in (j.a, j.b) if end.rod is not None}
    for i, c in enumerate(constraints):
        if getattr(c, "slides_along", None) is not None and (c.rod, c.node) in ends:
            fail(join(index("constraints", i), "slides_along"), f"a joint acts on node "
                 f"{c.node} of rod {c.rod!r}, which this drive slides: a sliding node "
                 "cannot be a joint end (put the joint on another node)")
