"""Scene parsing of materials and rods: ``[[materials]]``, and each ``[[rods]]`` entry
with its section, material, stiffness and inertia overrides, segments, geometry, base
pose, ``initial`` shape and contact radius. Plain Python + NumPy; errors name the key
path (:mod:`simsoft_jax.scene.scene` calls these; contract in ``docs/scene-format.md``)."""
from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from .key_checks import (check_keys, choice, fail, index, integer, join, number, polyline,
                        positive, prefixed, readonly, require, rodrigues, rotation_vector,
                        string, table, vector)
from .materials import BUILTIN_MATERIALS, Material, get_material
from .scene_attachments import parse_section_inertia, parse_stiffness
from .scene_fields import ROD_MAGNET_KEYS, parse_hydraulic_diameter, parse_magnet
from .scene_initial import parse_initial
from .scene_limits import MAX_ELEMENTS, check_elements
from .scene_specs import GeometrySpec, RodSpec, SegmentSpec, node_fractions
from .sections import Section, circle, rectangle, semicircle, tube

MATERIAL_KEYS = ("name", "E", "G", "nu", "density", "viscosity", "mass_damping")
ROD_KEYS = ("name", "material", "section", "shear_coefficients", "stiffness", "inertia",
             "elements", "geometry", "base", "initial", "segments", "contact_radius",
             "hydraulic_diameter", *ROD_MAGNET_KEYS)
SEGMENT_KEYS = ("elements", "material", "section", "shear_coefficients", "stiffness",
                 "inertia", "length", *ROD_MAGNET_KEYS)
SECTIONS = {"circle": (circle, ("diameter",)),
             "tube": (tube, ("outer_diameter", "inner_diameter")),
             "rectangle": (rectangle, ("width", "height")),
             "semicircle": (semicircle, ("radius",))}
GEOMETRY_KEYS = {"straight": ("length",), "arc": ("radius", "angle_deg"),
                  "helix": ("radius", "pitch", "turns"), "polyline": ("points",)}


def _material_from_table(m: dict, path: str, need_name: bool) -> Material:
    check_keys(m, path, MATERIAL_KEYS, required=("name",) if need_name else ())
    require(m, path, "E")
    require(m, path, "density")
    if ("G" in m) == ("nu" in m):
        fail(path, "give exactly one of G, nu")
    args: dict[str, Any] = {}
    for key in MATERIAL_KEYS:
        if key == "name" and key in m:
            args["name"] = string(m[key], join(path, key))
            if not args["name"]:
                fail(join(path, key), "must not be empty")
        elif key in m:
            check = positive if key in ("E", "G", "density") else number
            args[key] = check(m[key], join(path, key))
    with prefixed(path, MATERIAL_KEYS):
        return Material(**args)


def parse_materials(items: list[dict]) -> dict[str, Material]:
    customs: dict[str, Material] = {}
    for i, m in enumerate(items):
        path = index("materials", i)
        material = _material_from_table(m, path, need_name=True)
        if material.name in BUILTIN_MATERIALS:
            fail(join(path, "name"), f"{material.name!r} is a built-in material; "
                 "choose another name")
        if material.name in customs:
            fail(join(path, "name"), f"duplicate material name {material.name!r}")
        customs[material.name] = material
    return customs


def _parse_properties(r: dict, path: str, materials: dict[str, Material],
                      material: Material | None = None, required: bool = True) -> dict:
    """Material, section, shear coefficients and overrides of a rod or of a segment."""
    mpath = join(path, "material")
    if "material" in r:
        material = _rod_material(r["material"], mpath, materials)

    stiffness = inertia = None
    if "stiffness" in r:
        stiffness = parse_stiffness(r["stiffness"], join(path, "stiffness"))
    if "inertia" in r:
        inertia = parse_section_inertia(r["inertia"], join(path, "inertia"))

    section = None
    if "section" in r:
        section = _parse_section(r["section"], join(path, "section"))
    elif required and (stiffness is None or inertia is None):
        fail(join(path, "section"), "required unless both stiffness and inertia are given")
    if section is not None and material is None:
        fail(mpath, "required key missing (a rod with a section needs a material)")

    shear = None
    if "shear_coefficients" in r:
        kpath = join(path, "shear_coefficients")
        if stiffness is not None:
            fail(kpath, "has no effect when stiffness is given (remove one)")
        values = vector(r["shear_coefficients"], kpath, 2)
        for j, kv in enumerate(values):
            if kv <= 0.0:
                fail(index(kpath, j), f"must be > 0, got {kv}")
        shear = (float(values[0]), float(values[1]))
    return dict(material=material, section=section, shear_coefficients=shear,
                stiffness=readonly(stiffness), inertia=readonly(inertia),
                magnetic_moment=parse_magnet(r, path, section))


def _parse_segments(value: Any, path: str, materials: dict[str, Material],
                    material: Material | None) -> tuple:
    """``segments``: consecutive pieces of a rod, each with its own elements and section."""
    if not isinstance(value, list) or not value:
        fail(path, "must be a non-empty array of tables")
    segments = []
    for i, item in enumerate(value):
        ipath = index(path, i)
        seg = table(item, ipath)
        check_keys(seg, ipath, SEGMENT_KEYS, required=("elements",))
        props = _parse_properties(seg, ipath, materials, material)
        if "length" in seg:
            props["length"] = positive(seg["length"], join(ipath, "length"))
        segments.append(SegmentSpec(
            elements=integer(seg["elements"], join(ipath, "elements"), minimum=1), **props))
    given = ["length" in item for item in value]
    if any(given) and not all(given):
        fail(index(path, given.index(False) if given[0] else given.index(True)),
             "give every segment a length, or none (the elements are then equal)")
    return tuple(segments)


