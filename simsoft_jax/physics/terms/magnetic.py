"""Magnetic actuation: a uniform external field ``B`` (T, world frame) acting on magnetized
rods (magnetic continuum robots, magnetic catheters).

A section with magnetic moment per unit length ``m`` (A m, section frame: the
magnetization (A/m) times the area) feels the distributed couple ``c = (R m) x B`` (N m/m)
and no force (the field is uniform). The couple is the gradient of the potential energy
per unit length ``-(R m) . B``, so the term is written as the gradient of the element's
energy, which keeps its tangent symmetric at equilibrium:

``E_e = -L B . (R_A J(omega) m)``, ``J(omega) = int_0^1 exp(xi [omega]) dxi = T_SO3(omega)^T``

(``omega`` the element's relative rotation, ``d[3:]``: along the helical element the
section turns as ``R_A exp(xi [omega])``, spec S14; ``T_SO3`` spec S8; L the reference
length, the moment being given per unit reference length). The nodal forces are its
derivative in the chart of spec S37: ``d -> d + P(d) x`` and ``R_A -> R_A exp(x_A)``.
"""
from __future__ import annotations

import dataclasses
from typing import NamedTuple

import jax
import jax.numpy as jnp

from ...math import lie
from . import Term


@dataclasses.dataclass(frozen=True)
class MagneticPart:
    """The magnetic part of a Model: ``field`` (3,) T in the world frame at full scale,
    ``moment`` (E,3) A m per unit length in each element's section frame, ``law`` the
    field's time law (one :class:`~simsoft_jax.model.loads.TimeLaws` entry; dynamics)."""
    field: jax.Array
    moment: jax.Array
    law: object       # simsoft_jax.model.loads.TimeLaws


jax.tree_util.register_dataclass(MagneticPart, data_fields=["field", "moment", "law"],
                                 meta_fields=[])


class ElementMagnet(NamedTuple):
    """One element's slice: moment (3,) A m/m, field (3,) T, length () m."""
    moment: jax.Array
    field: jax.Array
    length: jax.Array


def element_energy(RA, omega, magnet: ElementMagnet, lam):
    """Potential energy (J) of one element in the field at load level ``lam``:
    ``-lam L B . (R_A T_SO3(omega)^T m)`` (module docstring)."""
    moment_world = RA @ (lie.tangent_so3(omega).T @ magnet.moment)
    return -lam * magnet.length * jnp.dot(magnet.field, moment_world)


def force(el, magnet: ElementMagnet, lam):
    """Nodal forces (12,) on the residual side: the derivative of :func:`element_energy` in
    the 12 right perturbations of the nodal frames (spec S37)."""
    zero = jnp.zeros(3, el.d.dtype)
    g_theta, g_omega = jax.grad(
        lambda theta, omega: element_energy(el.RA @ lie.exp_so3(theta), omega, magnet, lam),
        argnums=(0, 1))(zero, el.d[3:])
    through_d = el.P.T @ jnp.concatenate([zero, g_omega])
    return through_d.at[3:6].add(g_theta)


def couple(R, moment, field):
    """Distributed couple ``(R m) x B`` (3,) N m/m in the world frame of a section turned by
    ``R`` (3,3) with moment ``m`` (3,) A m/m in the field ``B`` (3,) T."""
    return jnp.cross(R @ moment, field)


def per_element(model) -> ElementMagnet:
    """Every element's slice (E, ...) of ``model.magnetic``."""
    part = model.magnetic
    n = model.length.shape[0]
    return ElementMagnet(part.moment, jnp.broadcast_to(part.field, (n, 3)), model.length)


def load_scale(model):
    """Sum of squares of the elements' full couples ``L |m| |B|`` divided by the model's
    ``char_length`` (N^2)."""
    part = model.magnetic
    size = model.length * jnp.linalg.norm(part.moment, axis=1) * jnp.linalg.norm(part.field)
    return jnp.sum((size / model.char_length) ** 2)


def at_time(model, t) -> dict:
    """The magnetic part with the field at time ``t`` (s): ``B scale(t)``."""
    part = model.magnetic
    return {"magnetic": dataclasses.replace(part, field=part.field * part.law.scales(t)[0])}


TERM = Term("magnetic", lambda model: model.magnetic is not None, force, per_element,
            load_scale, at_time=at_time)
