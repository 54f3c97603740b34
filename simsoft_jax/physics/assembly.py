"""The one assembler: residuals and tangents of every term, for statics, dynamics, the
implicit derivative and the stability count.

:func:`element_blocks` and :func:`node_blocks` give :class:`Blocks` ``(r, K, C, M)`` per
element (12 rows) and per node (6 rows): the residual ``r = f_int + f_inertia - lam f_ext``
in the nodal frames (spec S47, S70), its left-invariant tangent ``K = d r(q o exp(xi)) /
d xi`` at xi = 0 and, in dynamics, its derivatives ``C`` in the nodal body velocities and
``M`` in the accelerations. :func:`residual_and_tangent` (statics) and
:func:`simsoft_jax.solvers.dynamics.residual.residual_and_iteration_matrix` (dynamics) only combine
them. The residual is the sum of the terms of :mod:`simsoft_jax.physics.terms` (those the
structure has, and the registered ones the Model holds, :mod:`simsoft_jax.physics.terms.registry`).
Two tangent paths, chosen for a whole solve by ``tangent``: ``"autodiff"`` (``jax.jacfwd``
of the sum of the element terms, :mod:`simsoft_jax.physics.terms.autodiff`) and ``"closed_form"``
(elastic stress, viscous stress, inertia, gravity, world-frame distributed loads and nodal
loads in closed form; contact per contact point,
:func:`simsoft_jax.physics.terms.contact.force_and_tangent`; follower distributed loads and the
registered terms (:mod:`simsoft_jax.physics.terms.registry`) by ``jax.jacfwd`` of their own
sums); both give the same exact
tangent (tests/test_tangent_paths.py). Element blocks are assembled into a
block-tridiagonal matrix of 6x6 blocks ``(diag (N,6,6), upper (N-1,6,6), lower
(N-1,6,6))``, ``upper[i] = K[i, i+1]``, ``lower[i] = K[i+1, i]``. Held dofs get an identity
row/column and a zero residual, so the structure never changes. Linear solves:
:mod:`simsoft_jax.math.linalg`.
"""
from __future__ import annotations

from typing import TYPE_CHECKING, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from . import element, inertia
from ..math import lie
from ..math.xla import take_rows
from .inertia import line_density
from .terms import ElementData, element_state
from .terms import autodiff as term_tangents
from .terms import masses as mass_term
from .terms import contact, offset_loads, registry, static_friction

if TYPE_CHECKING:     # the model layer builds on this one: the type is only named here
    from ..model.model import Model

TANGENTS = ("closed_form", "autodiff")


def check_tangent(tangent: str) -> str:
    """``tangent`` if it names a tangent path, else a clear error."""
    if tangent not in TANGENTS:
        raise ValueError(f"tangent: must be one of {TANGENTS}, got {tangent!r}")
    return tangent


def dead_distributed_force(model: Model, lam):
    """``-lam (q_world + rho_a g)`` (3,) per element as a function of ``(rho_a, q_world)``:
    the dead force per unit length (N/m) of gravity and world-frame distributed loads on
    the residual side, or None when the scene has neither (then nothing of it is traced)."""
    g = model.gravity
    if model.distributed_world is None:
        return None if g is None else lambda rho_a, q_world: -lam * (rho_a * g)
    if g is None:
        return lambda rho_a, q_world: -lam * q_world
    return lambda rho_a, q_world: -lam * (q_world + rho_a * g)


def follower_distributed_load(model: Model, lam):
    """``-lam f_local`` (12,) of one element's follower distributed load as a function of
    ``(d, P, length, q_local)`` (:func:`element.follower_distributed_force`), or None when
    the scene has none."""
    if model.distributed_local is None:
        return None
    return lambda d, P, length, q_local: -lam * element.follower_distributed_force(
        d, P, length, q_local)


def follower_load_and_tangent(load, d, P, length, q_local):
    """Value (12,) and left-invariant tangent (12,12) of a :func:`follower_distributed_load`:
    it depends on the frames through d only, so ``jax.jacfwd`` in the 6 components of d is
    chained with the chart ``d + P(d) x`` of spec S37."""
    def f(y):
        dd = d + y
        return load(dd, element.strain_map(dd), length, q_local)

    jac, val = jax.jacfwd(lambda y: (f(y),) * 2, has_aux=True)(jnp.zeros(6, d.dtype))
    return val, jac @ P