def _check_segment_lengths(segments, geometry: GeometrySpec, path: str) -> None:
    """The segments' lengths must add up to the geometry's arc length (to 1e-9 of it)."""
    if not segments or segments[0].length is None:
        return
    total, arc = sum(seg.length for seg in segments), geometry.arc_length
    if abs(total - arc) > 1e-9 * arc:
        fail(path, f"the segments' lengths add up to {total:.12g} m, but the geometry's "
             f"arc length is {arc:.12g} m; they must be equal")


def parse_rod(r: dict, path: str, materials: dict[str, Material],
               base_dir: Path | None = None) -> RodSpec:
    check_keys(r, path, ROD_KEYS, required=("name", "geometry"))
    name = string(r["name"], join(path, "name"))
    if not name:
        fail(join(path, "name"), "must not be empty")
    has_segments = "segments" in r
    props = _parse_properties(r, path, materials, required=not has_segments)
    segments = None
    if has_segments:
        segments = _parse_segments(r["segments"], join(path, "segments"), materials,
                                   props["material"])
        total = sum(seg.elements for seg in segments)
        if "elements" in r and integer(r["elements"], join(path, "elements")) != total:
            fail(join(path, "elements"), f"must equal the sum over segments ({total})")
        r = {**r, "elements": total}
    elif "elements" not in r:
        fail(join(path, "elements"), "required key missing")

    elements = integer(r["elements"], join(path, "elements"), minimum=1)
    if elements > MAX_ELEMENTS:
        fail(join(path, "elements"), f"must be <= {MAX_ELEMENTS} (the limit per scene), "
             f"got {elements}")
    geometry = _parse_geometry(r["geometry"], join(path, "geometry"))
    _check_segment_lengths(segments, geometry, join(path, "segments"))
    check_elements(geometry, node_fractions(elements, segments), join(path, "geometry"))

    position, rotation = np.zeros(3), np.eye(3)
    if "base" in r:
        bpath = join(path, "base")
        b = table(r["base"], bpath)
        check_keys(b, bpath, ("position", "rotation"))
        if "position" in b:
            position = vector(b["position"], join(bpath, "position"))
        if "rotation" in b:
            rotation = rodrigues(rotation_vector(b["rotation"], join(bpath, "rotation")))

    initial = {}
    if "initial" in r:
        initial = parse_initial(r["initial"], join(path, "initial"), name, elements + 1,
                                 position, rotation, base_dir or Path.cwd())

    if "contact_radius" in r:
        initial["contact_radius"] = positive(r["contact_radius"], join(path, "contact_radius"))
    initial.update(parse_hydraulic_diameter(r, path))
    return RodSpec(name=name, **props, elements=elements, geometry=geometry,
                   base_position=readonly(position), base_rotation=readonly(rotation),
                   segments=segments, **initial)


def _rod_material(value: Any, path: str, materials: dict[str, Material]) -> Material:
    if isinstance(value, dict):
        return _material_from_table(value, path, need_name=False)
    name = string(value, path)
    if name in materials:
        return materials[name]
    if name not in BUILTIN_MATERIALS:
        known = ", ".join([*materials, *BUILTIN_MATERIALS])
        fail(path, f"unknown material {name!r} (known: {known})")
    return get_material(name)


def _parse_section(value: Any, path: str) -> Section:
    s = table(value, path)
    shape = choice(require(s, path, "shape"), join(path, "shape"), tuple(SECTIONS))
    build, keys = SECTIONS[shape]
    check_keys(s, path, ("shape", *keys), required=keys)
    args = {k: (number if k == "inner_diameter" else positive)(s[k], join(path, k))
            for k in keys}
    with prefixed(path, keys):
        return build(**args)


def _parse_geometry(value: Any, path: str) -> GeometrySpec:
    g = table(value, path)
    kind = choice(require(g, path, "kind"), join(path, "kind"), tuple(GEOMETRY_KEYS))
    keys = GEOMETRY_KEYS[kind]
    check_keys(g, path, ("kind", *keys), required=keys)
    if kind == "polyline":
        return GeometrySpec(kind, points=readonly(polyline(g["points"], join(path, "points"))))
    if kind == "straight":
        return GeometrySpec(kind, length=positive(g["length"], join(path, "length")))
    radius = positive(g["radius"], join(path, "radius"))
    if kind == "arc":
        angle = positive(g["angle_deg"], join(path, "angle_deg"))
        if angle > 360.0:
            fail(join(path, "angle_deg"), f"must be <= 360, got {angle}")
        return GeometrySpec(kind, radius=radius, angle_deg=angle)
    pitch = number(g["pitch"], join(path, "pitch"))
    if pitch < 0.0:
        fail(join(path, "pitch"), f"must be >= 0, got {pitch}")
    turns = positive(g["turns"], join(path, "turns"))
    return GeometrySpec(kind, radius=radius, pitch=pitch, turns=turns)
