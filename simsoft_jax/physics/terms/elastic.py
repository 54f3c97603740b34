"""Elastic stress of the Cosserat rod (the paper's eq. 48, spec S36, S39)."""
from .. import element


def force(el, data):
    """``P(d)^T K (d - d0)/L`` (12,): gradient of the strain energy ``(L/2) eps^T K eps``."""
    return element.internal_force(el.P, el.d, data.d0, data.length, data.stiffness)