def element_force_and_tangent(P, d, stress, stress_jacobian, RA, length, dead, follower,
                              rho_a, q_world, q_local):
    """Nodal forces (12,) and left-invariant tangent (12,12) of one element from its section
    stress (6,) and ``d stress / d d`` (6,6) (elastic, plus viscous in dynamics) and its
    distributed loads: ``dead`` (:func:`dead_distributed_force`, of ``rho_a, q_world``) and
    ``follower`` (:func:`follower_distributed_load`, of ``q_local`` (3,)), each None when
    the scene has none.

    The dead load enters as an extra stress and stress Jacobian plus rigid-motion terms
    (:func:`element.dead_load_terms`), so one geometric term serves both (spec S42, S44).
    """
    direct = None
    if dead is not None:
        s_q, S_q, f_direct, K_direct = element.dead_load_terms(RA, d, P, length,
                                                               dead(rho_a, q_world))
        stress, stress_jacobian = stress + s_q, stress_jacobian + S_q
        direct = (f_direct, K_direct)
    f, k = element.stress_force_and_tangent(P, d, stress, stress_jacobian)
    if direct is not None:
        f, k = f + direct[0], k + direct[1]
    if follower is not None:
        f_q, k_q = follower_load_and_tangent(follower, d, P, length, q_local)
        f, k = f + f_q, k + k_q
    return f, k


def contact_and_tangent(model: Model, R, p, v=None):
    """Nodal forces (E,12) of the contact with the obstacles
    (:mod:`simsoft_jax.physics.terms.contact`), their left-invariant tangents (E,12,12) and, in
    dynamics with the regularized friction or the normal damping (``v`` (N,6) the nodal
    body velocities), their derivatives in the nodal velocities (E,12,12) (else None),
    all by :func:`~simsoft_jax.physics.terms.contact.force_and_tangent` (the friction in
    dynamics only). None when the scene has no obstacles. Contact is a reaction: it is
    not scaled by the load level."""
    s = model.structure
    if not s.obstacle_kinds:
        return None
    friction = v is not None and contact.dynamic_friction(
        s.friction_law, model.obstacle_friction, model.friction_anchor)
    a = jnp.asarray(s.element_nodes)
    ve = (jnp.zeros((s.n_elements, 12), p.dtype) if v is None
          else jnp.concatenate([v[a], v[a + 1]], axis=1))

    def one(RA, pA, RB, pB, ve, data):
        return contact.force_and_tangent(element_state(RA, pA, RB, pB, ve, ve), data.contact,
                                         data.length, s.obstacle_kinds, s.contact_points,
                                         friction)

    return jax.vmap(one)(*element_poses(model, R, p), ve, element_data(model))


def registered_and_tangents(model: Model, lam, R, p, v=None):
    """Nodal forces (E,12) of the registered terms (:mod:`simsoft_jax.physics.terms.registry`),
    their left-invariant tangents (E,12,12) by ``jax.jacfwd`` in the 12 right
    perturbations of the two nodal frames and, in dynamics (``v`` (N,6) the nodal body
    velocities), the derivatives (E,12,12) of the terms that read velocities in the nodal
    velocities (else None). Terms that do not read velocities are differentiated in the
    frames only. None when the model has no registered term."""
    if not registry.active(model):
        return None
    dynamic = v is not None
    groups = [(registry.element_parts(model, velocity=False), False)]
    if dynamic:
        groups.append((registry.element_parts(model, velocity=True), True))
    else:   # in statics every term is evaluated at rest
        groups[0] = (registry.element_parts(model), False)
    a = jnp.asarray(model.structure.element_nodes)
    zero_v = jnp.zeros((model.structure.n_elements, 12), p.dtype)
    ve = jnp.concatenate([v[a], v[a + 1]], axis=1) if dynamic else zero_v
    out = None
    for parts, with_velocity in groups:
        if parts is None:
            continue

        def one(RA, pA, RB, pB, ve, parts, with_velocity=with_velocity):
            def f(y):
                RA1, pA1 = lie.compose_exp(RA, pA, y[:6])
                RB1, pB1 = lie.compose_exp(RB, pB, y[6:12])
                u = ve + y[12:] if with_velocity else ve
                el = element_state(RA1, pA1, RB1, pB1, u, jnp.zeros_like(ve))
                value = registry.forces(el, parts, lam)
                return value, value

            jac, value = jax.jacfwd(f, has_aux=True)(
                jnp.zeros(24 if with_velocity else 12, RA.dtype))
            return value, jac[:, :12], jac[:, 12:] if with_velocity else None

        f_el, k_el, c_el = jax.vmap(one)(*element_poses(model, R, p), ve, parts)
        if out is None:
            out = (f_el, k_el, c_el)
        else:
            c = c_el if out[2] is None else (out[2] if c_el is None else out[2] + c_el)
            out = (out[0] + f_el, out[1] + k_el, c)
    return out


