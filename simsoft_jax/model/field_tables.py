"""Scene -> the Model parts of the fields rods sit in: the magnetic part
(:class:`~simsoft_jax.physics.terms.magnetic.MagneticPart`) and the fluid part
(:class:`~simsoft_jax.physics.terms.fluid.FluidPart`), with per-element tables in the Model's
element order (rods in scene order, each rod's segments in order). NumPy float64."""
from __future__ import annotations

import numpy as np

from .loads import build_laws
from ..scene.scene_fields import section_diameter
from ..scene.scene_specs import ProfileSpec
from ..physics.terms.fluid import FluidPart
from ..physics.terms.magnetic import MagneticPart


def _per_element(scene, value_of):
    """(E, ...) table of ``value_of(rod, piece)`` repeated over each piece's elements."""
    return np.concatenate([np.repeat(np.asarray(value_of(rod, piece), float)[None],
                                     piece.elements, axis=0)
                           for rod in scene.rods for piece in (rod.segments or (rod,))])


def magnetic_part(scene) -> MagneticPart | None:
    """The field at full scale, each element's moment per unit length (the piece's, else
    its rod's, else zero) and the field's time law; None when the scene has neither a
    field nor a magnetized rod."""
    field = getattr(scene, "magnetic_field", None)
    magnetized = any(piece.magnetic_moment is not None
                     for rod in scene.rods for piece in (rod.segments or (rod,)))
    if field is None and not magnetized:
        return None

    def moment(rod, piece):
        for source in (piece, rod):
            if source.magnetic_moment is not None:
                return source.magnetic_moment
        return np.zeros(3)

    vector = np.zeros(3) if field is None else np.asarray(field.vector, float)
    law = build_laws([ProfileSpec("constant") if field is None else field.profile])
    return MagneticPart(vector, _per_element(scene, moment), law)


def fluid_part(scene) -> FluidPart | None:
    """The ``[fluid]`` coefficients and each element's diameter (the rod's
    ``hydraulic_diameter``, else its piece's circular section); None without ``[fluid]``."""
    fluid = getattr(scene, "fluid", None)
    if fluid is None:
        return None

    def diameter(rod, piece):
        return (rod.hydraulic_diameter if rod.hydraulic_diameter is not None
                else section_diameter(piece.section))

    scalars = [np.float64(x) for x in (fluid.density, fluid.drag_normal, fluid.drag_tangent)]
    return FluidPart(*scalars, np.asarray(fluid.velocity, float),
                     np.float64(1.0 if fluid.buoyancy else 0.0), np.float64(fluid.added_mass),
                     _per_element(scene, diameter))
