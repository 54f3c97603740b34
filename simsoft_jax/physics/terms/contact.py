"""Contact of an element with rigid obstacles: a smooth penalty on the gap, looked for along
the element's helical interpolation, and regularized Coulomb friction (dynamics).

Where. The centreline point at ``xi`` in [0, 1] is the position part of
``H_A exp(xi d)`` (spec S33): ``x(xi) = p_A + R_A T_SO3(xi d_w)^T (xi d_u)``; contact is
looked for at the ``n`` Gauss-Legendre points of the element (``[contact]
quadrature_points``), so a coarse rod cannot pass through an obstacle smaller than an
element between its nodes, and at its two nodes (``xi = 0, 1``). The nodes carry weight
only at a rod's two ends, the end caps: there the station stands for the rod's rounded
end, a length ``r`` (the contact radius) of the line penalty, so a free end pushed into
an obstacle meets it at the node instead of sinking until a Gauss point, a fraction of
an element behind the end, touches (an end pushed with a force ``F`` sinks by
``delta ~ F / (k r) + eps / 2``). At the other nodes the weight is 0: their stations
count only in the reported penetration.

Normal contact (penalty). With the obstacle's signed distance ``phi(x)``
(:mod:`simsoft_jax.physics.obstacles`) and the rod's contact radius ``r``, the gap is
``g = phi(x) - r`` and the penetration ``delta = -g``. The energy per unit length is the
C2 penalty

    psi(delta) = 0                                    delta <= 0
               = k delta^3 / (6 eps)                  0 < delta < eps
               = k (delta - eps/2)^2 / 2 + k eps^2/24 delta >= eps

with ``k`` the penalty stiffness (N/m^2: the line load per metre of penetration, once past
the smoothing width) and ``eps = SMOOTHING * r`` (a cubic start, so the force
``psi'(delta)`` and its slope are continuous and Newton sees no kink). A line load ``q``
(N/m) pressing the rod on an obstacle sinks it by ``delta ~ q/k + eps/2`` (or
``sqrt(2 eps q/k)`` while ``delta < eps``). The element's energy is
``sum_i c_i sum_k psi(delta_k(x(xi_i)))`` with the station weights ``c_i`` (m): ``L w_i``
at the Gauss points (weights ``w_i`` on [0, 1], ``L`` the reference length), the cap
lengths at the two nodes (:func:`station_weights`).

Nodal forces. The right perturbations of the two nodal frames move the section at ``xi``
by the twist ``N(xi, d) [dq_A; dq_B]`` (the velocity-field map, spec S38,
:func:`simsoft_jax.physics.element.velocity_field_map`), so ``dx = R(xi) (N dq)_u``: the exact
derivative of the energy in those perturbations is
``sum_i c_i N_i^T [R_i^T (-psi'(delta) grad phi); 0]`` (residual side; the obstacle
pushes along ``+grad phi``). Tangents by ``jax.jacfwd`` (:mod:`.autodiff` and
:func:`simsoft_jax.physics.assembly.contact_and_tangent`).

Friction (dynamics), two laws (``[contact] friction_law``, static
``Structure.friction_law``). ``"regularized"``: the contact point moves with the centreline velocity
``v = R(xi) (N(xi, d) v_e)_u`` (world), relative to the obstacle (translating with
``v_o``) with ``v_r = v - v_o``; its part tangent to the obstacle
``v_t = v_r - (v_r . n) n`` (``n = grad phi``) meets the regularized Coulomb line load
``f_t = -mu f_n v_t / sqrt(|v_t|^2 + v_s^2)`` (``f_n = psi'(delta)``, ``mu`` the
obstacle's coefficient, ``v_s`` the slip-velocity scale, ``[contact] slip_velocity``):
viscous-like below ``v_s``, Coulomb's ``mu f_n`` opposite to the slip above it. It is
not conservative; its tangent in the velocities is the C block of the iteration matrix.

``"stick_slip"`` (elastic-plastic, "spring-slider" friction): each station has, per
obstacle, an anchor ``a`` (m, world) where its tangential spring is unstretched; the
anchors are part of the dynamic state (:mod:`simsoft_jax.physics.stick_slip`) and fixed
within a step. The trial line load (N/m, world) is

    f_trial = -k_t ((x - a) - ((x - a) . n) n)                                  (S1)

with ``k_t`` the tangential stiffness, the element's normal penalty ``k`` (a sticking
station carrying ``f_t`` is displaced by ``f_t / k``: at most ``mu`` times its
penetration), and the friction line load is its return map onto the Coulomb disc
``|f| <= c = mu f_n``:

    f = f_trial                                 |f_trial| <= r0 c
      = f_trial c g(|f_trial| / c) / |f_trial|    otherwise                      (S2)
    g(r) = r0 + (1 - r0) tanh((r - r0) / (1 - r0))

``r0 = STICK_LIMIT``: exact sticking (linear, no creep) up to ``r0 mu f_n``, a C2
saturation to ``mu f_n`` above (value, slope and curvature continuous at ``r0``; no
kink for Newton). After a converged step each anchor moves to the plastic position

    a' = x + f / k_t                                                              (S3)

(:func:`stick_slip_load`): a sticking station keeps its anchor (it moves only along the
normal), a sliding one drags it at the distance ``|f| / k_t``, a station out of contact
(``c = 0``) takes it along, so contact begins with an unstretched spring. Between
``r0 mu f_n`` and ``mu f_n`` a held station creeps by ``c (r - g(r)) / k_t`` per step.
The law has no velocity: its C block is zero, its K block comes by ``jax.jacfwd``.

Normal damping (dynamics, ``[contact] damping_ratio`` ``zeta``). A dissipative normal line
load opposes the station's normal speed ``v_n = v_r . n`` (positive separating):

    f_d = -c a(delta) v_n n,   c = 2 zeta sqrt(k rhoA),   a(delta) = S(delta / eps)     (D1)

with ``rhoA`` the element's line density (kg/m) and ``S(u) = 3u^2 - 2u^3`` on [0, 1] (0
below, 1 above): ``a`` and its slope vanish at contact onset, so the load is C1 in the
penetration, and past the smoothing width the penalty and (D1) are a linear spring and
dashpot per unit length of damping ratio ``zeta`` (natural frequency ``sqrt(k/rhoA)``): a
resolved impact leaves with the restitution ``exp(-zeta pi / sqrt(1 - zeta^2))`` of that
oscillator (none for ``zeta >= 1``). Like a Kelvin-Voigt contact it may pull briefly while
the station leaves (the restitution above counts on it). It reads the velocities: its
tangent in them is in the C block of the iteration matrix (by ``jax.jacfwd``, with the
friction's). The friction's bound ``mu f_n`` and the reported contact forces use the
penalty's ``f_n = psi'`` only.
"""
from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from .. import element, obstacles
from ...math import lie