def element_data(model: Model, maps=None, masses=None) -> ElementData:
    """The per-element model arrays (E, ...) of :class:`~simsoft_jax.physics.terms.ElementData`
    (``maps``, ``masses``: element inertia in dynamics, None in statics; in dynamics the
    section inertia includes what registered terms add,
    :func:`~simsoft_jax.physics.terms.registry.section_inertia`)."""
    n = model.length.shape[0]
    inertia = model.inertia if maps is None else registry.section_inertia(model)
    gravity = None if model.gravity is None else jnp.broadcast_to(model.gravity, (n, 3))
    return ElementData(model.d0, model.length, model.stiffness, inertia,
                       model.viscosity, model.distributed_world, model.distributed_local,
                       gravity, maps, masses,
                       model.mass_damping, contact=contact_data(model),
                       parts=registry.element_parts(model))


def rod_end_flags(structure) -> np.ndarray:
    """Static (E,2) flags: 1 where an element's node A is its rod's first node (column 0)
    or its node B the rod's last (column 1), else 0; a rod end joined to another rod's
    node (a weld or ball joint) is no free end: welded rods meet as one rod does."""
    ends = np.zeros((structure.n_elements, 2))
    for info in structure.rods:
        ends[info.first_element, 0] = ends[info.first_element + info.elements - 1, 1] = 1.0
    a = np.asarray(structure.element_nodes)
    rod_nodes = set(a.tolist()) | set((a + 1).tolist())
    for _, na, nb in structure.joints:
        if na in rod_nodes and nb in rod_nodes:
            for n in (na, nb):
                ends[a == n, 0] = 0.0
                ends[a + 1 == n, 1] = 0.0
    return ends


def contact_data(model: Model):
    """Per-element :class:`~simsoft_jax.physics.terms.contact.ContactData` (E, ...), the obstacle
    rows broadcast to every element, the end caps (E,2) the contact radius at each rod's
    first and last node, the normal damping coefficient ``2 zeta sqrt(k rhoA)`` (E,)
    N s/m^2 (``zeta = model.contact_damping``; None without it); None when the scene has
    no obstacles."""
    if not model.structure.obstacle_kinds:
        return None
    n = model.length.shape[0]

    def each(a):
        return jnp.broadcast_to(a, (n,) + jnp.shape(a))

    ends = rod_end_flags(model.structure)
    friction = None if model.obstacle_friction is None else each(model.obstacle_friction)
    damping = None
    if model.contact_damping is not None:   # c = 2 zeta sqrt(k rhoA) (contact.py, D1)
        rho_a = jax.vmap(line_density)(model.inertia)
        damping = 2.0 * model.contact_damping * jnp.sqrt(model.contact_stiffness * rho_a)
    return contact.ContactData(model.contact_radius, model.contact_stiffness,
                               each(model.obstacles), friction,
                               each(model.slip_velocity), each(model.obstacle_velocity),
                               jnp.asarray(ends) * model.contact_radius[:, None],
                               model.friction_anchor, damping)


def static_friction_and_tangent(model: Model, R, p, previous, tangent: bool = True):
    """Nodal forces (E,12) of the quasi-static friction with the obstacles
    (:mod:`simsoft_jax.physics.terms.static_friction`) and (when ``tangent``, else None) their
    left-invariant tangents (E,12,12) by ``jax.jacfwd`` in the 12 right perturbations of
    the two nodal frames, the stations of the previous load level fixed; ``previous`` =
    (R (N,3,3), p (N,3)) the frames there. None when the structure has no friction or
    ``previous`` is None."""
    s = model.structure
    if previous is None or model.obstacle_friction is None:
        return None
    RA0, pA0, RB0, pB0 = element_poses(model, *previous)
    d0 = jax.vmap(element.relative_twist)(RA0, pA0, RB0, pB0)
    before = jax.vmap(lambda R, p, d: static_friction.stations(R, p, d, s.contact_points))(
        RA0, pA0, d0)
    zero = jnp.zeros(12, p.dtype)

    def one(RA, pA, RB, pB, before, scale, data):
        def f(y):
            RA1, pA1 = lie.compose_exp(RA, pA, y[:6])
            RB1, pB1 = lie.compose_exp(RB, pB, y[6:])
            value = static_friction.force(element_state(RA1, pA1, RB1, pB1, zero, zero),
                                          before, scale, data.contact, data.length,
                                          s.obstacle_kinds, s.contact_points)
            return value, value

        if not tangent:
            return f(zero)[0], None
        jac, value = jax.jacfwd(f, has_aux=True)(zero)
        return value, jac

    return jax.vmap(one)(*element_poses(model, R, p), before, model.slip_displacement,
                         element_data(model))


