"""Point loads placed by arc length ``s`` between two nodes act on their element through
the helical interpolation (spec S38, issue 17), against independent references: the
linear Timoshenko cantilever under a point load at ``a`` (``F a^2 (3L - a) / 6EI +
F a / GA``), the same load placed by node index, the potential ``F . p(xi)`` of a dead
force (differentiated here by ``jax.jacfwd``), and the autodiff tangent path.
"""
from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import simsoft_jax as sj
from conftest import iteration_matrices
from simsoft_jax.physics import assembly
from simsoft_jax.math import lie
from simsoft_jax.physics.terms import element_state, point_in_element

L, EI, GA = 1.0, 1.0, 1e4
F = 1e-4          # small: the response is linear to ~1e-10 relative


def scene(elements, load):
    stiff = {"EA": 1e4, "GAy": GA, "GAz": GA, "GJ": 0.7, "EIy": EI, "EIz": 1.5}
    return sj.Scene.from_dict({
        "solver": {"kind": "static", "load_steps": 1},
        "rods": [{"name": "arm", "stiffness": stiff,
                  "inertia": {"rhoA": 1.0, "rhoJ": 1.0, "rhoIy": 1.0, "rhoIz": 1.0},
                  "elements": elements, "geometry": {"kind": "straight", "length": L}}],
        "constraints": [{"kind": "clamp", "rod": "arm", "node": 0}],
        "loads": [{"kind": "force", "rod": "arm", "vector": [0.0, 0.0, F], **load}]})


def tip_deflection(elements, **load):
    eq = sj.solve_static(sj.build_model(scene(elements, load)))
    assert eq.converged
    return float(eq.p[-1, 2])


def closed_form(a):
    return F * a * a * (3 * L - a) / (6 * EI) + F * a / GA


def test_load_by_s_inside_an_element_is_not_rounded():
    model = sj.build_model(scene(4, {"s": 0.3}))
    assert model.element_point_dead is not None and model.nodal_dead is None
    assert np.allclose(model.element_point_dead[1], [0, 0, F, 0, 0, 0])
    assert abs(float(model.element_point_xi[1]) - 0.2) < 1e-12


def test_tip_deflection_converges_to_the_closed_form():
    # a kink inside an element is not representable (constant strain per element):
    # second-order convergence, measured 1 el. -44 %, 4: -3.5 %, 16: -0.25 %, 64: -1.5e-4
    exact = closed_form(0.3 * L)
    errors = [abs(tip_deflection(n, s=0.3 * L) - exact) / exact for n in (1, 4, 16, 64, 128)]
    assert errors[0] < 0.5 and errors[1] < 0.04
    assert all(e0 / e1 > 3.5 for e0, e1 in zip(errors, errors[1:]))
    assert errors[-1] < 5e-5


def test_load_inside_the_clamped_element_is_kept():
    # s = 0.05 L lies in the first element: it used to be rounded onto the clamped node 0
    exact = closed_form(0.05 * L)
    assert abs(tip_deflection(4, s=0.05 * L) - exact) / exact < 0.12
    assert abs(tip_deflection(128, s=0.05 * L) - exact) / exact < 3e-4


def test_s_on_a_node_equals_the_node_index():
    at = tip_deflection(4, s=0.5 * L)
    assert abs(at - tip_deflection(4, node=2)) <= 1e-12 * abs(at)


def test_moving_across_a_node_is_continuous():
    at = tip_deflection(4, s=0.5 * L)
    for ds in (-1e-7, 1e-7):
        assert abs(tip_deflection(4, s=0.5 * L + ds) - at) < 1e-6 * abs(at)   # 3.7e-7


def deformed_element():
    key = jax.random.split(jax.random.PRNGKey(3), 3)
    RA = lie.exp_so3(0.4 * jax.random.normal(key[0], (3,)))
    pA = jnp.array([0.1, -0.2, 0.3])
    d = jnp.array([0.3, 0.02, -0.03, 0.0, 0.0, 0.0]) + 0.2 * jax.random.normal(key[1], (6,))
    RB, pB = lie.compose_exp(RA, pA, d)
    return RA, pA, RB, pB


@jax.jit
def dead_force_and_potential_gradient(force, xi):
    """The point-load term of a dead ``force`` (3,) at ``xi`` on :func:`deformed_element`
    and the gradient (12,) of its potential ``F . p(xi)`` over the end nodes' chart
    increments by ``jax.jacfwd``, as one compiled program (eagerly, each of their
    operations compiles on its own: about two hundred small programs)."""
    RA, pA, RB, pB = deformed_element()
    data = point_in_element.ElementPointLoad(jnp.concatenate([force, jnp.zeros(3)]), None, xi)

    def potential(y):
        RA1, pA1 = lie.compose_exp(RA, pA, y[:6])
        RB1, pB1 = lie.compose_exp(RB, pB, y[6:])
        d = lie.log_se3(lie.relative_pose(RA1, pA1, RB1, pB1))
        p_xi = pA1 + RA1 @ lie.exp_se3(xi * d)[:3, 3]
        return force @ p_xi

    zero = jnp.zeros(12)
    term = point_in_element.force(element_state(RA, pA, RB, pB, zero, zero), data, 1.0)
    return term, jax.jacfwd(potential)(zero)


