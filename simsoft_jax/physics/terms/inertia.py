"""Inertia and gyroscopic forces of an element (spec S45-S46, algorithm.md 3.5)."""
from .. import inertia


def force(el, data, kind: str):
    """``M_e vdot_e + g(v_e)`` (12,): element mass matrix times the nodal accelerations
    plus the gyroscopic force of the ``kind`` ("consistent" | "lumped") inertia."""
    return data.mass @ el.vde + inertia.gyroscopic_force(data.maps, data.length, data.inertia,
                                                         el.ve, kind, data.mass)