def element_poses(model: Model, R, p):
    """Frames of the two nodes of every element: RA, pA, RB, pB (E,3,3)/(E,3)."""
    a = np.asarray(model.structure.element_nodes)
    return take_rows(R, a), take_rows(p, a), take_rows(R, a + 1), take_rows(p, a + 1)


def _nodal_load(model: Model, lam):
    """``-lam f_ext`` at one node (:mod:`simsoft_jax.physics.terms.nodal`; spec S43)."""
    return term_tangents.node_residual(lam)


def _placed(n_rows, rows, x):
    """``x`` (E, ...) with its row e moved to row ``rows[e]`` of an (n_rows, ...) array of
    zeros; ``rows`` static and distinct. A gather with static indices (or a pad for
    consecutive rows): XLA on CPU expands a scatter into a loop over the rows."""
    rows = np.asarray(rows, dtype=int)
    if rows.size and np.array_equal(rows, np.arange(rows[0], rows[0] + rows.size)):
        pad = [(int(rows[0]), n_rows - int(rows[-1]) - 1)] + [(0, 0)] * (x.ndim - 1)
        return jnp.pad(x, pad)
    source = np.full(n_rows, len(rows))
    source[rows] = np.arange(len(rows))
    return take_rows(jnp.concatenate([x, jnp.zeros((1,) + x.shape[1:], x.dtype)]), source)


def assemble_vector(n_nodes, element_nodes, f_el):
    """Element vectors (E,12) summed into nodes (N,6) (spec S47)."""
    a = np.asarray(element_nodes, dtype=int)
    return _placed(n_nodes, a, f_el[:, :6]) + _placed(n_nodes, a + 1, f_el[:, 6:])


def assemble_blocks(n_nodes, element_nodes, k_el):
    """Element matrices (E,12,12) -> block-tridiagonal ``(diag, upper, lower)`` (spec 3.6)."""
    a = np.asarray(element_nodes, dtype=int)
    diag = _placed(n_nodes, a, k_el[:, :6, :6]) + _placed(n_nodes, a + 1, k_el[:, 6:, 6:])
    n_off = max(n_nodes - 1, 0)
    return diag, _placed(n_off, a, k_el[:, :6, 6:]), _placed(n_off, a, k_el[:, 6:, :6])


def nodal_load_and_tangent(model: Model, lam, R, tangent: str = "closed_form"):
    """``-lam f_ext`` per node (N,6) and its left-invariant derivative (N,6,6) (spec S43):
    with ``a = R^T F`` (dead force or moment), ``(R exp(theta))^T F = a + skew(a) theta``,
    so the rotation columns hold ``-lam skew(R^T F)``, ``-lam skew(R^T M)``; follower loads
    do not depend on the frame. ``tangent="autodiff"``: ``jax.jacfwd`` of the node terms."""
    if tangent == "autodiff":
        return jax.vmap(term_tangents.node_tangent(lam))(R, model.nodal_dead,
                                                            model.nodal_follower)
    r = jax.vmap(_nodal_load(model, lam))(R, model.nodal_dead, model.nodal_follower)
    k = jnp.zeros(R.shape[:1] + (6, 6), R.dtype)
    if model.nodal_dead is not None:
        local = jnp.einsum("nji,nkj->nki", R, model.nodal_dead.reshape(-1, 2, 3))
        skews = jax.vmap(jax.vmap(lie.skew))(local)                     # (N, 2, 3, 3)
        k = k.at[:, :3, 3:].set(-lam * skews[:, 0]).at[:, 3:, 3:].set(-lam * skews[:, 1])
    return r, k


