"""The dynamic residual of one generalized-alpha step and its iteration matrix (spec S47,
S61, S66), from vmapped element kernels.

``F(w) = r(q(w), v(w), vdot(w), t_{n+1})``, the sum of the residual terms of
:mod:`simsoft_jax.terms`, with the exact iteration matrix
``M beta' + C_t gamma' + K_t T_SE3(w)`` built from element blocks, assembled into a
block-tridiagonal matrix. Element blocks by the ``tangent`` path: "closed_form"
(closed-form stress and dead-load tangents, ``jacfwd`` of the gyroscopic, follower-load,
in-element point-load, tendon and chamber terms) or "autodiff" (``jax.jacfwd`` of the
sum of the element terms in the frame perturbations, velocities and accelerations). Element inertia (field
maps and mass matrices) is computed from the Model's sectional inertia inside the trace
(:func:`element_inertia`), so a changed ``model.inertia`` changes everything it should,
gradients included.
"""
from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp

from .. import element, inertia, lie, mechanisms, rod_pairs, tendon_control
from ..assembly import (_nodal_load, apply_constraints, assemble_blocks, assemble_vector,
                        dead_distributed_force, element_data, element_force_and_tangent,
                        element_poses, follower_distributed_load, nodal_load_and_tangent,
                        attachments_and_tangents, contact_and_tangent,
                        jacfwd_terms_and_tangent, registered_and_tangents)
from ..drives import reduce, slide_maps
from ..loads import loads_at
from ..model import Model
from ..terms import autodiff as term_tangents
from ..terms import element_state, registry
from .scheme import State, fields, iteration_factors


class ElementInertia(NamedTuple):
    """maps (E,G,6,12): velocity-field maps at the quadrature points; masses (E,12,12):
    element mass matrices (see :mod:`simsoft_jax.inertia`)."""
    maps: jax.Array
    masses: jax.Array


def element_inertia(model: Model) -> ElementInertia:
    """Field maps and mass matrices of all elements from ``model.inertia`` (traced), with
    the inertia registered terms add (:func:`~simsoft_jax.terms.registry.section_inertia`)."""
    return ElementInertia(*inertia.element_inertia(model.d0, model.length,
                                                   registry.section_inertia(model),
                                                   model.structure.inertia_kind))


def _element_args(model: Model, inert: ElementInertia, R, p, v, vd):
    a = jnp.asarray(model.structure.element_nodes)
    d = jax.vmap(element.relative_twist)(R[a], p[a], R[a + 1], p[a + 1])
    ve = jnp.concatenate([v[a], v[a + 1]], axis=1)
    vde = jnp.concatenate([vd[a], vd[a + 1]], axis=1)
    return (R[a], d, ve, vde, inert.maps, inert.masses, model.d0, model.length,
            model.stiffness, registry.section_inertia(model), model.viscosity,
            model.distributed_world,
            model.distributed_local, model.mass_damping)


def _element_velocities(model: Model, v, vd):
    a = jnp.asarray(model.structure.element_nodes)
    return (jnp.concatenate([v[a], v[a + 1]], axis=1),
            jnp.concatenate([vd[a], vd[a + 1]], axis=1))


def dynamic_residual(model: Model, inert: ElementInertia, R, p, v, vd, masked=True):
    """Global dynamic residual (N,6) (spec S47), held dofs zeroed (unless ``masked=False``),
    rod-rod contact included (:mod:`simsoft_jax.rod_pairs`; scenes with it have no sliding
    drive, the only caller of ``masked=False``). ``model`` holds the loads at the time of
    evaluation (:func:`loads.loads_at`)."""
    s = model.structure
    residual = term_tangents.element_residual(s, 1.0, dynamic=True)
    f = jax.vmap(lambda RA, pA, RB, pB, ve, vde, data: residual(
        element_state(RA, pA, RB, pB, ve, vde), data))(
        *element_poses(model, R, p), *_element_velocities(model, v, vd),
        element_data(model, inert.maps, inert.masses))
    r = assemble_vector(s.n_nodes, s.element_nodes, f)
    if s.has_nodal_dead or s.has_nodal_follower:
        r = r + jax.vmap(_nodal_load(model, 1.0))(R, model.nodal_dead, model.nodal_follower)
    attached = attachments_and_tangents(model, 1.0, R, v, vd, dynamic=True)
    if attached is not None:
        r = r + attached[0]
    if s.self_contact:
        r = r + rod_pairs.residual(model, R, p)
    return r * s.free_mask() if masked else r


