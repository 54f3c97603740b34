"""Scene parsing of actuators: tendons (``[[tendons]]``) and pressure chambers
(``[[chambers]]``): plain Python + NumPy, every error naming its key path
(:mod:`simsoft_jax.scene` calls these; contract in ``docs/scene-format.md``)."""
from __future__ import annotations

import numpy as np

from ._validate import (check_keys, choice, fail, index, integer, join, number, positive,
                        readonly, string, table, vector)

TENDON_KEYS = ("name", "rod", "from_node", "to_node", "offset", "tension", "displacement",
               "profile")
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


def _span(item, path, rods):
    """(rod name, from_node, to_node): nodes resolved (negative from the end), from < to."""
    name = item["rod"]
    if not isinstance(name, str) or name not in rods:
        fail(join(path, "rod"), f"no rod named {name!r} (known: {', '.join(rods)})")
    n = rods[name].nodes
    nodes = []
    for key, default in (("from_node", 0), ("to_node", -1)):
        node = integer(item.get(key, default), join(path, key))
        if not -n <= node < n:
            fail(join(path, key), f"out of range for rod {name!r} with {n} nodes "
                 f"(allowed {-n}..{n - 1}), got {node}")
        nodes.append(node % n)
    if nodes[0] >= nodes[1]:
        fail(join(path, "to_node"), f"must come after from_node (node {nodes[0]}), got "
             f"node {nodes[1]}")
    return name, nodes[0], nodes[1]


def parse_routing(value, path):
    """``offset = [y, z]`` | ``{kind = "helix", radius, pitch, phase_deg}`` |
    ``{kind = "table", s, y, z}`` -> :class:`~simsoft_jax.scene_specs.RoutingSpec`."""
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


def parse_tendons(items: list, rods: dict, parse_profile, mechanism: bool) -> tuple:
    """``[[tendons]]`` -> :class:`~simsoft_jax.scene_specs.TendonSpec` tuple.
    ``parse_profile(value, path)`` parses a ``profile`` table; ``mechanism``: the scene is
    dynamic with joints or a sliding drive (no displacement control there yet)."""
    from .scene_specs import TendonSpec

    out, seen = [], set()
    for i, item in enumerate(items):
        path = index("tendons", i)
        check_keys(item, path, TENDON_KEYS, required=("name", "rod", "offset"))
        name = _name(item, path, seen)
        rod, a, b = _span(item, path, rods)
        routing = parse_routing(item["offset"], join(path, "offset"))
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
            if mechanism:
                fail(join(path, "displacement"), "displacement control in a dynamic scene "
                     "with joints or a sliding drive is not supported yet (give tension)")
        profile = _profile(item, path, parse_profile)
        _check_pulls(profile, join(path, "profile"))
        out.append(TendonSpec(name=name, rod=rod, from_node=a, to_node=b, routing=routing,
                              tension=tension, displacement=displacement, profile=profile))
    return tuple(out)


def parse_chambers(items: list, rods: dict, parse_profile) -> tuple:
    """``[[chambers]]`` -> :class:`~simsoft_jax.scene_specs.ChamberSpec` tuple."""
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
