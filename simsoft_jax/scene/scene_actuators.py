"""Scene parsing of actuators: tendons (``[[tendons]]``) and pressure chambers
(``[[chambers]]``): plain Python + NumPy, every error naming its key path
(:mod:`simsoft_jax.scene.scene` calls these; contract in ``docs/scene-format.md``)."""
from __future__ import annotations

import numpy as np

from .key_checks import (check_keys, choice, fail, index, integer, join, number, positive,
                        readonly, string, table, vector)
from .scene_tendon_paths import weld_path

TENDON_KEYS = ("name", "rod", "from_node", "to_rod", "to_node", "offset", "rod_offsets",
               "tension", "displacement", "profile")
CHAMBER_KEYS = ("name", "rod", "from_node", "to_node", "area", "offset", "pressure",
                "profile")
ROUTING_KEYS = {"helix": ("kind", "radius", "pitch", "phase_deg"),
                "table": ("kind", "s", "y", "z")}


def _name(item, path, seen):
    name = string(item["name"], join(path, "name"))
    if name in seen:
        fail(join(path, "name"), f"duplicate name {name!r}")
    seen.add(name)
    return name


def _rod(item, key, path, rods):
    """The rod named by ``item[key]`` (a RodSpec)."""
    name = item[key]
    if not isinstance(name, str) or name not in rods:
        fail(join(path, key), f"no rod named {name!r} (known: {', '.join(rods)})")
    return rods[name]


def _node(item, key, default, rod, path):
    """``item[key]`` (default ``default``) resolved to a node of ``rod`` (negative from
    the end)."""
    n = rod.nodes
    node = integer(item.get(key, default), join(path, key))
    if not -n <= node < n:
        fail(join(path, key), f"out of range for rod {rod.name!r} with {n} nodes "
             f"(allowed {-n}..{n - 1}), got {node}")
    return node % n


def _span(item, path, rods):
    """(rod name, from_node, to_node): nodes resolved (negative from the end), from < to."""
    rod = _rod(item, "rod", path, rods)
    a, b = (_node(item, key, default, rod, path)
            for key, default in (("from_node", 0), ("to_node", -1)))
    if a >= b:
        fail(join(path, "to_node"), f"must come after from_node (node {a}), got node {b}")
    return rod.name, a, b


def _routings(item, path, names):
    """Rod name -> RoutingSpec for the rods ``names`` a tendon passes: ``rod_offsets``
    where it names the rod, else ``offset``."""
    default = (parse_routing(item["offset"], join(path, "offset")) if "offset" in item
               else None)
    per_rod = table(item.get("rod_offsets", {}), join(path, "rod_offsets"))
    out = {}
    for name, value in per_rod.items():
        if name not in names:
            fail(join(join(path, "rod_offsets"), name), f"rod {name!r} is not on the "
                 f"tendon's route ({', '.join(names)})")
        out[name] = parse_routing(value, join(join(path, "rod_offsets"), name))
    for name in names:
        if name not in out and default is None:
            fail(join(path, "offset"), f"required (the routing on rod {name!r}, which "
                 "rod_offsets does not give)")
        out.setdefault(name, default)
    return out


def _route(item, path, rods, joints):
    """``(parts, crossings)`` of a tendon (:class:`~simsoft_jax.scene.scene_specs.TendonSpec`):
    in one rod from ``from_node`` to a later ``to_node``; with a ``to_rod``, along the
    welds from ``rod`` to ``to_rod`` (:mod:`simsoft_jax.scene.scene_tendon_paths`)."""
    from .scene_specs import TendonPart

    start = _rod(item, "rod", path, rods).name
    end = _rod(item, "to_rod", path, rods).name if "to_rod" in item else start
    if end == start:
        _, a, b = _span(item, path, rods)
        spans, steps = [(start, a, b)], ()
    else:
        steps = weld_path(start, end, joints, path)
        nodes = ([_node(item, "from_node", 0, rods[start], path)]
                 + [n for step in steps for n in (step[1], step[3])]
                 + [_node(item, "to_node", -1, rods[end], path)])
        names = [start] + [step[2] for step in steps]
        spans = [(name, nodes[2 * k], nodes[2 * k + 1]) for k, name in enumerate(names)]
        if all(a == b for _, a, b in spans):
            fail(join(path, "to_node"), "the tendon passes no element (it starts and ends "
                 "at the welds)")
    routings = _routings(item, path, [name for name, _, _ in spans])
    parts = tuple(TendonPart(rod=name, first=min(a, b), last=max(a, b),
                             routing=routings[name]) for name, a, b in spans)
    return parts, tuple((step[0], step[1], step[3]) for step in steps)


