"""The contact tangents (:func:`simsoft_jax.physics.terms.contact.force_and_tangent`)
against their reference: ``jax.jacfwd`` of the contact force
(:func:`simsoft_jax.physics.terms.contact.force`) in the 12 right perturbations of the two nodal
frames, for every obstacle kind, a bent and twisted element pressed into each obstacle at
several stations, with and without end caps."""
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from simsoft_jax.math import lie
from simsoft_jax.scene.scene_contact import ROW
from simsoft_jax.physics.terms import contact, element_state

RADIUS, STIFFNESS, POINTS = 0.01, 2e6, 3


def _row(values):
    row = np.zeros(ROW)
    row[:len(values)] = values
    return row


# each obstacle placed so that the element below (from the origin along about +x, 0.1 m,
# bent and twisted) sinks into it by a few millimetres somewhere along its length
OBSTACLES = {
    "plane": _row([0, 0, -0.004, 0.1, 0.2, 1.0]),
    "sphere": _row([0.06, 0.0, -0.045, 0, 0, 0, 0.05]),
    "capsule": _row([0.0, 0.0, -0.028, 0.094, -0.021, -0.052, 0.02]),
    "cylinder": _row([0.0, 0.0, -0.032, 0.1, 1.0, 0.05, 0.03]),
    "tube": _row([0.0, 0.005, 0.002, 1.0, 0.05, 0.02, 0.012]),
    "curved_tube": _row([0.0, 0.2, 0.0, 0.0, 0.0, 1.0, 0, 0.0, 0.0, 0.003, 0.8]),
}


def _element():
    rng = np.random.default_rng(7)
    RA = lie.exp_so3(jnp.asarray(0.1 * rng.standard_normal(3)))
    pA = jnp.asarray([0.0, 0.0, 0.0])
    d = jnp.asarray([0.1, 0.003, -0.002, 0.4, 0.3, -0.5])   # stretch, shear, twist, bending
    RB, pB = lie.compose_exp(RA, pA, d)
    return RA, pA, RB, pB


@pytest.mark.parametrize("kind", sorted(OBSTACLES))
def test_frictionless_tangent_equals_jacfwd_of_the_force(kind):
    RA, pA, RB, pB = _element()
    length, zero = jnp.asarray(0.1), jnp.zeros(12)

    def data(caps):
        return contact.ContactData(jnp.asarray(RADIUS), jnp.asarray(STIFFNESS),
                                   jnp.asarray(OBSTACLES[kind])[None], jnp.zeros(1),
                                   jnp.asarray(0.01), jnp.zeros((1, 3)), caps)

    def force(y, caps):
        RA1, pA1 = lie.compose_exp(RA, pA, y[:6])
        RB1, pB1 = lie.compose_exp(RB, pB, y[6:])
        return contact.force(element_state(RA1, pA1, RB1, pB1, zero, zero), data(caps),
                             length, (kind,), POINTS)

    both = jax.jit(lambda caps: (
        contact.force_and_tangent(element_state(RA, pA, RB, pB, zero, zero), data(caps),
                                  length, (kind,), POINTS),
        force(zero, caps), jax.jacfwd(force)(zero, caps)))
    pressed = contact.stations(RA, pA, element_state(RA, pA, RB, pB, zero, zero).d,
                               data(None), (kind,), POINTS)[0]
    assert int(jnp.sum(pressed > 0.0)) >= 2          # the element is in contact
    for caps in (jnp.zeros(2), jnp.array([RADIUS, RADIUS])):    # without and with end caps
        (value, tangent, rate), expected, reference = both(caps)
        assert rate is None                              # no velocity read
        np.testing.assert_allclose(value, expected, rtol=0,
                                   atol=1e-12 * float(jnp.abs(expected).max()))
        assert float(jnp.abs(reference).max()) > 0.0
        np.testing.assert_allclose(tangent, reference, rtol=0,
                                   atol=1e-9 * float(jnp.abs(reference).max()))


@pytest.mark.parametrize("law", ["regularized", "stick_slip"])
def test_tangents_with_friction_and_damping_equal_jacfwd_of_the_force(law):
    """With friction (either law) and the normal damping (D1), a moving element: the K
    block (frames, at fixed body velocities) and the C block (velocities) of
    ``force_and_tangent`` against ``jax.jacfwd`` of the force in the 12 perturbations
    and the 12 velocities, for two obstacle kinds at once (a plane and a sphere), with
    end caps."""
    RA, pA, RB, pB = _element()
    length = jnp.asarray(0.1)
    rng = np.random.default_rng(11)
    ve = jnp.asarray(0.3 * rng.standard_normal(12))
    kinds = ("plane", "sphere")
    rows = jnp.asarray(np.stack([OBSTACLES[k] for k in kinds]))
    anchor = None
    if law == "stick_slip":   # anchors a little off the stations: some stick, some slide
        x = jax.vmap(lambda t: contact.centreline_point(
            RA, pA, element_state(RA, pA, RB, pB, ve, ve).d, t)[1])(
            jnp.asarray(contact.station_points(POINTS)))
        anchor = x[:, None, :] + jnp.asarray(1e-4 * rng.standard_normal((POINTS + 2, 2, 3)))
    data = contact.ContactData(jnp.asarray(RADIUS), jnp.asarray(STIFFNESS), rows,
                               jnp.asarray([0.3, 0.5]), jnp.asarray(0.01),
                               jnp.asarray([[0.01, 0.0, 0.0], [0.0, -0.02, 0.0]]),
                               jnp.array([RADIUS, RADIUS]), anchor, jnp.asarray(40.0))

    def force(y):
        RA1, pA1 = lie.compose_exp(RA, pA, y[:6])
        RB1, pB1 = lie.compose_exp(RB, pB, y[6:12])
        u = ve + y[12:]
        return contact.force(element_state(RA1, pA1, RB1, pB1, u, u), data, length, kinds,
                             POINTS, True)

    both = jax.jit(lambda: (contact.force_and_tangent(
        element_state(RA, pA, RB, pB, ve, ve), data, length, kinds, POINTS, True),
        force(jnp.zeros(24)), jax.jacfwd(force)(jnp.zeros(24))))
    (value, K, C), expected, reference = both()
    np.testing.assert_allclose(value, expected, rtol=0,
                               atol=1e-12 * float(jnp.abs(expected).max()))
    for block, expected_block in ((K, reference[:, :12]), (C, reference[:, 12:])):
        scale = float(jnp.abs(expected_block).max())
        assert scale > 0.0
        np.testing.assert_allclose(block, expected_block, rtol=0, atol=1e-9 * scale)
