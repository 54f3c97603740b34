"""Displacement-controlled tendons as a coupling: the tendon's length change from the
stress-free shape is prescribed, ``Delta l_k(q) = delta_k``, and its tension ``t_k`` is
the unknown, the Lagrange multiplier of that constraint (Bertsekas' bordered KKT form).

The rods' residual holds the tendon forces ``t_k grad l_k``
(:mod:`simsoft_jax.physics.terms.tendons`: the potential ``t l``) once the tensions are set
from the multipliers (:func:`with_tensions`), and its tangent the tensions' geometric
stiffness. Beside the
chains the K tensions border the Newton system ``[[K, B], [C, D]]`` with

  B (N,6,K) = G^T, the residual per unit tension (the length gradients ``G`` in the
              nodes' right perturbations, :func:`gradients`),
  C (K,N,6) = G T(w), the length-change gradients in the unknowns (``T = T_SE3(w)`` of a
              time step's increments w, spec S61; the identity in statics),
  D (K,K)   = 0, and the residual r_z = ``Delta l(q) - delta`` (K,) (:func:`mismatch`),

where ``delta`` is the prescribed length change at the time of the step (its time law,
:func:`simsoft_jax.physics.terms.tendons.at_time`), in statics at the load level of the
continuation (:func:`simsoft_jax.solvers.statics.newton.at_level`). The scene is in m and N.
"""
from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np

from ..math import lie
from ..math.quadrature import gauss_rule
from ..physics import element
from ..physics.terms import tendons


def displaced(structure) -> tuple:
    """Indices of the displacement-controlled tendons (static)."""
    return tuple(k for k, flag in enumerate(structure.tendon_displaced) if flag)


def count(structure) -> int:
    """K, the displacement-controlled tendons: their tensions are K multipliers."""
    return len(displaced(structure))


def tension_controlled(model):
    """``model`` with every tendon tension-controlled (its structure's displacement flags
    cleared): the tendons' tensions are then the Model's ``tendon_tension`` and no
    coupling borders the chains for them (the stability count at the solved tensions,
    :func:`simsoft_jax.solvers.stability.negative_eigenvalues`)."""
    s = model.structure
    if not any(s.tendon_displaced):
        return model
    return model.replace(structure=dataclasses.replace(
        s, tendon_displaced=(False,) * len(s.tendon_displaced)))


def length_changes(model, R, p):
    """Length change (m) of every tendon from the stress-free shape, (M,), at the nodal
    frames R (N,3,3), p (N,3) (:func:`simsoft_jax.physics.terms.tendons.element_length` summed
    over the elements each tendon passes)."""
    s = model.structure
    weights = gauss_rule(s.tendon_quadrature)[1]
    a = jnp.asarray(s.element_nodes)
    d = jax.vmap(element.relative_twist)(R[a], p[a], R[a + 1], p[a + 1])
    lengths = jax.vmap(jax.vmap(tendons.element_length, in_axes=(None, None, 0, 0, None)),
                       in_axes=(0, 0, 1, 1, None))
    change = (lengths(d, model.length, model.tendon_offset, model.tendon_slope, weights)
              - lengths(model.d0, model.length, model.tendon_offset, model.tendon_slope,
                        weights))                                           # (E, M)
    member = jnp.asarray(np.array(s.tendon_elements, float))               # (M, E)
    return jnp.sum(member * change.T, axis=1)


def with_tensions(model, t):
    """``model`` with the tensions ``t`` (K,) N of its displacement-controlled tendons."""
    idx = jnp.asarray(displaced(model.structure), dtype=int)
    return model.replace(tendon_tension=model.tendon_tension.at[idx].set(t))


def mismatch(model, R, p):
    """``Delta l(q) - delta`` (K,) m of the displacement-controlled tendons at the frames
    R, p; ``model.tendon_displacement`` holds the prescribed changes ``delta`` (at the
    step's time in dynamics: :func:`simsoft_jax.model.loads.loads_at`)."""
    idx = jnp.asarray(displaced(model.structure), dtype=int)
    return length_changes(model, R, p)[idx] - model.tendon_displacement[idx]


def gradients(model, R, p):
    """``G`` (K,N,6): the derivatives of the displacement-controlled tendons' length
    changes in the nodes' right perturbations ``(R, p) exp(x)`` at ``x = 0`` (1 for
    translations, m/rad for rotations)."""
    idx = jnp.asarray(displaced(model.structure), dtype=int)

    def lengths(x):
        R1, p1 = jax.vmap(lie.compose_exp)(R, p, x)
        return length_changes(model, R1, p1)[idx]

    return jax.jacrev(lengths)(jnp.zeros_like(p, shape=p.shape[:1] + (6,)))


def border(model, R, p, T=None):
    """``(B (N,6,K), C (K,N,6), D (K,K), r_z (K,))`` of the module docstring at the
    frames R, p (unmasked: the caller reduces them like the chains, held dofs and
    sliding drives). ``T`` (N,6,6): the maps ``T_SE3(w)`` of a time step (None: statics,
    the identity)."""
    G = gradients(model, R, p)
    C = G if T is None else jnp.einsum("knj,nji->kni", G, T)
    k = G.shape[0]
    return (jnp.transpose(G, (1, 2, 0)), C, jnp.zeros((k, k), p.dtype),
            mismatch(model, R, p))