def parse_routing(value, path):
    """``offset = [y, z]`` | ``{kind = "helix", radius, pitch, phase_deg}`` |
    ``{kind = "table", s, y, z}`` -> :class:`~simsoft_jax.scene.scene_specs.RoutingSpec`."""
    from .scene_specs import RoutingSpec

    if not isinstance(value, dict):
        y, z = vector(value, path, 2)
        return RoutingSpec("constant", y=float(y), z=float(z))
    t = table(value, path)
    if "kind" not in t:
        fail(join(path, "kind"), "required (\"helix\" or \"table\")")
    kind = choice(t["kind"], join(path, "kind"), tuple(ROUTING_KEYS))
    check_keys(t, path, ROUTING_KEYS[kind], required=ROUTING_KEYS[kind][:3])
    if kind == "helix":
        pitch = number(t["pitch"], join(path, "pitch"))
        if pitch == 0.0:
            fail(join(path, "pitch"), "must be nonzero (m of arc length per turn; < 0 "
                 "turns the other way)")
        return RoutingSpec("helix", radius=positive(t["radius"], join(path, "radius")),
                           pitch=pitch,
                           phase_deg=number(t.get("phase_deg", 0.0), join(path, "phase_deg")))
    s = vector(t["s"], join(path, "s"), None, min_len=1)
    if np.any(np.diff(s) <= 0.0):
        fail(join(path, "s"), "must be strictly increasing")
    cols = {}
    for key in ("y", "z"):
        cols[key] = vector(t[key], join(path, key), None, min_len=1)
        if len(cols[key]) != len(s):
            fail(join(path, key), f"must have as many entries as s ({len(s)}), got "
                 f"{len(cols[key])}")
    return RoutingSpec("table", s=readonly(s), ys=readonly(cols["y"]),
                       zs=readonly(cols["z"]))


def _profile(item, path, parse_profile):
    """The item's ``profile`` (default constant); a table read from a file is written
    back inline, so the validated input (``Scene.to_dict``) stays self-contained."""
    profile = parse_profile(item.get("profile", {"kind": "constant"}), join(path, "profile"))
    if profile.kind == "table" and "file" in item.get("profile", {}):
        item["profile"] = {"kind": "table", "t": profile.t.tolist(),
                           "scale": profile.scale.tolist()}
    return profile


def _check_pulls(profile, path):
    """A tendon cannot push: a time law with a negative scale is rejected."""
    negative = ((profile.kind == "linear" and profile.rate < 0.0)
                or (profile.kind == "table" and np.any(profile.scale < 0.0)))
    if negative:
        fail(path, "makes the tension negative (a tendon cannot push)")


def parse_tendons(items: list, rods: dict, joints: tuple, parse_profile) -> tuple:
    """``[[tendons]]`` -> :class:`~simsoft_jax.scene.scene_specs.TendonSpec` tuple. ``joints``:
    the scene's JointSpec tuple (a tendon with ``to_rod`` crosses its welds);
    ``parse_profile(value, path)`` parses a ``profile`` table."""
    from .scene_specs import TendonSpec

    out, seen = [], set()
    for i, item in enumerate(items):
        path = index("tendons", i)
        check_keys(item, path, TENDON_KEYS, required=("name", "rod"))
        name = _name(item, path, seen)
        parts, crossings = _route(item, path, rods, joints)
        if ("tension" in item) == ("displacement" in item):
            fail(path, "give exactly one of tension, displacement")
        tension = displacement = None
        if "tension" in item:
            tension = number(item["tension"], join(path, "tension"))
            if tension < 0.0:
                fail(join(path, "tension"), f"must be >= 0 (a tendon cannot push), got "
                     f"{tension}")
        else:
            displacement = number(item["displacement"], join(path, "displacement"))
        profile = _profile(item, path, parse_profile)
        _check_pulls(profile, join(path, "profile"))
        out.append(TendonSpec(name=name, parts=parts, crossings=crossings, tension=tension,
                              displacement=displacement, profile=profile))
    return tuple(out)


def parse_chambers(items: list, rods: dict, parse_profile) -> tuple:
    """``[[chambers]]`` -> :class:`~simsoft_jax.scene.scene_specs.ChamberSpec` tuple."""
    from .scene_specs import ChamberSpec

    out, seen = [], set()
    for i, item in enumerate(items):
        path = index("chambers", i)
        check_keys(item, path, CHAMBER_KEYS,
                   required=("name", "rod", "area", "offset", "pressure"))
        name = _name(item, path, seen)
        rod, a, b = _span(item, path, rods)
        out.append(ChamberSpec(
            name=name, rod=rod, from_node=a, to_node=b,
            area=positive(item["area"], join(path, "area")),
            offset=readonly(vector(item["offset"], join(path, "offset"), 2)),
            pressure=number(item["pressure"], join(path, "pressure")),
            profile=_profile(item, path, parse_profile)))
    return tuple(out)