def attachments_and_tangents(model: Model, lam, R, v=None, vd=None, dynamic: bool = False):
    """Node terms of the attached masses (:mod:`~simsoft_jax.physics.terms.masses`) and of the dead
    forces at offset points (:mod:`~simsoft_jax.physics.terms.offset_loads`), scattered to the
    nodes: residual (N,6) and its derivatives (N,6,6) in the rotation perturbation
    ``R exp(theta)`` (K; translation columns zero: these terms do not depend on the
    position), in the body velocity (C) and acceleration (M) (dynamics; None in
    statics), all by ``jax.jacfwd`` on both tangent paths. None when the scene has
    neither. ``v, vd`` (N,6): nodal body velocities and accelerations (dynamics)."""
    s = model.structure
    with_gravity = model.gravity is not None
    weighs = with_gravity or dynamic
    if not (s.offset_load_nodes or (s.mass_nodes and weighs)):
        return None
    n, dtype = s.n_nodes, R.dtype
    size = 15 if dynamic else 3          # theta (3); dV (6), dVdot (6) in dynamics
    out = [jnp.zeros((n, 6), dtype), jnp.zeros((n, 6, 6), dtype)]
    if dynamic:
        out += [jnp.zeros((n, 6, 6), dtype), jnp.zeros((n, 6, 6), dtype)]

    def scatter(nodes, one, *args):
        idx = jnp.asarray(nodes)
        zero = jnp.zeros(6, dtype)
        V = v[idx] if dynamic else jnp.broadcast_to(zero, (len(nodes), 6))
        Vd = vd[idx] if dynamic else jnp.broadcast_to(zero, (len(nodes), 6))

        def value_and_jac(Ri, Vi, Vdi, *a):
            def f(y):
                value = one(Ri @ lie.exp_so3(y[:3]), Vi + y[3:9] if dynamic else Vi,
                            Vdi + y[9:15] if dynamic else Vdi, *a)
                return value, value
            jac, value = jax.jacfwd(f, has_aux=True)(jnp.zeros(size, dtype))
            return value, jac

        value, jac = jax.vmap(value_and_jac)(R[idx], V, Vd, *args)
        out[0] = out[0].at[idx].add(value)
        out[1] = out[1].at[idx, :, 3:].add(jac[:, :, :3])
        if dynamic:
            out[2] = out[2].at[idx].add(jac[:, :, 3:9])
            out[3] = out[3].at[idx].add(jac[:, :, 9:15])

    if s.mass_nodes and weighs:
        scatter(s.mass_nodes, lambda Ri, Vi, Vdi, m, c, J: mass_term.force(
            Ri, Vi, Vdi, m, c, J, model.gravity, lam, with_gravity, dynamic),
            model.mass, model.mass_offset, model.mass_inertia)
    if s.offset_load_nodes:
        scatter(s.offset_load_nodes, lambda Ri, Vi, Vdi, F, c: offset_loads.force(
            Ri, F, c, lam), model.offset_force, model.offset_point)
    return tuple(out) if dynamic else (out[0], out[1], None, None)


class Blocks(NamedTuple):
    """What the assembler gives for elements (rows of 12) or nodes (rows of 6): the
    residual r, its left-invariant tangent K in the frame perturbations and, in dynamics,
    its derivatives C in the body velocities and M in the accelerations (None in statics)."""
    r: jax.Array
    K: jax.Array
    C: jax.Array = None
    M: jax.Array = None


def element_velocities(model: Model, v, vd):
    """Nodal body velocities and accelerations (N,6) gathered per element: (E,12) each."""
    a = jnp.asarray(model.structure.element_nodes)
    return (jnp.concatenate([v[a], v[a + 1]], axis=1),
            jnp.concatenate([vd[a], vd[a + 1]], axis=1))


def _static_kernel(model: Model, lam):
    """One element's closed-form forces and tangent in statics: elastic stress, dead and
    follower distributed loads (spec S42, S44; follower loads by jacfwd)."""
    dead = dead_distributed_force(model, lam)
    follower = follower_distributed_load(model, lam)

    def kernel(RA, d, d0, length, stiffness, rho_a, q_world, q_local):
        P = element.strain_map(d)
        return element_force_and_tangent(
            P, d, element.section_stress(stiffness, (d - d0) / length),
            element.section_stress_jacobian(stiffness, length), RA, length,
            dead, follower, rho_a, q_world, q_local)

    return kernel