def residual_and_iteration_matrix(model, inert, R, p, v, vd, w, beta_p, gamma_p, slide=None,
                                  tangent: str = "closed_form"):
    """Residual (N,6) and block-tridiagonal ``M beta' + C_t gamma' + K_t T(w)`` (S61, S66).
    ``slide = (C, B, mask)`` (see :func:`drives.slide_maps`) reduces sliding drive nodes to their
    slide unknown before the held dofs are eliminated. ``tangent``: the element-block path
    (module docstring). Rod-rod contact is not in it: :func:`step_functions` borders it
    on (:func:`simsoft_jax.rod_pairs.system`)."""
    s = model.structure
    n = s.n_nodes
    a = jnp.asarray(s.element_nodes)
    dead, follower = dead_distributed_force(model, 1.0), follower_distributed_load(model, 1.0)
    T = jax.vmap(lie.tangent_se3)(w)

    def value_and_blocks(RA, d, ve, vde, maps, mass, d0, length, stiffness, inert, visc, qw, ql,
                         c_mass):
        # K_t: closed-form stress and load tangents (spec S42, S44), in the chart of S37;
        # C_t: gyroscopic (jacfwd in the 12 velocities) and viscous P^T Ups P / L (S42)
        P = element.strain_map(d)
        stress = element.section_stress(stiffness, (d - d0) / length)
        stress_jac = element.section_stress_jacobian(stiffness, length)
        gyro = lambda u: inertia.gyroscopic_force(  # noqa: E731
            maps, length, inert, u, s.inertia_kind, mass)
        C, g = jax.jacfwd(lambda u: (gyro(u),) * 2, has_aux=True)(ve)
        if s.has_viscosity:
            rate = lambda dd: element.strain_map(dd) @ ve / length  # noqa: E731
            stress = stress + visc * rate(d)
            stress_jac = stress_jac + visc[:, None] * jax.jacfwd(rate)(d)
            C = C + P.T @ (visc[:, None] * P) / length
        if s.has_mass_damping:  # c M_e v_e: M_e is fixed by the reference shape, so C only
            g, C = g + c_mass * (mass @ ve), C + c_mass * mass
        f, K = element_force_and_tangent(P, d, stress, stress_jac, RA, length, dead, follower,
                                         inertia.line_density(inert), qw, ql)
        return f + mass @ vde + g, K, C, mass

    if tangent == "autodiff":
        f_el, K_el, C_el, M_el = jax.vmap(term_tangents.element_tangents(s, 1.0, dynamic=True))(
            *element_poses(model, R, p), *_element_velocities(model, v, vd),
            element_data(model, inert.maps, inert.masses))
    else:
        f_el, K_el, C_el, M_el = jax.vmap(value_and_blocks)(
            *_element_args(model, inert, R, p, v, vd))
        point = jacfwd_terms_and_tangent(model, 1.0, R, p)
        if point is not None:
            f_el, K_el = f_el + point[0], K_el + point[1]
        touch = contact_and_tangent(model, R, p, v)
        if touch is not None:
            f_el, K_el = f_el + touch[0], K_el + touch[1]
            C_el = C_el if touch[2] is None else C_el + touch[2]
        registered = registered_and_tangents(model, 1.0, R, p, v)
        if registered is not None:
            f_el, K_el, C_el = (f_el + registered[0], K_el + registered[1],
                                C_el + registered[2])
    TA, TB = T[a], T[a + 1]
    K_el = jnp.concatenate([K_el[:, :, :6] @ TA, K_el[:, :, 6:] @ TB], axis=2)
    S_el = M_el * beta_p + C_el * gamma_p + K_el
    r = assemble_vector(n, s.element_nodes, f_el)
    diag, upper, lower = assemble_blocks(n, s.element_nodes, S_el)
    if s.has_nodal_dead or s.has_nodal_follower:
        f_n, k_n = nodal_load_and_tangent(model, 1.0, R, tangent)
        r = r + f_n
        diag = diag + k_n @ T
    attached = attachments_and_tangents(model, 1.0, R, v, vd, dynamic=True)
    if attached is not None:   # masses and offset loads: jacfwd on both paths
        f_m, K_m, C_m, M_m = attached
        r = r + f_m
        diag = diag + M_m * beta_p + C_m * gamma_p + K_m @ T
    if slide is not None:
        C, B, mask = slide
        r, blocks = reduce(C, B, r, (diag, upper, lower))
        return apply_constraints(mask, r, blocks)
    return apply_constraints(s.free_mask(), r, (diag, upper, lower))


