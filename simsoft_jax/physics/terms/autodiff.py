"""Residuals of the active terms and their exact tangents by ``jax.jacfwd``.

:func:`element_residual` sums the element terms a structure has; :func:`element_tangents`
differentiates that sum in the chart of right perturbations of the two nodal frames,
``H_A exp(x_A)``, ``H_B exp(x_B)`` (the left-invariant tangent of spec S42, S70), and in
dynamics in the nodal velocities (``C``) and accelerations (``M``). :func:`node_residual`
and :func:`node_tangent` do the same for node terms.
"""
from __future__ import annotations

import jax
import jax.numpy as jnp

from ...math import lie
from . import (Element, contact, distributed, elastic, element_state, inertia, mass_damping,
               nodal, registry, viscous)


def element_residual(structure, lam, dynamic: bool):
    """``f(el: Element, data: ElementData) -> (12,)``: the sum of the element terms of
    ``structure`` at load level ``lam`` (inertia, viscosity and mass damping only when
    ``dynamic``) and contact, plus the registered terms whose slices ``data.parts``
    holds (:mod:`.registry`: point loads inside elements, offset gravity, tendons,
    chambers, magnetic couples, fluid loads). The optional arrays of ``data`` (None when
    the model lacks the term, :mod:`simsoft_jax.model.parts`) say which terms are traced."""
    s = structure

    def residual(el: Element, data):
        r = elastic.force(el, data)
        if dynamic:
            r = r + inertia.force(el, data, s.inertia_kind)
            if data.viscosity is not None:
                r = r + viscous.force(el, data)
            if data.mass_damping is not None:
                r = r + mass_damping.force(el, data)
        if data.gravity is not None or data.q_world is not None:
            r = r + distributed.dead_force(el, data, lam)
        if data.q_local is not None:
            r = r + distributed.follower_force(el, data, lam)
        if s.obstacle_kinds:
            r = r + contact.force(el, data.contact, data.length, s.obstacle_kinds,
                                  s.contact_points,
                                  dynamic and contact.dynamic_friction(
                                      s.friction_law, data.contact.friction,
                                      data.contact.anchor))
        registered = registry.forces(el, data.parts, lam)
        return r if registered is None else r + registered

    return residual


def element_tangents(structure, lam, dynamic: bool):
    """``f(RA, pA, RB, pB, ve, vde, data) -> (r (12,), K (12,12), C, M)``: the residual of
    :func:`element_residual` and its derivatives in the frame perturbations (K), the
    velocities (C) and the accelerations (M); C and M are None in statics."""
    residual = element_residual(structure, lam, dynamic)

    def tangents(RA, pA, RB, pB, ve, vde, data):
        def r(y):
            RA1, pA1 = lie.compose_exp(RA, pA, y[:6])
            RB1, pB1 = lie.compose_exp(RB, pB, y[6:12])
            if dynamic:
                el = element_state(RA1, pA1, RB1, pB1, ve + y[12:24], vde + y[24:36])
            else:
                el = element_state(RA1, pA1, RB1, pB1, ve, vde)
            value = residual(el, data)
            return value, value

        size = 36 if dynamic else 12
        jac, value = jax.jacfwd(r, has_aux=True)(jnp.zeros(size, RA.dtype))
        if dynamic:
            return value, jac[:, :12], jac[:, 12:24], jac[:, 24:]
        return value, jac, None, None

    return tangents


def node_residual(lam):
    """``f(R, dead (6,), follower (6,)) -> (6,)``: the nodal loads (each None when the
    model has none of that kind)."""
    return lambda R, dead, follower: nodal.force(R, dead, follower, lam)


def node_tangent(lam):
    """``f(R, dead, follower) -> (r (6,), K (6,6))`` with K the derivative of
    :func:`node_residual` in the rotation perturbation ``R exp(theta)`` (the translation
    columns are zero: point loads do not depend on the position)."""
    residual = node_residual(lam)

    def tangent(R, dead, follower):
        def r(theta):
            value = residual(R @ lie.exp_so3(theta), dead, follower)
            return value, value

        jac, value = jax.jacfwd(r, has_aux=True)(jnp.zeros(3, R.dtype))
        return value, jnp.concatenate([jnp.zeros((6, 3), R.dtype), jac], axis=1)

    return tangent