def _dynamic_kernel(model: Model, lam):
    """One element's closed-form blocks in dynamics: the static kernel's terms, the
    viscous stress ``P^T Ups P v / L`` (S42), the gyroscopic force (jacfwd in the 12
    velocities), mass damping ``c M_e v_e`` and the inertia ``M_e vdot_e``."""
    s = model.structure
    dead = dead_distributed_force(model, lam)
    follower = follower_distributed_load(model, lam)

    def kernel(RA, d, ve, vde, maps, mass, d0, length, stiffness, inert, visc, qw, ql, c_mass):
        P = element.strain_map(d)
        stress = element.section_stress(stiffness, (d - d0) / length)
        stress_jac = element.section_stress_jacobian(stiffness, length)
        gyro = lambda u: inertia.gyroscopic_force(  # noqa: E731
            maps, length, inert, u, s.inertia_kind, mass)
        C, g = jax.jacfwd(lambda u: (gyro(u),) * 2, has_aux=True)(ve)
        if visc is not None:
            rate = lambda dd: element.strain_map(dd) @ ve / length  # noqa: E731
            stress = stress + visc * rate(d)
            stress_jac = stress_jac + visc[:, None] * jax.jacfwd(rate)(d)
            C = C + P.T @ (visc[:, None] * P) / length
        if c_mass is not None:  # c M_e v_e: M_e is fixed by the reference shape, so C only
            g, C = g + c_mass * (mass @ ve), C + c_mass * mass
        f, K = element_force_and_tangent(P, d, stress, stress_jac, RA, length, dead, follower,
                                         inertia.line_density(inert), qw, ql)
        return f + mass @ vde + g, K, C, mass

    return kernel


def element_blocks(model: Model, lam, R, p, v=None, vd=None, inert=None,
                   tangent: str = "closed_form") -> Blocks:
    """The assembler's element part: :class:`Blocks` (E, ...) of every element term at
    load level ``lam`` (statics) or of the dynamic residual (``inert`` = (maps, masses),
    :func:`simsoft_jax.solvers.dynamics.residual.element_inertia`, with the nodal velocities and
    accelerations ``v, vd`` (N,6)). ``tangent``: "autodiff" differentiates the sum of the
    terms (:mod:`simsoft_jax.physics.terms.autodiff`); "closed_form" takes the elastic, viscous,
    inertial and distributed-load blocks in closed form, the contact per contact point
    (:func:`contact_and_tangent`) and the registered terms by ``jax.jacfwd`` of their own
    sums (:func:`registered_and_tangents`: point loads in elements, offset gravity,
    tendons, chambers, magnetic couples, fluid loads)."""
    s = model.structure
    dynamic = inert is not None
    if dynamic:
        ve, vde = element_velocities(model, v, vd)
    else:
        ve = vde = jnp.zeros((s.n_elements, 12), p.dtype)
    if tangent == "autodiff":
        data = (element_data(model, inert.maps, inert.masses) if dynamic
                else element_data(model))
        return Blocks(*jax.vmap(term_tangents.element_tangents(s, lam, dynamic))(
            *element_poses(model, R, p), ve, vde, data))
    RA, pA, RB, pB = element_poses(model, R, p)
    d = jax.vmap(element.relative_twist)(RA, pA, RB, pB)
    if dynamic:
        f, K, C, M = jax.vmap(_dynamic_kernel(model, lam))(
            RA, d, ve, vde, inert.maps, inert.masses, model.d0, model.length,
            model.stiffness, registry.section_inertia(model), model.viscosity,
            model.distributed_world, model.distributed_local, model.mass_damping)
    else:
        f, K = jax.vmap(_static_kernel(model, lam))(
            RA, d, model.d0, model.length, model.stiffness,
            jax.vmap(line_density)(model.inertia), model.distributed_world,
            model.distributed_local)
        C = M = None
    for extra in (contact_and_tangent(model, R, p, v), registered_and_tangents(model, lam, R, p, v)):
        if extra is None:
            continue
        f, K = f + extra[0], K + extra[1]
        if dynamic and extra[2] is not None:
            C = C + extra[2]
    return Blocks(f, K, C, M)