class StepFunctions(NamedTuple):
    """``F(w)`` pieces of one step of size h from a state (see :func:`step_functions`):
    new_state(w) -> State; residual(w) (N,6), held dofs zeroed; newton_residual(w): the
    residual of residual_and_matrix (sliding drives reduced), without the matrix;
    residual_and_matrix(w) -> (residual, blocks); t1: the time at the end of the step.
    With multipliers ``mu`` (M,) (:func:`border_sizes`): the joint multipliers
    (:mod:`simsoft_jax.mechanisms`), or the tensions of displacement-controlled tendons
    (the multipliers of their length constraints, :mod:`simsoft_jax.tendon_control`), or
    none: system_residual(w, mu) -> (r (N,6), r_z (m,)), the Newton residual with the
    joints' forces and constraints (or the tendons' forces and length mismatches, m) at
    ``t1``; system(w, mu) -> the bordered iteration matrix and residual
    (:class:`~simsoft_jax.mechanisms.Coupled`, empty couplings without either)."""
    new_state: object
    residual: object
    newton_residual: object
    residual_and_matrix: object
    system_residual: object
    system: object
    t1: jax.Array


def border_sizes(structure) -> tuple[int, int]:
    """``(m, M)``: the unknowns beside the rods' chains in a dynamic step and how many of
    them are multipliers: the joints' coupling set (:mod:`simsoft_jax.mechanisms`), or
    one tension per displacement-controlled tendon, or the 6 dofs of each node the
    rod-rod contact pairs may couple (no multipliers; :mod:`simsoft_jax.rod_pairs`), or
    none (the scene refuses any two of them in one dynamic scene)."""
    if structure.joints:
        return mechanisms.coupling_count(structure), mechanisms.multiplier_count(structure)
    if structure.self_contact:
        return 6 * rod_pairs.coupled_nodes(structure), 0
    k = len(tendon_control.displaced(structure))
    return k, k