SMOOTHING = 0.01   # eps / r: width of the cubic start of the penalty, fraction of the radius
STICK_LIMIT = 0.95  # r0 of (S2): exact sticking below r0 mu f_n, saturation to mu f_n above


class ContactData(NamedTuple):
    """An element's contact arrays: radius () m, stiffness () N/m^2 (penalty ``k``),
    obstacles (K,11) parameter rows (:mod:`simsoft_jax.physics.obstacles`), friction (K,) Coulomb
    coefficients, slip_velocity () m/s, velocity (K,3) m/s of the (translating)
    obstacles, caps (2,) m the end-cap lengths of its nodes A and B (the radius at a
    rod's end, else 0; None: no caps), anchor (S,K,3) m the stick-slip anchors (world) of
    its stations (None: the regularized law, or no friction), damping () N s/m^2 the
    normal damping coefficient ``c`` of (D1) (None: no damping)."""
    radius: jax.Array
    stiffness: jax.Array
    obstacles: jax.Array
    friction: jax.Array
    slip_velocity: jax.Array
    velocity: jax.Array
    caps: jax.Array = None
    anchor: jax.Array = None
    damping: jax.Array = None


def quadrature(n: int):
    """Gauss-Legendre points (n,) and weights (n,) on [0, 1] (weights sum to 1)."""
    x, w = np.polynomial.legendre.leggauss(n)
    return 0.5 * (x + 1.0), 0.5 * w


def station_points(n: int):
    """``xi`` (n+2,) of an element's contact stations: its ``n`` Gauss points, then its
    nodes A (0) and B (1)."""
    return np.concatenate([quadrature(n)[0], [0.0, 1.0]])


