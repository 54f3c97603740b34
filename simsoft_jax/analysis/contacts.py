"""What the obstacles do to the rods in a solved state: per obstacle the total force, its
normal part, the largest penetration and the nodes in contact (result ``"contacts"``).

From the penalty of :mod:`simsoft_jax.physics.terms.contact` at the solution's frames: the force
of obstacle k on the rods is ``sum_e sum_i c_i psi'(delta_ik) n_ik`` (N, world; ``c_i``
the stations' weights, end caps included), its normal part the same sum of magnitudes
``psi'`` (N) (friction not included); the largest penetration is over every station
(Gauss points and nodes); a node is in contact when an element it belongs to has a
station with positive penetration.
"""
from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from ..couplings import rod_pairs
from ..physics.assembly import contact_data, element_poses
from ..physics.element import relative_twist
from ..model.loads import obstacles_at
from ..scene.scene_contact import SELF_NAME
from ..physics.terms import contact


@jax.jit
def _per_obstacle(model, R, p):
    s = model.structure
    RA, pA, RB, pB = element_poses(model, R, p)
    d = jax.vmap(relative_twist)(RA, pA, RB, pB)
    force, normal, pen = jax.vmap(lambda RA, pA, d, data, length: contact.summary(
        RA, pA, d, data, length, s.obstacle_kinds, s.contact_points))(
        RA, pA, d, contact_data(model), model.length)
    return force.sum(0), normal.sum(0), pen.max(0), pen > 0.0     # pen: (E,K)


def _nodes_in_contact(structure, touching):
    """``{rod: [node, ...]}`` from a per-element mask (E,) (nodes of touching elements)."""
    out = {}
    for info in structure.rods:
        hit = touching[info.first_element:info.first_element + info.elements]
        nodes = np.zeros(info.nodes, bool)
        nodes[:-1] |= hit
        nodes[1:] |= hit
        out[info.name] = np.flatnonzero(nodes).tolist()
    return out


def _at(model, t):
    """``model`` with its moving obstacles where they are at time ``t`` (s)."""
    if model.obstacle_shift is None:
        return model
    return model.replace(obstacles=obstacles_at(model, t)[0])


def report(model, R, p, time=None) -> dict | None:
    """``{obstacle: {"normal_force", "force", "max_penetration", "nodes"}}`` at frames
    ``R`` (N,3,3), ``p`` (N,3) (a static state: floats, (3,) and ``{rod: [nodes]}``) or
    (T,N,3,3), (T,N,3) at the times ``time`` (T,) s (a trajectory: each with a leading
    time axis, ``nodes`` a list per time; moving obstacles taken where they are at each
    time); None when the scene has no obstacles. With rod-rod contact the entry
    ``SELF_NAME`` (``"rods"``) holds :func:`simsoft_jax.couplings.rod_pairs.report`."""
    s = model.structure
    if not s.obstacle_kinds and not s.self_contact:
        return None
    R, p = jnp.asarray(R), jnp.asarray(p)
    out = {}
    if s.self_contact:
        out[SELF_NAME] = rod_pairs.report(model, R, p)
    if not s.obstacle_kinds:
        return out
    if p.ndim == 2:
        force, normal, pen, touch = jax.device_get(_per_obstacle(model, R, p))
    else:
        time = jnp.zeros(p.shape[0]) if time is None else jnp.asarray(time, jnp.float64)
        force, normal, pen, touch = jax.device_get(jax.vmap(
            lambda Ri, pi, ti: _per_obstacle(_at(model, ti), Ri, pi))(R, p, time))
    for k, name in enumerate(s.obstacle_names):
        if p.ndim == 2:
            nodes = _nodes_in_contact(s, touch[:, k])
        else:
            per_time = [_nodes_in_contact(s, t[:, k]) for t in touch]
            nodes = {r.name: [n[r.name] for n in per_time] for r in s.rods}
        out[name] = {"normal_force": normal[..., k], "force": force[..., k, :],
                     "max_penetration": pen[..., k], "nodes": nodes}
    return out
