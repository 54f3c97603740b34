"""Pressure chambers: a sealed channel of constant cross-section area A (m^2) running
along the rod at the centroid offset ``rho = (0, y, z)`` (m, section frame) between two
nodes, under a gauge pressure P (Pa).

Model: the chamber's sections are rigid and move with the rod's sections (no ballooning,
no change of A with pressure or strain; the fluid is massless and its pressure uniform).
Its volume is the section area swept along the centroid path,
``V = A int e_x . (nu + kappa x rho) ds`` (the section's own rotation about its centroid
sweeps no volume: the first moment of the area about the centroid is zero), so in a
helical element (spec S34, uniform strain over the reference length L)
``V_e = A (d_x + d_wy z - d_wz y)``, linear in the element twist ``d`` (6,). The pressure
does the work ``P V``: the potential ``-P V`` gives the nodal forces
``-P A P(d)^T (1, 0, 0, 0, z, -y)`` (12,) (residual side; spec S37), which hold both the
end-cap forces ``P A`` at the offset (the caps sit in the sections of the end nodes) and
the consistent distributed effect of a curved chamber. Without shear this is exactly a
tendon at the same offset with tension ``-P A`` (:mod:`.tendons`). Limits: no wall
stretch or bulging, no chamber-to-chamber coupling, area constant along the chamber.
"""
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from . import Term


def volume_gradients(offsets):
    """``grad_d V_e / A`` (C,6) of chambers with centroids at ``offsets`` (C,2) = (y, z)
    (m): rows ``(1, 0, 0, 0, z, -y)``."""
    c = offsets.shape[0]
    return jnp.concatenate([jnp.ones((c, 1), offsets.dtype), jnp.zeros((c, 3), offsets.dtype),
                            offsets[:, 1:], -offsets[:, :1]], axis=1)


class ElementChambers(NamedTuple):
    """One element's slice: force (C,) pressure times area (N; zero where a chamber does
    not pass), offset (C,2) m."""
    force: jax.Array
    offset: jax.Array


def force(el, part: ElementChambers, lam):
    """Nodal forces (12,) ``-lam P(d)^T sum_c (P_c A_c) grad_d V_e/A`` of the chambers
    passing the element."""
    return -lam * el.P.T @ (part.force @ volume_gradients(part.offset))


def per_element(model) -> ElementChambers:
    """Every element's slice (E, ...) (membership by ``structure.chamber_elements``)."""
    s = model.structure
    member = jnp.asarray(np.array(s.chamber_elements, float))          # (C, E)
    pushed = model.chamber_pressure * model.chamber_area
    return ElementChambers((member * pushed[:, None]).T,
                           jnp.broadcast_to(model.chamber_offset,
                                            (s.n_elements,) + model.chamber_offset.shape))


def load_scale(model):
    """Sum of squares (N^2) of pressure times area and of its moment at the chamber's
    offset (divided by ``char_length``)."""
    r = jnp.linalg.norm(model.chamber_offset, axis=-1)
    f = model.chamber_pressure * model.chamber_area
    return jnp.sum(f ** 2 * (1.0 + (r / model.char_length) ** 2))


def at_time(model, t) -> dict:
    """The pressures times their time laws at ``t`` (s)."""
    return {"chamber_pressure": model.chamber_pressure * model.chamber_law.scales(t)}


TERM = Term("chambers", lambda model: bool(model.structure.chamber_names), force,
            per_element, load_scale, at_time=at_time)
