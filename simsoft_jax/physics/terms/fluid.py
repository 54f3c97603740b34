"""Fluid loads on rods (underwater and in-vessel robots): quadratic drag against a uniform
current, buoyancy and added mass.

Per unit length of a rod of diameter ``d`` in a fluid of density ``rho_f`` (Morison-type
loads on a slender cylinder), with ``u`` the velocity of the section's centre line
relative to the current (``v - U``, in the section frame, ``u_t`` along the axis, ``u_n``
normal to it):

- normal drag ``f_n = -1/2 rho_f C_n d |u_n| u_n``,
- tangential (skin) drag ``f_t = -1/2 rho_f C_t pi d |u_t| u_t``,
- buoyancy ``-rho_f A g`` (world frame, ``A = pi d^2 / 4``), when the scene has gravity,
- added mass ``rho_f C_a A`` on the two normal translations of the section inertia
  (dynamics; :func:`added_inertia`, read by :func:`simsoft_jax.physics.terms.registry.section_inertia`),
  whose Euler-Poincare gyroscopic term gives the Kirchhoff (Munk) coupling of a body
  moving through a fluid.

The distributed force is integrated along the helical element with the velocity field
``v(xi) = N(xi, d) v_e`` of the paper's eqs. 36, 40 (spec S38), which is also the virtual
displacement map: nodal forces ``sum_g w_g L N_g^T [f_g; 0]`` (3-point Gauss-Legendre).
``|u_n| u_n`` is differentiable at ``u_n = 0`` (value and derivative 0); the norm is
taken with a double ``where`` so that its derivative is finite there too.
"""
from __future__ import annotations

import dataclasses
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from .. import element
from ...math import lie
from . import Term

_POINTS, _WEIGHTS = np.polynomial.legendre.leggauss(3)
_POINTS, _WEIGHTS = 0.5 * (_POINTS + 1.0), 0.5 * _WEIGHTS


@dataclasses.dataclass(frozen=True)
class FluidPart:
    """The fluid part of a Model: ``density`` () kg/m^3, ``drag_normal``,
    ``drag_tangent`` () coefficients C_n, C_t, ``current`` (3,) m/s world, ``buoyancy`` ()
    1.0 or 0.0, ``added_mass`` () coefficient C_a, ``diameter`` (E,) m per element."""
    density: jax.Array
    drag_normal: jax.Array
    drag_tangent: jax.Array
    current: jax.Array
    buoyancy: jax.Array
    added_mass: jax.Array
    diameter: jax.Array


jax.tree_util.register_dataclass(
    FluidPart, data_fields=[f.name for f in dataclasses.fields(FluidPart)], meta_fields=[])


class ElementFluid(NamedTuple):
    """One element's slice: length () m, diameter () m, normal and tangential drag factors
    ``1/2 rho_f C_n d``, ``1/2 rho_f C_t pi d`` () kg/m^2, current (3,) m/s and buoyancy
    (3,) N/m, both world frame."""
    length: jax.Array
    normal: jax.Array
    tangent: jax.Array
    current: jax.Array
    buoyancy: jax.Array


def area(diameter):
    """Area ``pi d^2 / 4`` (m^2) of a circle of diameter ``d`` (m)."""
    return 0.25 * jnp.pi * diameter ** 2


def per_element(model) -> ElementFluid:
    """Every element's slice (E, ...) of ``model.fluid``; buoyancy ``-rho_f A g buoyancy``
    (zero without gravity: ``model.gravity`` None)."""
    part = model.fluid
    n = model.length.shape[0]
    half = 0.5 * part.density * part.diameter
    lift = (jnp.zeros((n, 3)) if model.gravity is None else
            (-part.density * part.buoyancy * area(part.diameter))[:, None] * model.gravity)
    return ElementFluid(model.length, half * part.drag_normal,
                        half * part.drag_tangent * jnp.pi,
                        jnp.broadcast_to(part.current, (n, 3)), lift)


def safe_norm(x):
    """``|x|`` with a finite derivative (zero) at ``x = 0`` (double ``where``)."""
    squared = jnp.dot(x, x)
    positive = squared > 0.0
    return jnp.where(positive, jnp.sqrt(jnp.where(positive, squared, 1.0)), 0.0)


def section_force(R, u, fluid: ElementFluid):
    """Fluid force per unit length (3,) N/m in the section frame of a section turned by
    ``R`` (3,3) whose centre line moves at ``u`` (3,) m/s (section frame, relative to the
    ground): drag against the relative velocity and buoyancy (module docstring)."""
    relative = u - R.T @ fluid.current
    normal = relative.at[0].set(0.0)
    along = relative[0]
    drag = -fluid.normal * safe_norm(normal) * normal
    drag = drag.at[0].add(-fluid.tangent * jnp.abs(along) * along)
    return drag + R.T @ fluid.buoyancy


def force(el, fluid: ElementFluid, lam):
    """Nodal forces (12,) on the residual side, ``-lam sum_g w_g L N_g^T [f_g; 0]``."""
    def at(xi, weight):
        N = element.velocity_field_map(xi, el.d, el.P)
        R = el.RA @ lie.exp_so3(xi * el.d[3:])
        f = section_force(R, (N @ el.ve)[:3], fluid)
        return weight * N[:3].T @ f

    total = jnp.sum(jax.vmap(at)(jnp.asarray(_POINTS), jnp.asarray(_WEIGHTS)), axis=0)
    return -lam * fluid.length * total


def load_scale(model):
    """Sum of squares (N^2) of the elements' buoyancy plus normal drag in the current at
    rest, ``L (|b| + 1/2 rho_f C_n d |U|^2)``."""
    fluid = per_element(model)
    size = (jnp.linalg.norm(fluid.buoyancy, axis=1)
            + fluid.normal * jnp.sum(fluid.current ** 2, axis=1))
    return jnp.sum((model.length * size) ** 2)


def added_inertia(model):
    """Added mass ``rho_f C_a A`` (kg/m) on the normal translations: (E,6) diagonals."""
    part = model.fluid
    m = part.density * part.added_mass * area(part.diameter)
    zero = jnp.zeros_like(m)
    return jnp.stack([zero, m, m, zero, zero, zero], axis=1)


TERM = Term("fluid", lambda model: model.fluid is not None, force, per_element, load_scale,
            added_inertia=added_inertia, velocity=True)
