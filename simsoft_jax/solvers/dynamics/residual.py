"""The dynamic residual of one generalized-alpha step and its iteration matrix (spec S47,
S61, S66).

``F(w) = r(q(w), v(w), vdot(w), t_{n+1})``, the sum of the residual terms, with the exact
iteration matrix ``M beta' + C_t gamma' + K_t T_SE3(w)``, both from the one assembler of
:mod:`simsoft_jax.physics.assembly` (its element and node :class:`~simsoft_jax.physics.assembly.Blocks`
``(r, K, C, M)``, by either tangent path), assembled into a block-tridiagonal matrix.
Element inertia (field maps and mass matrices) is computed from the Model's sectional
inertia inside the trace (:func:`element_inertia`), so a changed ``model.inertia`` changes
everything it should, gradients included. :func:`step_functions` adds the couplings beside
the chains (joints, rod-rod contact, displacement-controlled tendons, sliding drives).
"""
from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp

from ...couplings import coupling, rod_pairs
from ...physics import inertia, stick_slip
from ...math import lie
from ...physics.assembly import (apply_constraints, assemble_blocks, assemble_vector, element_blocks,
                        node_blocks, residual_vector)
from ...couplings.drives import reduce, slide_maps
from ...model.loads import loads_at
from ...model.model import Model
from ...physics.terms import registry
from .scheme import State, fields, iteration_factors


class ElementInertia(NamedTuple):
    """maps (E,G,6,12): velocity-field maps at the quadrature points; masses (E,12,12):
    element mass matrices (see :mod:`simsoft_jax.physics.inertia`)."""
    maps: jax.Array
    masses: jax.Array


def element_inertia(model: Model) -> ElementInertia:
    """Field maps and mass matrices of all elements from ``model.inertia`` (traced), with
    the inertia registered terms add (:func:`~simsoft_jax.physics.terms.registry.section_inertia`)."""
    return ElementInertia(*inertia.element_inertia(model.d0, model.length,
                                                   registry.section_inertia(model),
                                                   model.structure.inertia_kind))


def dynamic_residual(model: Model, inert: ElementInertia, R, p, v, vd, masked=True,
                     contact=True):
    """Global dynamic residual (N,6) (spec S47), held dofs zeroed (unless ``masked=False``:
    for the sliding drives' reduction, which then adds no rod-rod contact), rod-rod contact
    included unless ``contact=False`` (:mod:`simsoft_jax.couplings.rod_pairs`). ``model`` holds
    the loads at the time of evaluation (:func:`loads.loads_at`)."""
    s = model.structure
    r = residual_vector(model, 1.0, R, p, v, vd, inert)
    if not masked:
        return r
    if s.self_contact and contact:
        r = r + rod_pairs.residual(model, R, p)
    return r * s.free_mask()


def residual_and_iteration_matrix(model, inert, R, p, v, vd, w, beta_p, gamma_p, slide=None,
                                  tangent: str = "closed_form"):
    """Residual (N,6) and block-tridiagonal ``M beta' + C_t gamma' + K_t T(w)`` (S61, S66)
    from the assembler's blocks (:func:`simsoft_jax.physics.assembly.element_blocks`,
    :func:`~simsoft_jax.physics.assembly.node_blocks`). ``slide = (C, B, mask)`` (see
    :func:`drives.slide_maps`) reduces sliding drive nodes to their slide unknown before the
    held dofs are eliminated. ``tangent``: the element-block path. The couplings are not
    in it: :func:`step_functions` borders them on
    (:func:`simsoft_jax.couplings.coupling.couple`)."""
    s = model.structure
    n = s.n_nodes
    a = jnp.asarray(s.element_nodes)
    T = jax.vmap(lie.tangent_se3)(w)
    el = element_blocks(model, 1.0, R, p, v, vd, inert, tangent)
    TA, TB = T[a], T[a + 1]
    K_el = jnp.concatenate([el.K[:, :, :6] @ TA, el.K[:, :, 6:] @ TB], axis=2)
    r = assemble_vector(n, s.element_nodes, el.r)
    diag, upper, lower = assemble_blocks(n, s.element_nodes,
                                         el.M * beta_p + el.C * gamma_p + K_el)
    nodes = node_blocks(model, 1.0, R, v, vd, dynamic=True, tangent=tangent)
    if nodes is not None:
        r, diag = r + nodes.r, diag + nodes.K @ T
        if nodes.M is not None:
            diag = diag + nodes.M * beta_p + nodes.C * gamma_p
    if slide is not None:
        C, B, mask = slide
        r, blocks = reduce(C, B, r, (diag, upper, lower))
        return apply_constraints(mask, r, blocks)
    return apply_constraints(s.free_mask(), r, (diag, upper, lower))