def station_weights(length, caps, n: int):
    """Weights (n+2,) m of the stations: ``L w_i`` at the Gauss points, the cap lengths
    ``caps`` (2,) at the nodes (zeros when None)."""
    w = jnp.asarray(quadrature(n)[1]) * length
    return jnp.concatenate([w, jnp.zeros(2, w.dtype) if caps is None else caps])


def penalty_slope(delta, k, eps):
    """``psi'(delta)`` (N/m): the normal line load at penetration ``delta`` (m)."""
    inside = jnp.clip(delta, 0.0, eps)
    return jnp.where(delta < eps, k * inside**2 / (2.0 * eps), k * (delta - 0.5 * eps))


def damping_activation(delta, eps):
    """``a(delta)`` of (D1): ``S(delta/eps)``, ``S(u) = 3u^2 - 2u^3`` clipped to [0, 1]
    (0 out of contact, 1 past the smoothing width ``eps``; value and slope continuous)."""
    u = jnp.clip(delta / eps, 0.0, 1.0)
    return u * u * (3.0 - 2.0 * u)


def penalty(delta, k, eps):
    """``psi(delta)`` (J/m), the penalty energy per unit length (module docstring)."""
    inside = jnp.clip(delta, 0.0, eps)
    return jnp.where(delta < eps, k * inside**3 / (6.0 * eps),
                     0.5 * k * (delta - 0.5 * eps) ** 2 + k * eps**2 / 24.0)


def centreline_point(RA, pA, d, xi):
    """Rotation (3,3) and position (3,) of the section at ``xi``: ``H_A exp(xi d)``."""
    return lie.compose_exp(RA, pA, xi * d)


def _gap_and_normal(kind, params, radius, x):
    phi, normal = jax.value_and_grad(lambda y: obstacles.signed_distance(kind, params, y))(x)
    return phi - radius, normal


def _point_contact(y, data: ContactData, kinds: tuple):
    """Per obstacle at the centreline point ``y`` (3,): the penetration (K,) m, the normal
    line load ``psi'`` (K,) N/m and the unit normal (K,3) (world)."""
    eps = SMOOTHING * data.radius
    pen, load, normals = [], [], []
    for k, kind in enumerate(kinds):
        g, nrm = _gap_and_normal(kind, data.obstacles[k], data.radius, y)
        pen.append(-g)
        load.append(penalty_slope(-g, data.stiffness, eps))
        normals.append(nrm)
    return jnp.stack(pen), jnp.stack(load), jnp.stack(normals)


def stations(RA, pA, d, data: ContactData, kinds: tuple, n: int):
    """Per station (:func:`station_points`, S = n+2) and obstacle: the penetration (S,K) m,
    the normal line load ``psi'`` (S,K) N/m and the unit normals (S,K,3) (world), and the
    section frames (S,3,3), (S,3) at the stations."""
    xi = station_points(n)
    R, x = jax.vmap(lambda t: centreline_point(RA, pA, d, t))(jnp.asarray(xi))
    pen, load, normals = jax.vmap(lambda y: _point_contact(y, data, kinds))(x)
    return pen, load, normals, R, x


def dynamic_friction(law: str, friction, anchor) -> bool:
    """Whether the dynamic contact force has friction (static, trace time): Coulomb
    coefficients ``friction`` (K,) given (not None) and, with the stick-slip ``law``
    (``Structure.friction_law``), the anchors ``anchor`` of a step (without them, e.g.
    for a start state's accelerations, the springs are unstretched: no friction)."""
    return friction is not None and (law != "stick_slip" or anchor is not None)


def _saturation(r):
    """``g(r)`` of (S2) for ``r >= STICK_LIMIT`` (increasing from ``r0`` to 1)."""
    soft = 1.0 - STICK_LIMIT
    return STICK_LIMIT + soft * jnp.tanh((r - STICK_LIMIT) / soft)


def stick_slip_trial(x, anchor, normals, stiffness):
    """The trial line loads (S,K,3) N/m (world) of (S1) at the stations ``x`` (S,3) against
    their anchors ``anchor`` (S,K,3), with the unit normals ``normals`` (S,K,3) and the
    tangential stiffness ``stiffness`` () N/m^2."""
    gap = x[:, None, :] - anchor
    along = jnp.einsum("ski,ski->sk", gap, normals)
    return -stiffness * (gap - along[..., None] * normals)


