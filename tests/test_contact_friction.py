"""Quasi-static friction (issue 14): the capstan equation for a flexible rod wrapped on a
fixed rough drum, pulled at one end and clamped at the other, solved with load stepping
and the regularized Coulomb law on the slip since the previous load level
(:mod:`simsoft_jax.physics.terms.static_friction`); and the friction of one element on a plane,
sliding and sticking, against the resultant force and moment of its line load.

The scene (one structure, compiled once): a drum of radius ``RC`` (axis y through the
origin), a rod of contact radius ``R`` lying on it over the wrap angle ``THETA = pi``
between two straight pieces: the held piece along +x on top of the drum (clamped at its
left end, node 0), the pulled piece along -x under the drum, pulled by ``T1`` along -x at
its end. The rod starts in that wrapped shape, its centreline ``DEPTH`` inside the
contact surface (the end of the penalty's cubic start, so the contact is stiff from the
first Newton step).

Independent reference: a string on a rough drum at the onset of sliding (friction
``mu`` times the normal line load ``T/Rw`` everywhere along the wrap, against the
slip) has ``dT/dphi = mu T``, so ``T(phi) = T0 exp(mu phi)`` and ``T1/T0 = exp(mu
theta)`` whatever the radius. Under monotonic pulling with the held end clamped, every
point of the wrap moves towards the pulled end at every load level (the rod stretches
everywhere), so the whole wrap slides and the capstan ratio holds at every level. The
rod differs from a string by its bending stiffness: where it leaves the drum its
curvature drops from ``1/Rw`` to 0 over the length ``sqrt(EI/T)``, which adds point
reactions ``~ sqrt(EI T)/Rw`` and hence friction ``~ mu sqrt(EI T)/Rw`` at the two ends
of the wrap: relative to T that is ``mu sqrt(EI/(T Rw^2))``, here 0.3 x 0.016 (EI =
1e-5 N m^2, T0 = 3.9 N, Rw = 0.105 m), well inside the 2 % of the issue. The slips of the
last level (>= 1e-6 m) are large against the slip scale u_s = 1e-7 m, so the
regularized law is Coulomb's to ``(u_s/slip)^2/2``.

Tensions are measured from the deformation: on the straight pieces ``T = EA (|p_{i+1} -
p_i| / h - 1)`` (no bending there: EI is tiny and the pieces are straight); on the wrap
the element's chord ``c`` is turned into its arc ``c (a/2) / sin(a/2)`` with ``a`` the
angle between its end tangents.
"""
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import simsoft_jax as sj

RC, R, T1, MU, THETA = 0.1, 0.005, 10.0, 0.3, np.pi
EA, EI = 1.0e3, 1.0e-5                 # N, N m^2
DEPTH = 0.01 * R                       # start penetration (the penalty's smoothing width)
RW = RC + R - DEPTH                    # radius of the centreline on the drum at the start
NF, NA, NP = 6, 26, 8                  # elements: held piece, wrap, pulled piece
N = NF + NA + NP
H = RW * THETA / NA                    # element length, m
SLIP = 1.0e-7                          # u_s, m


def _start():
    """Node positions (N+1,3) and rotations (N+1,3,3) of the wrapped start, in the base
    frame (origin at the clamp, node 0)."""
    points, rotations = [], []
    for s in H * np.arange(N + 1):
        phi = np.clip((s - NF * H) / RW, 0.0, THETA)
        along = max(s - NF * H - RW * phi, 0.0)     # beyond the wrap (> 0 only there)
        before = min(s - NF * H, 0.0)               # before it (< 0 only there)
        tangent = np.array([np.cos(phi), 0.0, -np.sin(phi)])
        x = RW * np.array([np.sin(phi), 0.0, np.cos(phi)]) + (along + before) * tangent
        points.append((x - [-NF * H, 0.0, RW]).tolist())
        c, si = np.cos(phi), np.sin(phi)
        rotations.append([[c, 0.0, si], [0.0, 1.0, 0.0], [-si, 0.0, c]])
    return points, rotations


def _scene():
    points, rotations = _start()
    return {
        "solver": {"kind": "static", "load_steps": 10},
        "rods": [{"name": "rod", "elements": N,
                  "geometry": {"kind": "straight", "length": N * H},
                  "base": {"position": [-NF * H, 0.0, RW]},
                  "initial": {"points": points, "rotations": rotations},
                  "stiffness": {"EA": EA, "GAy": EA, "GAz": EA, "GJ": EI, "EIy": EI,
                                "EIz": EI},
                  "inertia": {"rhoA": 1.0, "rhoJ": 1e-6, "rhoIy": 1e-6, "rhoIz": 1e-6}}],
        "constraints": [{"kind": "clamp", "rod": "rod", "node": 0}],
        "loads": [{"kind": "force", "rod": "rod", "node": -1,
                   "vector": [T1 * np.cos(THETA), 0.0, -T1 * np.sin(THETA)]}],
        "obstacles": [{"name": "drum", "kind": "cylinder", "axis_point": [0.0, 0.0, 0.0],
                       "axis": [0.0, 1.0, 0.0], "radius": RC, "friction": MU}],
        "contact": {"radius": R, "stiffness": 1.0e6, "slip_displacement": SLIP}}


@pytest.fixture(scope="module")
def capstan():
    model = sj.build_model(sj.Scene.from_dict(_scene()))
    return model, sj.StaticSettings(load_steps=10)