class StepFunctions(NamedTuple):
    """``F(w)`` pieces of one step of size h from a state (see :func:`step_functions`):
    new_state(w) -> State; newton_residual(w, mu): the rods' residual of
    residual_and_matrix (sliding drives reduced, no couplings), without the matrix; residual_and_matrix(w, mu) -> (residual, blocks); t1: the time at
    the end of the step. With the couplings' multipliers ``mu`` (M,) (:func:`border_sizes`:
    joint multipliers, tendon tensions): system_residual(w, mu) -> (r (N,6), r_z (m,)),
    the Newton residual with the couplings' forces and own residuals at ``t1``;
    system(w, mu) -> the bordered iteration matrix and residual
    (:class:`~simsoft_jax.couplings.mechanisms.Coupled`; an empty border without couplings),
    both from :mod:`simsoft_jax.couplings.coupling`; loaded: the model with its loads at
    ``t1`` and the stick-slip friction's anchors of the step's start
    (:func:`simsoft_jax.physics.stick_slip.anchored`)."""
    new_state: object
    newton_residual: object
    residual_and_matrix: object
    system_residual: object
    system: object
    t1: jax.Array
    loaded: object


def border_sizes(structure) -> tuple[int, int]:
    """``(m, M)``: the unknowns beside the rods' chains in a dynamic step and how many of
    them are multipliers (:func:`simsoft_jax.couplings.coupling.border_sizes`)."""
    return coupling.border_sizes(structure)


def step_functions(model, inert, rho_inf, state: State, h,
                   tangent: str = "closed_form", pairs=None) -> StepFunctions:
    """F(w) pieces for one step of size h from ``state`` (spec S66); ``tangent`` picks the
    iteration matrix's element-block path; ``pairs``: the rod-rod contact's candidate
    pairs (:class:`simsoft_jax.couplings.rod_pairs.Pairs`, holding every pair that touches
    at the ``w`` evaluated; None: found at each ``w``)."""
    beta_p, gamma_p = iteration_factors(rho_inf, h)
    t1 = state.t + h
    loaded = stick_slip.anchored(loads_at(model, t1), state.anchor, t1)
    sliding = bool(model.structure.slide_drives)
    coupled = coupling.present(model.structure)

    def new_state(w):
        a1, v1, vd1 = fields(rho_inf, state, w, h)
        R1, p1 = jax.vmap(lie.compose_exp)(state.R, state.p, w)
        return State(R1, p1, v1, vd1, a1, t1, stick_slip.updated(loaded, R1, p1, t1))

    def slide(w):
        """The sliding drives' maps at ``w`` (:func:`slide_maps`), None without them."""
        return slide_maps(model, state.R, w) if sliding else None

    def newton_residual(w, mu):
        s1 = new_state(w)
        pulled = coupling.with_multipliers(loaded, mu)
        if not sliding:
            return dynamic_residual(pulled, inert, s1.R, s1.p, s1.v, s1.vd, contact=False)
        C, _, mask = slide(w)
        r = dynamic_residual(pulled, inert, s1.R, s1.p, s1.v, s1.vd, masked=False)
        return jnp.einsum("nij,nj->ni", C, r) * mask

    def residual_and_matrix(w, mu):
        s1 = new_state(w)
        return residual_and_iteration_matrix(coupling.with_multipliers(loaded, mu), inert,
                                             s1.R, s1.p, s1.v, s1.vd, w, beta_p, gamma_p,
                                             slide(w), tangent)

    def system_residual(w, mu):
        r = newton_residual(w, mu)
        if not coupled:
            return r, mu
        s1 = new_state(w)
        return coupling.coupled_residual(coupling.with_multipliers(loaded, mu), s1.R, s1.p,
                                         mu, r, slide(w), pairs)

    def system(w, mu):
        r, blocks = residual_and_matrix(w, mu)
        if not coupled:
            return coupling.couple(loaded, None, None, mu, r, blocks)
        s1 = new_state(w)
        return coupling.couple(coupling.with_multipliers(loaded, mu), s1.R, s1.p, mu, r,
                               blocks, jax.vmap(lie.tangent_se3)(w), slide(w), pairs)

    return StepFunctions(new_state, newton_residual, residual_and_matrix,
                         system_residual, system, t1, loaded)
