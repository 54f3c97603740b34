"""The anchors of the stick-slip friction in dynamics (``[contact] friction_law =
"stick_slip"``; the law (S1)-(S3) in :mod:`simsoft_jax.physics.terms.contact`): per element,
contact station and obstacle, the point (E,S,K,3) m where the station's tangential spring
is unstretched, carried from step to step in the dynamic state
(:class:`simsoft_jax.solvers.dynamics.State` ``anchor``; S = quadrature points + 2).

Anchors are kept relative to their obstacle's displacement ``obstacle_shift scale(t)``
(:func:`simsoft_jax.model.loads.obstacles_at`), so an anchor moves with a moving obstacle.
A step from ``t_n`` to ``t_{n+1}`` solves with the anchors of its start state placed at
``t_{n+1}`` (:func:`anchored`), and its end state carries the plastic anchors (S3) at its
solution (:func:`updated`). Both are differentiable: a rollout's implicit derivatives
(:func:`simsoft_jax.solvers.dynamics.newton.replay`) go through the anchors, so gradients
see the friction's history. A start state's anchors are its stations
(:func:`initial`): unstretched springs.
"""
from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp

from . import element
from .assembly import contact_data, element_poses
from .terms import contact, static_friction


def active(model) -> bool:
    """Whether ``model``'s dynamics carries anchors: the stick-slip law and some obstacle
    with friction (static, trace time)."""
    return model.structure.friction_law == "stick_slip" and model.obstacle_friction is not None


def _shift(model, t):
    """Displacement (K,3) m of each obstacle at time ``t`` (s) (zeros when none moves)."""
    if model.obstacle_shift is None:
        return jnp.zeros((len(model.structure.obstacle_kinds), 3))
    return model.obstacle_shift * model.obstacle_law.scales(t)[:, None]


def initial(model, R, p, t):
    """Anchors (E,S,K,3) of a start state with the frames ``R`` (N,3,3), ``p`` (N,3) at time
    ``t``: the stations themselves (unstretched springs); None when not :func:`active`."""
    if not active(model):
        return None
    RA, pA, RB, pB = element_poses(model, R, p)
    d = jax.vmap(element.relative_twist)(RA, pA, RB, pB)
    x = jax.vmap(lambda R, p, d: static_friction.stations(
        R, p, d, model.structure.contact_points))(RA, pA, d)
    return x[:, :, None, :] - _shift(model, t)


def anchored(loaded, anchor, t):
    """``loaded`` (the model at time ``t``, :func:`simsoft_jax.model.loads.loads_at`) holding
    the anchors ``anchor`` (E,S,K,3) placed where their obstacles are at ``t`` (world), the
    friction's reference in a step ending at ``t``; ``loaded`` itself when ``anchor`` is
    None."""
    if anchor is None:
        return loaded
    return dataclasses.replace(loaded, friction_anchor=anchor + _shift(loaded, t))


def _per_station(loaded, R, p, law):
    """``law(x (S,3), load (S,K), normals (S,K,3), data)`` of every element's contact
    stations at the frames ``R`` (N,3,3), ``p`` (N,3), mapped over the elements."""
    s = loaded.structure
    RA, pA, RB, pB = element_poses(loaded, R, p)
    d = jax.vmap(element.relative_twist)(RA, pA, RB, pB)

    def one(RA, pA, d, data):
        _, load, normals, _, x = contact.stations(RA, pA, d, data, s.obstacle_kinds,
                                                  s.contact_points)
        return law(x, load, normals, data)

    return jax.vmap(one)(RA, pA, d, contact_data(loaded))


def trials(loaded, R, p):
    """The trial line loads (E,S,K,3) N/m (world, (S1)) of the stations at the frames
    ``R`` (N,3,3), ``p`` (N,3) against the anchors of ``loaded`` (:func:`anchored`) and
    their Coulomb caps ``mu f_n`` (E,S,K) N/m: a station sticks while its trial is within
    ``STICK_LIMIT`` of its cap (:func:`simsoft_jax.physics.terms.contact.stick_slip_load`)."""
    return _per_station(loaded, R, p, lambda x, load, normals, data: (
        contact.stick_slip_trial(x, data.anchor, normals, data.stiffness),
        data.friction * load))


def updated(loaded, R, p, t):
    """The plastic anchors (E,S,K,3) (S3) at the frames ``R``, ``p`` reached at time ``t``
    by a step solved with ``loaded`` (:func:`anchored`), relative to the obstacles'
    displacement; None when ``loaded`` holds no anchors."""
    if loaded.friction_anchor is None:
        return None
    return _per_station(loaded, R, p, lambda x, load, normals, data: contact.stick_slip_load(
        x, data.anchor, load, normals, data.stiffness, data.friction)[1]) - _shift(loaded, t)