def stick_slip_load(x, anchor, load, normals, stiffness, mu):
    """The stick-slip friction (S1)-(S3) at S stations against K obstacles: ``x`` (S,3)
    the stations (m, world), ``anchor`` (S,K,3) their anchors, ``load`` (S,K) the normal
    line loads ``f_n`` (N/m), ``normals`` (S,K,3) the unit normals, ``stiffness`` () the
    tangential stiffness ``k_t`` (N/m^2), ``mu`` (K,) the Coulomb coefficients. Returns
    the friction line loads (S,K,3) N/m (world) and the plastic anchors (S,K,3) of (S3).
    Finite value and derivatives at zero slip (``|f_trial| = 0``) and out of contact
    (``c = 0``): the sticking branch is linear and the other one is evaluated only on
    safe arguments."""
    trial = stick_slip_trial(x, anchor, normals, stiffness)                    # (S1)
    cap = mu * load
    size = jax.vmap(jax.vmap(obstacles.safe_norm))(trial)
    stick = size <= STICK_LIMIT * cap
    slide = ~stick & (cap > 0.0)
    safe_cap, safe_size = jnp.where(slide, cap, 1.0), jnp.where(slide, size, 1.0)
    scale = jnp.where(stick, 1.0, jnp.where(
        slide, safe_cap * _saturation(safe_size / safe_cap) / safe_size, 0.0))     # (S2)
    f = scale[..., None] * trial
    return f, x[:, None, :] + f / stiffness                                     # (S3)


def _reads_velocity(data: ContactData, friction: bool) -> bool:
    """Whether the line load reads the stations' velocities (static): the regularized
    friction or the normal damping."""
    return (friction and data.anchor is None) or data.damping is not None


def station_load(y, u, anchor, data: ContactData, kinds: tuple, friction: bool):
    """The world line load (3,) N/m of the obstacles on a station at the point ``y`` (3,)
    moving with the world velocity ``u`` (3,) m/s: the penalty ``sum_k psi' n_k``, the
    normal damping (D1) when ``data.damping`` is given and, when ``friction``, the friction
    (stick-slip (S1)-(S2) against the station's anchors ``anchor`` (K,3) when
    ``data.anchor`` is given, else the regularized law). ``u`` and ``anchor`` are read only
    by the laws that need them."""
    pen, load, normals = _point_contact(y, data, kinds)
    f = load @ normals
    if _reads_velocity(data, friction):
        rel = u[None, :] - data.velocity                          # relative (K,3)
        vn = jnp.sum(normals * rel, -1)                           # (K,)
    if data.damping is not None:                                  # (D1)
        f = f - (data.damping * damping_activation(pen, SMOOTHING * data.radius) * vn) @ normals
    if friction and data.anchor is not None:
        f = f + stick_slip_load(y[None], anchor[None], load[None], normals[None],
                                data.stiffness, data.friction)[0][0].sum(0)
    elif friction:
        vt = rel - vn[:, None] * normals                          # (K,3)
        slip = jnp.sqrt(jnp.sum(vt**2, -1) + data.slip_velocity**2)
        f = f - (data.friction * load / slip) @ vt
    return f


def _station_velocities(R, maps, ve):
    """World centreline velocities (S,3) of the stations: ``R_i (N_i v_e)_u``."""
    return jnp.einsum("sij,sj->si", R, (maps @ ve)[:, :3])


def _anchors(data: ContactData, n: int):
    """The stations' anchors (S,K,3), zeros when the law has none (not read then)."""
    return (jnp.zeros((n + 2,) + data.velocity.shape, data.velocity.dtype)
            if data.anchor is None else data.anchor)


def force(el, data: ContactData, length, kinds: tuple, n: int, friction: bool = False):
    """Nodal forces (12,) of the contact, its normal damping (D1) when ``data.damping`` is
    given (zero at rest: in statics ``el.ve`` is zero) and, when ``friction``, the
    friction (the stick-slip law against ``data.anchor`` when it is given, else the
    regularized law) of one element (:class:`~simsoft_jax.physics.terms.Element` ``el``
    with ``el.pA``) with the obstacles ``kinds`` (static), residual side (module
    docstring, :func:`station_load`); ``length`` the element's reference length (m),
    ``n`` the quadrature points."""
    xi = jnp.asarray(station_points(n))
    R, x = jax.vmap(lambda t: centreline_point(el.RA, el.pA, el.d, t))(xi)
    maps = jax.vmap(lambda t: element.velocity_field_map(t, el.d, el.P))(xi)
    u = _station_velocities(R, maps, el.ve)
    f = jax.vmap(lambda y, w, a: station_load(y, w, a, data, kinds, friction))(
        x, u, _anchors(data, n))                                   # world line load (S,3)
    local = jnp.einsum("nji,nj->ni", R, f)                         # R^T f
    wrench = jnp.concatenate([local, jnp.zeros_like(local)], axis=1)
    return -jnp.einsum("n,nji,nj->i", station_weights(length, data.caps, n), maps, wrench)