def test_dead_force_is_the_gradient_of_its_potential():
    term, gradient = dead_force_and_potential_gradient(jnp.array([0.3, -1.2, 0.7]),
                                                       jnp.asarray(0.37))
    assert jnp.max(jnp.abs(term + gradient)) < 1e-12 * jnp.max(jnp.abs(gradient))


@pytest.mark.parametrize("frame", ["world", "local"])
def test_closed_form_and_autodiff_tangents_agree(frame):
    model = sj.build_model(sj.Scene.from_dict({
        "solver": {"kind": "static"},
        "rods": [{"name": "arm", "stiffness": {"EA": 10.0, "GAy": 8.0, "GAz": 9.0, "GJ": 0.7,
                                               "EIy": 1.0, "EIz": 1.5},
                  "inertia": {"rhoA": 1.0, "rhoJ": 1.0, "rhoIy": 1.0, "rhoIz": 1.0},
                  "elements": 3, "geometry": {"kind": "straight", "length": L}}],
        "constraints": [{"kind": "clamp", "rod": "arm", "node": 0}],
        "loads": [{"kind": "force", "rod": "arm", "s": 0.5, "vector": [0.2, 0.5, 1.0],
                   "frame": frame},
                  {"kind": "moment", "rod": "arm", "s": 0.5, "vector": [0.3, -0.4, 0.2],
                   "frame": frame}]}))
    w = 0.3 * jax.random.normal(jax.random.PRNGKey(0), (4, 6))
    R, p = jax.vmap(lie.compose_exp)(model.R0, model.p0, w)
    r1, k1 = assembly.residual_and_tangent(model, R, p, 0.7, tangent="closed_form")
    r2, k2 = assembly.residual_and_tangent(model, R, p, 0.7, tangent="autodiff")
    assert jnp.max(jnp.abs(r1 - r2)) < 1e-13
    for b1, b2 in zip(k1, k2):
        assert jnp.max(jnp.abs(b1 - b2)) < 1e-12 * jnp.max(jnp.abs(k2[0]))


def scene_with(loads, kind="static"):
    solver = {"kind": "static"} if kind == "static" else {"kind": "dynamic", "t_end": 1.0,
                                                          "dt": 0.1}
    return {"solver": solver,
            "rods": [{"name": "arm", "material": "spring_steel",
                      "section": {"shape": "circle", "diameter": 0.01}, "elements": 2,
                      "geometry": {"kind": "straight", "length": L}}],
            "constraints": [{"kind": "clamp", "rod": "arm", "node": 0}], "loads": loads}


def test_two_places_in_one_element_are_rejected():
    loads = [{"kind": "force", "rod": "arm", "s": 0.1, "vector": [0, 0, 1.0]},
             {"kind": "force", "rod": "arm", "s": 0.2, "vector": [0, 0, 1.0]}]
    with pytest.raises(ValueError, match=r"^loads\[1\]\.s: s = 0.2 lies in element 0"):
        sj.Scene.from_dict(scene_with(loads))


def test_a_time_law_scales_a_load_inside_an_element():
    load = {"kind": "moment", "rod": "arm", "s": 0.7, "vector": [0, 2.0, 0], "frame": "local",
            "profile": {"kind": "linear", "rate": 0.5}}
    model = sj.build_model(sj.Scene.from_dict(scene_with([load], "dynamic")))
    assert model.element_point_follower is not None and model.nodal_follower is None
    assert float(model.element_point_xi[1]) == pytest.approx(0.4, abs=1e-12)
    at = sj.loads.loads_at(model, 0.6)          # scale 0.5 * 0.6
    np.testing.assert_allclose(np.asarray(at.element_point_follower[1]), [0, 0, 0, 0, 0.6, 0],
                               atol=1e-15)
    assert not np.any(np.asarray(at.element_point_follower[0]))


def test_dynamic_iteration_matrix_paths_agree():
    """``M beta' + C gamma' + K T(w)`` of both tangent paths, with dead and follower point
    loads inside an element (one on a ramp), by :func:`conftest.iteration_matrices` (one
    compiled program per path)."""
    from simsoft_jax.model import loads
    point = [{"kind": "force", "rod": "arm", "s": 0.3, "vector": [0.2, 5.0, -3.0]},
             {"kind": "moment", "rod": "arm", "s": 0.3, "vector": [0.3, -0.4, 0.2],
              "frame": "local", "profile": {"kind": "ramp", "t0": 0.0, "t1": 1.0}}]
    model = loads.loads_at(sj.build_model(sj.Scene.from_dict(scene_with(point, "dynamic"))),
                           0.5)
    rng = np.random.default_rng(5)
    R, p = jax.vmap(lie.compose_exp)(model.R0, model.p0,
                                     jnp.asarray(0.05 * rng.standard_normal((3, 6))))
    (r1, S1), (r2, S2) = iteration_matrices(model, R, p)
    np.testing.assert_allclose(r1, r2, rtol=0, atol=1e-13 * np.abs(r2).max())
    np.testing.assert_allclose(S1, S2, rtol=0, atol=1e-10 * np.abs(S1).max())
