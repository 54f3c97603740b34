"""Tendons: a frictionless cable routed through the rod at an offset from the centreline,
pulled with a tension T (N); its action on the rod is the derivative of ``T * l``, with
``l`` the tendon's length inside the rod (potential ``T l``: pulling shortens the tendon).

Routing: the tendon passes through the section at ``rho(s) = (0, y(s), z(s))`` (m, section
frame). Inside a helical element (spec S34: uniform strain ``nu = d_u / L``,
``kappa = d_w / L`` over the reference length L) the tendon point
``x(s) = p(s) + R(s) rho(s)`` has the tangent ``x' = R (nu + kappa x rho + rho')``, so its
length in the element is ``l_e(d) = int_0^L |nu + kappa x rho + rho'| ds``
``= sum_q w_q |d_u + d_w x rho_q + L rho'_q|`` (Gauss-Legendre points ``xi_q``, weights
``w_q`` on [0, 1]; exact with one point for a constant offset). The path follows the
helical interpolation inside each element and is continuous across nodes (no kink term).
The nodal forces are ``T P(d)^T grad_d l_e(d)`` (12,) on the residual side, the same
chain rule as the elastic force ``P^T K (d - d0)/L`` (spec S37, S42); the tangent is
``jax.jacfwd`` of it (:mod:`simsoft_jax.physics.terms.autodiff`). A straight tendon at offset r
(along z) in a straight rod gives ``l_e = d_x + r d_wy``: the moment ``T r`` and the
axial force ``T`` of the classical tendon-driven rod (Rucker & Webster 2011, IEEE T-RO
27(6), with the tendon terminated at the end node).

Across rods welded together a tendon is one cable with one tension: its length is the
sum of its parts inside the rods it passes (each part in its own rod's elements and
section frame), so ``T l`` adds the same per-element terms. Limit: the tendon's bridge
across a weld (from its routing point on one side to the one on the other) is left out,
which is exact only when the two points coincide; they must coincide at the start
(checked while the scene is read, :mod:`simsoft_jax.scene.scene_start`), and the
weld keeps its two sides' relative pose, hence the points together and the bridge of
zero length, at every solution (to the solver's tolerance on the weld). A kink there
(the tangents of the two parts differ) then pushes on the weld point with
``T (t_after - t_before)``, as a cable through a fixed eyelet does.
"""
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from ...math.quadrature import gauss_rule
from . import Term


def element_length(d, length, offset, slope, weights):
    """Tendon length (m) in one element: ``d`` (6,) the element's relative twist,
    ``length`` () its reference length L (m), ``offset`` (Q,2) ``(y, z)`` at the quadrature
    points (m), ``slope`` (Q,2) their derivatives ``d(y, z)/ds`` (1), ``weights`` (Q,)
    Gauss weights on [0, 1]."""
    rho = jnp.concatenate([jnp.zeros(offset.shape[:-1] + (1,), d.dtype), offset], axis=-1)
    drho = jnp.concatenate([jnp.zeros(slope.shape[:-1] + (1,), d.dtype), slope], axis=-1)
    t = d[:3] + jnp.cross(d[3:], rho) + length * drho
    return jnp.sum(weights * jnp.sqrt(jnp.sum(t * t, axis=-1)))


def total_length(d, length, offsets, slopes, tensions, weights):
    """``sum_m T_m l_m(d)`` (J) over the tendons of one element: ``offsets``, ``slopes``
    (M,Q,2), ``tensions`` (M,) (N; zero for tendons that do not pass this element)."""
    lengths = jax.vmap(element_length, in_axes=(None, None, 0, 0, None))(
        d, length, offsets, slopes, weights)
    return jnp.dot(tensions, lengths)


class ElementTendons(NamedTuple):
    """One element's slice: tension (M,) N (zero for tendons that do not pass it), offset,
    slope (M,Q,2) the routing and its derivative, length () m, weights (Q,) Gauss weights."""
    tension: jax.Array
    offset: jax.Array
    slope: jax.Array
    length: jax.Array
    weights: jax.Array


def force(el, part: ElementTendons, lam):
    """Nodal forces (12,) ``lam P(d)^T grad_d sum_m T_m l_m(d)`` of the tendons passing
    the element."""
    g = jax.grad(total_length)(el.d, part.length, part.offset, part.slope, part.tension,
                               part.weights)
    return lam * el.P.T @ g


def per_element(model) -> ElementTendons:
    """Every element's slice (E, ...): the tensions of the tendons passing it (by
    ``structure.tendon_elements``), their routing, the element length and the Gauss
    weights of ``structure.tendon_quadrature``."""
    s = model.structure
    member = jnp.asarray(np.array(s.tendon_elements, float))           # (M, E)
    weights = gauss_rule(s.tendon_quadrature)[1]
    return ElementTendons((member * model.tendon_tension[:, None]).T,
                          jnp.swapaxes(model.tendon_offset, 0, 1),
                          jnp.swapaxes(model.tendon_slope, 0, 1), model.length,
                          jnp.broadcast_to(jnp.asarray(weights), (s.n_elements, len(weights))))


def load_scale(model):
    """Sum of squares (N^2) of the tensions and of the moments they make at their largest
    offsets (divided by ``char_length``)."""
    r = jnp.max(jnp.linalg.norm(model.tendon_offset, axis=-1), axis=(1, 2))
    return jnp.sum(model.tendon_tension ** 2 * (1.0 + (r / model.char_length) ** 2))


def at_time(model, t) -> dict:
    """The tensions and the prescribed length changes of displacement-controlled tendons
    times their time laws at ``t`` (s)."""
    scales = model.tendon_law.scales(t)
    return {"tendon_tension": model.tendon_tension * scales,
            "tendon_displacement": model.tendon_displacement * scales}


TERM = Term("tendons", lambda model: bool(model.structure.tendon_names), force, per_element,
            load_scale, at_time=at_time)