def node_blocks(model: Model, lam, R, v=None, vd=None, dynamic: bool = False,
                tangent: str = "closed_form") -> Blocks | None:
    """The assembler's node part: :class:`Blocks` (N, ...) of the nodal loads (spec S43)
    and of the attached masses and offset loads (:func:`attachments_and_tangents`); C and
    M None where no node term reads velocities or accelerations (statics, nodal loads
    only); None when the scene has no node term."""
    loads = (nodal_load_and_tangent(model, lam, R, tangent)
             if model.nodal_dead is not None or model.nodal_follower is not None else None)
    attached = attachments_and_tangents(model, lam, R, v, vd, dynamic)
    if loads is None and attached is None:
        return None
    if loads is None:
        return Blocks(*attached)
    if attached is None:
        return Blocks(*loads)
    return Blocks(loads[0] + attached[0], loads[1] + attached[1], attached[2], attached[3])


def residual_vector(model: Model, lam, R, p, v=None, vd=None, inert=None, previous=None):
    """Global residual (N,6) of every term, unmasked (spec S47/S70): the sum of the
    element terms (:func:`simsoft_jax.physics.terms.autodiff.element_residual`, in dynamics with
    ``inert``, ``v``, ``vd`` as for :func:`element_blocks`), the quasi-static friction
    against the frames ``previous`` of the last load level (statics;
    :func:`static_friction_and_tangent`) and the node terms."""
    s = model.structure
    dynamic = inert is not None
    if dynamic:
        ve, vde = element_velocities(model, v, vd)
        data = element_data(model, inert.maps, inert.masses)
    else:
        ve = vde = jnp.zeros((s.n_elements, 12), p.dtype)
        data = element_data(model)
    terms = term_tangents.element_residual(s, lam, dynamic)
    f_el = jax.vmap(lambda RA, pA, RB, pB, ve, vde, data: terms(
        element_state(RA, pA, RB, pB, ve, vde), data))(*element_poses(model, R, p), ve, vde,
                                                       data)
    friction = static_friction_and_tangent(model, R, p, previous, tangent=False)
    if friction is not None:
        f_el = f_el + friction[0]
    r = assemble_vector(s.n_nodes, s.element_nodes, f_el)
    if model.nodal_dead is not None or model.nodal_follower is not None:
        r = r + jax.vmap(_nodal_load(model, lam))(R, model.nodal_dead, model.nodal_follower)
    attached = attachments_and_tangents(model, lam, R, v, vd, dynamic)
    if attached is not None:
        r = r + attached[0]
    return r


def residual(model: Model, R, p, lam=1.0, previous=None):
    """Global static residual (N,6), held dofs zeroed (spec S47/S70): :func:`residual_vector`
    at load level ``lam``, with the quasi-static friction against ``previous``."""
    return residual_vector(model, lam, R, p, previous=previous) * model.structure.free_mask()


def residual_and_tangent(model: Model, R, p, lam=1.0, tangent: str = "closed_form",
                         previous=None):
    """Static residual (N,6) and block-tridiagonal tangent ``(diag, upper, lower)`` (spec
    S70) from :func:`element_blocks` and :func:`node_blocks` by the ``tangent`` path; with
    ``previous`` (the frames of the last load level) the quasi-static friction is added
    (by ``jax.jacfwd`` on both paths, :func:`static_friction_and_tangent`)."""
    s = model.structure
    blocks = element_blocks(model, lam, R, p, tangent=tangent)
    f_el, k_el = blocks.r, blocks.K
    friction = static_friction_and_tangent(model, R, p, previous)
    if friction is not None:
        f_el, k_el = f_el + friction[0], k_el + friction[1]
    r = assemble_vector(s.n_nodes, s.element_nodes, f_el)
    diag, upper, lower = assemble_blocks(s.n_nodes, s.element_nodes, k_el)
    nodes = node_blocks(model, lam, R, tangent=tangent)
    if nodes is not None:
        r, diag = r + nodes.r, diag + nodes.K
    return apply_constraints(s.free_mask(), r, (diag, upper, lower))


def apply_constraints(mask, r, blocks):
    """Zero held rows of ``r``; identity rows/columns for held dofs in the blocks."""
    diag, upper, lower = blocks
    diag = mask[:, :, None] * diag * mask[:, None, :] + jax.vmap(jnp.diag)(1.0 - mask)
    upper = mask[:-1, :, None] * upper * mask[1:, None, :]
    lower = mask[1:, :, None] * lower * mask[:-1, None, :]
    return r * mask, (diag, upper, lower)
