"""simsoft_jax.solvers.packing: program outputs as one float64 vector, rebuilt on the host."""
import jax
import numpy as np
import pytest

import simsoft_jax as sj
from simsoft_jax.model import built_models
from simsoft_jax.solvers import programs
from simsoft_jax.solvers.packing import Layout, pack
from simsoft_jax.solvers.statics import as_traced, settings_from_scene


def test_round_trip_keeps_values_shapes_types_and_absent_fields():
    tree = {"R": np.arange(18.0).reshape(2, 3, 3) / 7.0, "ok": np.bool_(True),
            "its": np.int64(2**52 + 1), "none": None, "v": np.array([-1.5e300, 3e-310])}
    like = jax.tree_util.tree_map(lambda x: jax.ShapeDtypeStruct(np.shape(x), x.dtype), tree)
    back = Layout(like).unpack(np.asarray(jax.jit(pack)(tree)))
    assert back["none"] is None
    for key in ("R", "ok", "its", "v"):
        assert back[key].dtype == tree[key].dtype and back[key].shape == np.shape(tree[key])
        np.testing.assert_array_equal(back[key], tree[key])


def test_layout_of_another_size_is_refused():
    like = (jax.ShapeDtypeStruct((2, 3), np.float64),)
    with pytest.raises(ValueError, match="packed vector of 5 numbers, layout of 6"):
        Layout(like).unpack(np.zeros(5))


STIFF = {"EA": 1e4, "GAy": 1e4, "GAz": 1e4, "GJ": 1.0, "EIy": 1.0, "EIz": 1.0}


def rod(name, x=0.0):
    return {"name": name, "stiffness": STIFF, "elements": 4,
            "inertia": {"rhoA": 1.0, "rhoJ": 1.0, "rhoIy": 1.0, "rhoIz": 1.0},
            "geometry": {"kind": "straight", "length": 1.0},
            "base": {"position": [0.0, x, 0.0]}}


PLAIN = {"name": "layout", "solver": {"kind": "static"}, "rods": [rod("a")],
         "constraints": [{"kind": "clamp", "rod": "a", "node": 0}],
         "loads": [{"kind": "force", "rod": "a", "node": -1, "vector": [0.0, 0.0, -0.01]}]}
TENDON = {**PLAIN, "tendons": [{"name": "t", "rod": "a", "from_node": 0, "to_node": -1,
                                "offset": [0.0, 0.01], "tension": 0.1}]}
JOINT = {**PLAIN, "rods": [rod("a"), rod("b")],
         "constraints": [{"kind": "clamp", "rod": r, "node": 0} for r in "ab"],
         "joints": [{"kind": "weld", "a": {"rod": "a", "node": -1},
                     "b": {"rod": "b", "node": -1}}]}
FRICTION = {**PLAIN, "obstacles": [{"name": "floor", "kind": "plane",
                                    "point": [0.0, 0.0, -0.05], "normal": [0.0, 0.0, 1.0],
                                    "friction": 0.3}],
            "contact": {"radius": 0.01, "stiffness": 1e3}}


@pytest.mark.parametrize("scene", [PLAIN, TENDON, JOINT, FRICTION],
                         ids=["plain", "tendon", "joint", "friction"])
def test_static_layout_is_the_traced_output(scene):
    """The hand-written layout of the static program's packed output has the shapes and
    types JAX traces for those fields (plain rod, tendons, joints, friction), and adds up to the
    traced size of the packed vector."""
    scene = sj.Scene.from_dict(scene)
    model = built_models.model_of(scene)
    settings = as_traced(settings_from_scene(scene.solver))
    R, p, packed = jax.eval_shape(programs.solve_static_checked, model, settings,
                                  np.bool_(True))
    n = model.structure.n_nodes
    assert (R.shape, p.shape) == ((n, 3, 3), (n, 3))
    layout = programs.static_layout(model)
    size = sum(int(np.prod(x.shape)) for x in jax.tree_util.tree_leaves(layout))
    assert packed.shape == (size,)
    fields = jax.eval_shape(lambda m, st: sj.statics.equilibrium(m, st, keep_tangent=True)
                            ._replace(R=None, p=None, tangent_positive=None), model, settings)
    assert jax.tree_util.tree_structure(fields) == jax.tree_util.tree_structure(layout[0])
    for got, want in zip(jax.tree_util.tree_leaves(fields),
                         jax.tree_util.tree_leaves(layout[0])):
        assert got.shape == want.shape and np.dtype(got.dtype) == np.dtype(want.dtype)
    assert np.dtype(layout[1].dtype) == np.int64
