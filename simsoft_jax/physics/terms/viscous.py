"""Kelvin-Voigt viscous stress (the paper's eq. 8, spec S40)."""
from .. import element


def force(el, data):
    """``P^T Upsilon P v_e / L`` (12,) with the nodal body velocities ``v_e``."""
    return element.viscous_force(el.P, el.ve, data.length, data.viscosity)