def _tensions(R, p):
    """Axial force (N) per element from its stretch (module docstring)."""
    chord = np.linalg.norm(np.diff(p, axis=0), axis=1)
    cos = np.einsum("ni,ni->n", R[:-1, :, 0], R[1:, :, 0])
    half = 0.5 * np.arccos(np.clip(cos, -1.0, 1.0))
    arc = chord * np.where(half > 1e-12, half / np.sin(np.maximum(half, 1e-12)), 1.0)
    return EA * (arc / H - 1.0)


@pytest.mark.slow     # compiling the contact-with-friction solver: ~50 s on a loaded 2-core machine
def test_capstan_tension_ratio_at_the_onset_of_sliding(capstan):
    """T1/T0 = exp(mu theta) to 2 % (held-piece tension from its stretch), the tension
    along the wrap T0 exp(mu phi) to 2 %, every node on the wrap slid along the rod
    towards the pulled end by more than 10 u_s in the last load level (friction fully
    mobilized), and without friction (the same structure, mu = 0) the tension is T1 on
    both sides: the ratio is the friction's."""
    model, settings = capstan
    eq = sj.solve_static(model, settings)
    assert bool(eq.converged), eq.message()
    assert int(eq.load_steps) >= 10     # friction: increments capped at 1/load_steps
    R, p = np.asarray(eq.R), np.asarray(eq.p)
    T = _tensions(R, p)
    T0 = T[1:NF - 1].mean()
    np.testing.assert_allclose(T[NF + NA + 1:], T1, rtol=1e-3)      # the measure itself
    assert T1 / T0 == pytest.approx(np.exp(MU * THETA), rel=0.02)
    mid = 0.5 * (p[1:] + p[:-1])
    phi = np.arctan2(mid[:, 0], mid[:, 2]) % (2 * np.pi)
    wrap = slice(NF + 3, NF + NA - 3)
    np.testing.assert_allclose(T[wrap], T0 * np.exp(MU * phi[wrap]), rtol=0.02)
    slid = np.einsum("ni,ni->n", p - np.asarray(eq.previous[1]), R[:, :, 0])  # along
    assert slid[NF + 1:NF + NA].min() > 10.0 * SLIP
    frictionless = sj.solve_static(model.replace(obstacle_friction=jnp.zeros(1)), settings)
    assert bool(frictionless.converged), frictionless.message()
    T = _tensions(np.asarray(frictionless.R), np.asarray(frictionless.p))
    np.testing.assert_allclose(T[1:NF - 1], T1, rtol=2e-3)


@pytest.mark.parametrize("slip,share", [([100.0, 0.0, 0.0], 100.0 / np.sqrt(1.0 + 1e4)),
                                        ([0.0, 0.01, 0.0], 0.01 / np.sqrt(1.0 + 1e-4)),
                                        ([0.0, 30.0, 5.0], 30.0 / np.sqrt(1.0 + 900.0))])
def test_friction_of_an_element_sliding_and_sticking_on_a_plane(slip, share):
    """A straight element of length L lying on a plane (z = 0), sunk by 2 eps (normal line
    load f_n = k (2 eps - eps/2)), its stations moved by the slip u (in units of u_s)
    since the previous level: the friction is a uniform line load
    -mu f_n u_t / sqrt(|u_t|^2 + u_s^2), so the nodal forces (residual side) sum to
    mu f_n L u_t / sqrt(..) and their moment about node A is L/2 x that force. Sliding
    (|u_t| = 100 u_s: Coulomb's mu f_n L to 5e-5), sticking (|u_t| = 0.01 u_s: a spring,
    1 % of it), and a slip with a normal part (only the tangential part counts)."""
    from simsoft_jax.scene import scene_contact as contact_tables
    from simsoft_jax.physics.terms import contact, element_state, static_friction
    L, r, k, mu, us = 0.2, 0.01, 1.0e5, 0.4, 1.0e-6
    eps = contact.SMOOTHING * r
    plane = jnp.zeros((1, contact_tables.ROW)).at[0, 5].set(1.0)   # point 0, normal +z
    data = contact.ContactData(jnp.asarray(r), jnp.asarray(k), plane, jnp.asarray([mu]),
                               jnp.asarray(1e-3), jnp.zeros((1, 3)))
    RA, pA = jnp.eye(3), jnp.array([0.0, 0.0, r - 2.0 * eps])
    pB = pA + jnp.array([L, 0.0, 0.0])
    u = us * jnp.asarray(slip)

    @jax.jit
    def forces(u):
        el = element_state(RA, pA, RA, pB, jnp.zeros(12), jnp.zeros(12))
        before = static_friction.stations(RA, pA, el.d, 4) - u
        return static_friction.force(el, before, us, data, L, ("plane",), 4)

    f = forces(u)
    fn = k * 1.5 * eps
    tangential = np.array([slip[0], slip[1], 0.0]) / np.linalg.norm(slip[:2])
    expected = mu * fn * L * share * tangential
    np.testing.assert_allclose(f[:3] + f[6:9], expected, rtol=1e-9, atol=1e-12 * mu * fn * L)
    moment = f[3:6] + f[9:12] + np.cross([L, 0.0, 0.0], f[6:9])
    np.testing.assert_allclose(moment, np.cross([L / 2, 0.0, 0.0], expected), rtol=1e-9,
                               atol=1e-12 * mu * fn * L * L)