def _coadjoint_bar(m):
    """``B(m)`` (6,6) with ``ad_eta^T m = B(m) eta`` for twists ``eta = [u; w]`` and
    ``m = [m1; m2]`` (6,) (``ad`` of spec S3): ``[[0, skew(m1)], [skew(m1), skew(m2)]]``."""
    a, b = lie.skew(m[:3]), lie.skew(m[3:])
    return jnp.block([[jnp.zeros((3, 3), m.dtype), a], [a, b]])


def force_and_tangent(el, data: ContactData, length, kinds: tuple, n: int,
                      friction: bool = False):
    """The contact forces (12,) of one element, as :func:`force`, their left-invariant
    tangent K (12,12) in the right perturbations ``y`` of the two nodal frames (at fixed
    nodal body velocities) and, when the load reads the velocities (regularized
    friction, normal damping), their derivative C (12,12) in the nodal velocities
    ``v_e`` (else None).

    With the world line load ``F(x, u)`` of a station at the point x moving with the world
    velocity u (:func:`station_load`) and its section-frame value ``l_i = R_i^T F_i``,
    the force is ``f = -sum_i c_i N_i^T [l_i; 0]`` (``N_i`` the velocity-field map at the
    station, spec S38). A perturbation y moves station i by the section twist ``N_i y``
    (``dx = R_i du``, ``dR = R_i skew(dtheta)``) and ``N_i`` through the element's twist
    d, which moves by ``P y`` (S37); the station's velocity ``u_i = R_i a_i``,
    ``a_i = (N_i v_e)_u``, moves by ``R_i (-skew(a_i) dtheta + J_i P y)`` with
    ``J_i = d a_i / d d`` at fixed ``v_e``, and by ``R_i (N_i dv_e)_u`` with the
    velocities. With ``H_i = dF/dx``, ``D_i = dF/du`` (3,3; ``jax.jacfwd`` in the 6
    coordinates of a station):

        dl_i = [R^T H R, skew(l_i)] N_i y + R^T D R (-skew(a_i) (N_i y)_theta + J_i P y
               + (N_i dv_e)_u)

    so ``K = -sum_i c_i N_i[:3]^T dl_i/dy - (d/dd sum_i c_i N_i(d)[:3]^T l_i) P`` and
    ``C = -sum_i c_i N_i[:3]^T R_i^T D_i R_i N_i[:3]``. The slopes in d (at fixed ``l_i``,
    ``v_e``) split by S38, ``N = [A, 0] + xi T(xi d) P(d)`` with ``A = Ad_{exp(-xi d)}``:
    the rigid part in closed form, ``dA = A ad(E dd)`` with ``E = -xi T(-xi d)`` (S20:
    ``exp(z + dz) = exp(z) exp(T(z) dz)`` to first order), so
    ``d(A[:3]^T l) = B(A[:3]^T l) E dd`` (:func:`_coadjoint_bar`) and
    ``d(A v_A)_u = -A[:3] ad(v_A) E dd``; the rest, through ``T(xi d)`` and ``P(d)``, by
    ``jax.jacfwd`` in the 6 components of d. The same as ``jax.jacfwd`` of
    :func:`force` in the 12 perturbations and the 12 velocities (checked in the tests),
    at a fraction of its cost.
    """
    xi = jnp.asarray(station_points(n))
    R, x = jax.vmap(lambda t: centreline_point(el.RA, el.pA, el.d, t))(xi)
    maps = jax.vmap(lambda t: element.velocity_field_map(t, el.d, el.P))(xi)
    u = _station_velocities(R, maps, el.ve)
    rate = _reads_velocity(data, friction)

    def load(z, anchor):   # world line load (3,) at z = [x; u]
        return station_load(z[:3], z[3:], anchor, data, kinds, friction)

    def with_slopes(y, w, anchor):
        if rate:
            z = jnp.concatenate([y, w])
            return load(z, anchor), jax.jacfwd(load)(z, anchor)
        return load(jnp.concatenate([y, w]), anchor), jnp.concatenate(
            [jax.jacfwd(lambda q: load(jnp.concatenate([q, w]), anchor))(y),
             jnp.zeros((3, 3), y.dtype)], axis=1)

    F, slopes = jax.vmap(with_slopes)(x, u, _anchors(data, n))     # (S,3), (S,3,6)
    H, D = slopes[..., :3], slopes[..., 3:]
    local = jnp.einsum("sji,sj->si", R, F)                                  # R^T F (S,3)
    weights = station_weights(length, data.caps, n)
    # slopes in d: the rigid part A = Ad_{exp(-xi d)}[:3] of N in closed form (docstring),
    # the part xi T(xi d)[:3] P(d) by jax.jacfwd
    A = jax.vmap(lambda t: lie.adjoint_se3(lie.exp_se3(-t * el.d))[:3])(xi)         # (S,3,6)
    E = -xi[:, None, None] * jax.vmap(lambda t: lie.tangent_se3(-t * el.d))(xi)     # (S,6,6)
    rigid = jnp.einsum("sai,sa->si", A, local)                              # A^T l (S,6)

    def through(d):
        P = element.strain_map(d)
        T = xi[:, None, None] * jax.vmap(lambda t: lie.tangent_se3(t * d)[:3])(xi)  # (S,3,6)
        pulled = P.T @ jnp.einsum("s,sai,sa->i", weights, T, local)
        return (pulled, (T @ (P @ el.ve)) if rate else None), pulled

    (geometric, J), value = jax.jacfwd(through, has_aux=True)(el.d)   # (12,6), (S,3,6)
    # value: sum_i c_i N_i^T [l_i; 0]
    value = value.at[:6].add(weights @ rigid)
    geometric = geometric.at[:6].add(jnp.einsum(
        "s,sij,sjk->ik", weights, jax.vmap(_coadjoint_bar)(rigid), E))
    moved = jnp.concatenate([jnp.einsum("sji,sjk,skl->sil", R, H, R),
                             jax.vmap(lie.skew)(local)], axis=2)            # (S,3,6)
    direct = jnp.einsum("s,sai,sab,sbj->ij", weights, maps[:, :3, :], moved, maps)
    K = direct + geometric @ el.P
    if not rate:
        return -value, -K, None
    damp = jnp.einsum("sji,sjk,skl->sil", R, D, R)                         # R^T D R
    a = (maps @ el.ve)[:, :3]
    # J_i = d a_i / d d at fixed v_e (P = strain_map(d) moves with d too)
    J = J - jnp.einsum("saj,jk,skl->sal", A, lie.ad_se3(el.ve[:6]), E)
    spin = (-jnp.einsum("sab,sbj->saj", jax.vmap(lie.skew)(a), maps[:, 3:, :])
            + J @ el.P)                                                     # (S,3,12)
    K = K + jnp.einsum("s,sai,sab,sbj->ij", weights, maps[:, :3, :], damp, spin)
    C = jnp.einsum("s,sai,sab,sbj->ij", weights, maps[:, :3, :], damp, maps[:, :3, :])
    return -value, -K, -C


def energy(RA, pA, RB, pB, data: ContactData, length, kinds: tuple, n: int):
    """Penalty energy (J) of one element given its two nodal frames (module docstring)."""
    d = element.relative_twist(RA, pA, RB, pB)
    pen, _, _, _, _ = stations(RA, pA, d, data, kinds, n)
    eps = SMOOTHING * data.radius
    weights = station_weights(length, data.caps, n)
    return jnp.sum(weights[:, None] * penalty(pen, data.stiffness, eps))


def summary(RA, pA, d, data: ContactData, length, kinds: tuple, n: int):
    """Per obstacle (K,): the force of the obstacle on the element (K,3) N (world), its
    normal part ``sum c psi'`` (K,) N, and the largest penetration (K,) m at any of its
    stations, nodes included (0 if none)."""
    pen, load, normals, _, _ = stations(RA, pA, d, data, kinds, n)
    weights = station_weights(length, data.caps, n)[:, None]
    return (jnp.einsum("nk,nki->ki", weights * load, normals),
            jnp.sum(weights * load, 0), jnp.maximum(pen.max(0), 0.0))
