"""Scene sections of the fields a rod sits in: ``[magnetic_field]``, ``[fluid]``, and the
rod keys they read (``magnetization`` / ``magnetic_moment``, ``hydraulic_diameter``).

Plain Python + NumPy (no JAX): every bad input is rejected here with one ``ValueError``
naming the key. The physics: :mod:`simsoft_jax.physics.terms.magnetic`, :mod:`simsoft_jax.physics.terms.fluid`.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from .key_checks import (SpecBase, check_keys, fail, index, join, number, positive, readonly,
                        require, table, vector)
from .scene_specs import ProfileSpec

MAGNETIC_KEYS = ("vector", "profile")
FLUID_KEYS = ("density", "drag_normal", "drag_tangent", "velocity", "buoyancy", "added_mass")
ROD_MAGNET_KEYS = ("magnetization", "magnetic_moment")


@dataclass(frozen=True, eq=False)
class MagneticFieldSpec(SpecBase):
    """``[magnetic_field]``: ``vector`` (3,) T, world frame; ``profile`` its time law."""
    vector: np.ndarray
    profile: ProfileSpec


@dataclass(frozen=True, eq=False)
class FluidSpec(SpecBase):
    """``[fluid]``: density kg/m^3, drag coefficients C_n, C_t, the current ``velocity``
    (3,) m/s (world), ``buoyancy`` (bool), added-mass coefficient C_a."""
    density: float
    drag_normal: float
    drag_tangent: float
    velocity: np.ndarray
    buoyancy: bool
    added_mass: float


def parse_magnetic_field(value: Any, profile) -> MagneticFieldSpec:
    """``[magnetic_field]`` -> :class:`MagneticFieldSpec`; ``profile(value, path)`` parses a
    time law as for loads (constant when absent)."""
    m = table(value, "magnetic_field")
    check_keys(m, "magnetic_field", MAGNETIC_KEYS, required=("vector",))
    law = (profile(m["profile"], "magnetic_field.profile") if "profile" in m
           else ProfileSpec("constant"))
    return MagneticFieldSpec(readonly(vector(m["vector"], "magnetic_field.vector")), law)


def parse_fluid(value: Any) -> FluidSpec:
    """``[fluid]`` -> :class:`FluidSpec` (defaults: C_n 1.2, C_t 0, still fluid, buoyancy
    on, no added mass)."""
    f = table(value, "fluid")
    check_keys(f, "fluid", FLUID_KEYS, required=("density",))
    coefficients = {}
    for key, default in (("drag_normal", 1.2), ("drag_tangent", 0.0), ("added_mass", 0.0)):
        coefficients[key] = number(f.get(key, default), join("fluid", key))
        if coefficients[key] < 0.0:
            fail(join("fluid", key), f"must be >= 0, got {coefficients[key]}")
    buoyancy = f.get("buoyancy", True)
    if not isinstance(buoyancy, bool):
        fail("fluid.buoyancy", f"must be true or false, got {buoyancy!r}")
    current = vector(f.get("velocity", [0.0, 0.0, 0.0]), "fluid.velocity")
    return FluidSpec(positive(f["density"], "fluid.density"), velocity=readonly(current),
                     buoyancy=buoyancy, **coefficients)


def parse_magnet(r: dict, path: str, section) -> np.ndarray | None:
    """A rod's or segment's magnetic moment per unit length (3,) A m, section frame, from
    ``magnetization`` (A/m, times the section's area) or ``magnetic_moment``; None when
    neither is given."""
    given = [key for key in ROD_MAGNET_KEYS if key in r]
    if len(given) == 2:
        fail(join(path, "magnetic_moment"), "give magnetization or magnetic_moment, not both")
    if not given:
        return None
    key = join(path, given[0])
    moment = vector(r[given[0]], key)
    if given[0] == "magnetization":
        if section is None:
            fail(key, "needs a section (its area); give magnetic_moment (A m per unit "
                 "length) for a rod without one")
        moment = moment * section.area
    return readonly(moment)


def section_diameter(section) -> float | None:
    """Outer diameter (m) of a circular section (circle or tube), else None."""
    if section is None:
        return None
    if section.shape == "circle":
        return float(section.dimensions["diameter"])
    if section.shape == "tube":
        return float(section.dimensions["outer_diameter"])
    return None


def check_fluid_rods(fluid: FluidSpec | None, rods) -> None:
    """Under ``[fluid]`` every rod piece needs a diameter: its circular section or the
    rod's ``hydraulic_diameter``."""
    if fluid is None:
        return
    for i, rod in enumerate(rods):
        if rod.hydraulic_diameter is not None:
            continue
        for piece in rod.segments or (rod,):
            if section_diameter(piece.section) is None:
                fail(index("rods", i) + ".hydraulic_diameter", "required under [fluid] for a "
                     "rod without a circular section (the diameter the fluid loads act on)")


def parse_hydraulic_diameter(r: dict, path: str) -> dict:
    """``{"hydraulic_diameter": m}`` when the rod gives one, else ``{}``."""
    if "hydraulic_diameter" not in r:
        return {}
    return {"hydraulic_diameter": positive(require(r, path, "hydraulic_diameter"),
                                           join(path, "hydraulic_diameter"))}