def step_functions(model, inert, rho_inf, state: State, h,
                   tangent: str = "closed_form") -> StepFunctions:
    """F(w) pieces for one step of size h from ``state`` (spec S66); ``tangent`` picks the
    iteration matrix's element-block path."""
    beta_p, gamma_p = iteration_factors(rho_inf, h)
    t1 = state.t + h
    loaded = loads_at(model, t1)
    sliding = bool(model.structure.slide_drives)

    def new_state(w):
        a1, v1, vd1 = fields(rho_inf, state, w, h)
        R1, p1 = jax.vmap(lie.compose_exp)(state.R, state.p, w)
        return State(R1, p1, v1, vd1, a1, t1)

    def residual(w):
        s1 = new_state(w)
        return dynamic_residual(loaded, inert, s1.R, s1.p, s1.v, s1.vd)

    def newton_residual(w):
        if not sliding:
            return residual(w)
        s1 = new_state(w)
        C, _, mask = slide_maps(model, state.R, w)
        r = dynamic_residual(loaded, inert, s1.R, s1.p, s1.v, s1.vd, masked=False)
        return jnp.einsum("nij,nj->ni", C, r) * mask

    def residual_and_matrix(w):
        s1 = new_state(w)
        slide = slide_maps(model, state.R, w) if sliding else None
        return residual_and_iteration_matrix(loaded, inert, s1.R, s1.p, s1.v, s1.vd, w,
                                             beta_p, gamma_p, slide, tangent)

    joints = bool(model.structure.joints)
    touching = bool(model.structure.self_contact)
    pair_dofs = border_sizes(model.structure)[0] if touching else 0
    displaced = jnp.asarray(tendon_control.displaced(model.structure), dtype=int)

    def pulled(mu):
        """``loaded`` with the tensions ``mu`` of the displacement-controlled tendons."""
        return loaded.replace(tendon_tension=loaded.tendon_tension.at[displaced].set(mu))

    def length_mismatch(w):
        """Length changes minus the prescribed ones at ``t1`` (K,), m."""
        s1 = new_state(w)
        target = model.tendon_displacement[displaced] * model.tendon_law.scales(t1)[displaced]
        return tendon_control.length_changes(model, s1.R, s1.p)[displaced] - target

    def system_residual(w, mu):
        if displaced.size:
            s1 = new_state(w)
            return (dynamic_residual(pulled(mu), inert, s1.R, s1.p, s1.v, s1.vd),
                    length_mismatch(w))
        r = newton_residual(w)
        if touching:    # the border's rows W U^T x - y = 0 hold exactly in every solve
            return r, jnp.zeros(pair_dofs, r.dtype)
        if not joints:
            return r, mu
        s1 = new_state(w)
        return mechanisms.residual(loaded, s1.R, s1.p, mu, r)

    def system(w, mu):
        if displaced.size:   # the border: tendon forces per unit tension, length gradients
            s1 = new_state(w)
            r, blocks = residual_and_iteration_matrix(pulled(mu), inert, s1.R, s1.p, s1.v,
                                                      s1.vd, w, beta_p, gamma_p, None, tangent)
            B = jax.jacfwd(lambda t: dynamic_residual(pulled(t), inert, s1.R, s1.p, s1.v,
                                                      s1.vd))(mu)
            C = jax.jacrev(length_mismatch)(w) * model.structure.free_mask()
            return mechanisms.Coupled(r, blocks, B, C, jnp.zeros((mu.size,) * 2, r.dtype),
                                      length_mismatch(w))
        r, blocks = residual_and_matrix(w)
        if touching:    # rod-rod contact: bordered with its cross blocks
            s1 = new_state(w)
            r, blocks, cpl = rod_pairs.system(loaded, s1.R, s1.p, r, blocks,
                                              jax.vmap(lie.tangent_se3)(w))
            return mechanisms.Coupled(r, blocks, cpl.B, cpl.C, cpl.D,
                                      jnp.zeros(pair_dofs, r.dtype))
        if not joints:
            n = r.shape[0]
            return mechanisms.Coupled(r, blocks, jnp.zeros((n, 6, 0), r.dtype),
                                      jnp.zeros((0, n, 6), r.dtype), jnp.zeros((0, 0), r.dtype),
                                      mu)
        s1 = new_state(w)
        return mechanisms.couple(loaded, s1.R, s1.p, mu, r, blocks,
                                 jax.vmap(lie.tangent_se3)(w))

    return StepFunctions(new_state, residual, newton_residual, residual_and_matrix,
                         system_residual, system, t1)
