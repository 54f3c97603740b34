"""Optional parts of a Model (simsoft_jax.model.parts): None when the scene lacks the term.

* a part the scene lacks is None, and ``Model.replace`` refuses to give it a value with
  a ValueError naming the field;
* a present part is an ordinary traced leaf: the derivative of the tip deflection of a
  cantilever under its own weight in the gravity vector matches the small-deflection
  closed form ``d/dg (rhoA g L^4 / (8 EI)) = rhoA L^4 / (8 EI)`` (Euler-Bernoulli; shear
  stiffness 1e9 N makes the Timoshenko term ``rhoA L^2 / (2 GA)`` 1e-6 of it; the sag is
  3e-4 L, so the geometric nonlinearity is ~1e-7). The discretization error falls as
  h^2 (measured -3.3e-3, -8.3e-4, -2.1e-4 with 10, 20, 40 elements): 40 elements, 5e-4.
"""
import re

import numpy as np
import pytest

import simsoft_jax as sj  # enables float64
import jax
import jax.numpy as jnp
from simsoft_jax.model.parts import WHAT

L, EI, RHOA, G = 0.5, 50.0, 0.1, 9.81


def cantilever(gravity):
    """A clamped straight rod along x, 40 elements, with or without ``[gravity]``."""
    d = {"solver": {"kind": "static"},
         "rods": [{"name": "rod", "elements": 40, "geometry": {"kind": "straight", "length": L},
                   "stiffness": dict(EA=1e9, GAy=1e9, GAz=1e9, GJ=EI, EIy=EI, EIz=EI),
                   "inertia": dict(rhoA=RHOA, rhoJ=1e-6, rhoIy=1e-6, rhoIz=1e-6)}],
         "constraints": [{"kind": "clamp", "rod": "rod", "node": 0}]}
    if gravity is not None:
        d["gravity"] = {"vector": list(gravity)}
    return sj.build_model(sj.Scene.from_dict(d))


def test_absent_parts_are_none_and_refused_naming_the_field():
    model = cantilever(None)
    absent = [key for key in WHAT if getattr(model, key) is None]
    assert set(absent) == set(WHAT)          # no load, gravity, viscosity, contact, field
    for key in absent:
        with pytest.raises(ValueError, match=f"^{key}: this model was built without "
                                             f"{re.escape(WHAT[key])}"):
            model.replace(**{key: np.zeros(3)})
    with pytest.raises(ValueError, match="build it from a scene that has gravity$"):
        model.replace(gravity=jnp.array([0.0, 0.0, -G]))
    # the present part takes a value: the same model built with gravity
    heavy = cantilever([0.0, 0.0, -G])
    np.testing.assert_array_equal(np.asarray(heavy.replace(gravity=np.zeros(3)).gravity), 0.0)


def test_tip_deflection_gradient_in_gravity_matches_the_closed_form():
    model = cantilever([0.0, 0.0, -G])
    settings = sj.StaticSettings(tolerance=1e-12)

    def tip_z(g):
        return sj.solve_static(model.replace(gravity=g), settings).p[-1, 2]

    g = jnp.array([0.0, 0.0, -G])
    sag, grad = jax.value_and_grad(tip_z)(g)
    per_g = RHOA * L ** 4 / (8 * EI)                 # m per (m/s^2)
    assert float(sag) == pytest.approx(-G * per_g, rel=5e-4)
    assert float(grad[2]) == pytest.approx(per_g, rel=5e-4)
    assert abs(float(grad[1])) < 1e-6 * per_g        # a sideways g does not lift the tip


def test_which_parts_are_present_is_part_of_the_pytree_structure():
    """A world-frame and a follower tip force give equal Structures and leaves of equal
    shapes; only the None parts tell the models apart, and they are part of the pytree
    structure, which keys every compiled program (jit, ``compile_key``, the persistent
    cache), so the two never share one."""
    def tip_force(frame):
        return sj.build_model(sj.Scene.from_dict({
            "solver": {"kind": "static"},
            "rods": [{"name": "r", "elements": 2, "geometry": {"kind": "straight", "length": L},
                      "stiffness": dict(EA=1e9, GAy=1e9, GAz=1e9, GJ=EI, EIy=EI, EIz=EI),
                      "inertia": dict(rhoA=RHOA, rhoJ=1e-6, rhoIy=1e-6, rhoIz=1e-6)}],
            "constraints": [{"kind": "clamp", "rod": "r", "node": 0}],
            "loads": [{"kind": "force", "rod": "r", "node": -1, "vector": [0.0, 0.0, 1.0],
                       "frame": frame}]}))

    dead, follower = tip_force("world"), tip_force("local")
    assert dead.nodal_follower is None and follower.nodal_dead is None
    assert dead.structure == follower.structure
    assert ([np.shape(x) for x in jax.tree_util.tree_leaves(dead)]
            == [np.shape(x) for x in jax.tree_util.tree_leaves(follower)])
    assert jax.tree_util.tree_structure(dead) != jax.tree_util.tree_structure(follower)
