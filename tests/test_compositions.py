"""Couplings composed in one scene, checked against closed forms and equivalences: a rod
chain welded end to end behaves exactly as one rod, whatever else is in the scene."""
import functools

import jax
import numpy as np
import pytest

import simsoft_jax as sj
from simsoft_jax.solvers import stability
from conftest import assert_gradient_equals_central_differences, crossing_rod

L, RHOA, ELEMENTS = 0.5, 2.0, 4
STIFFNESS = {"EA": 1e5, "GAy": 1e5, "GAz": 1e5, "GJ": 1.0, "EIy": 1.0, "EIz": 1.0}
INERTIA = {"rhoA": RHOA, "rhoJ": 2e-3, "rhoIy": 1e-3, "rhoIz": 1e-3}


def straight_rod(name, length, elements, x0=0.0):
    return {"name": name, "stiffness": STIFFNESS, "inertia": INERTIA, "elements": elements,
            "geometry": {"kind": "straight", "length": length},
            "base": {"position": [x0, 0.0, 0.0]}}


def slide(rod, along=(1.0, 0.0, 0.0)):
    """A drive at the rod's first node that holds its rotation and the position normal
    to ``along`` and leaves it free to slide along it."""
    return {"kind": "drive", "rod": rod, "node": 0, "times": [0.0, 1.0],
            "displacement": [[0, 0, 0], [0, 0, 0]], "rotation": [[0, 0, 0], [0, 0, 0]],
            "slides_along": list(along)}


def welded_scene(tip_force, t_end=0.2):
    """Rod a (node 0 sliding along x) welded at its end to rod b, force at b's tip."""
    return {"name": "welded slider",
            "solver": {"kind": "dynamic", "t_end": t_end, "dt": 0.01, "rho_inf": 0.9},
            "rods": [straight_rod("a", L, ELEMENTS), straight_rod("b", L, ELEMENTS, x0=L)],
            "constraints": [slide("a")],
            "joints": [{"kind": "weld", "a": {"rod": "a", "node": -1},
                        "b": {"rod": "b", "node": 0}}],
            "loads": [{"kind": "force", "rod": "b", "node": -1, "vector": list(tip_force),
                       "frame": "world"}]}


def one_rod_scene(tip_force, t_end=0.2):
    """The same assembly as one rod of twice the length."""
    return {"name": "one slider",
            "solver": {"kind": "dynamic", "t_end": t_end, "dt": 0.01, "rho_inf": 0.9},
            "rods": [straight_rod("ab", 2 * L, 2 * ELEMENTS)],
            "constraints": [slide("ab")],
            "loads": [{"kind": "force", "rod": "ab", "node": -1, "vector": list(tip_force),
                       "frame": "world"}]}


def test_welded_rods_on_a_sliding_drive_translate_as_a_rigid_body():
    """An axial tip force moves the welded pair along the slide: the centre of mass
    follows ``F t^2 / (2 rhoA 2L)`` exactly (the linear interpolation's mass is exact)."""
    F = 1.5
    r = sj.run(welded_scene([F, 0.0, 0.0]))
    assert r.converged
    t = r.time
    x0 = np.linspace(0.0, L, ELEMENTS + 1)
    com = 0.0
    for name, shift in (("a", 0.0), ("b", L)):
        u = r.positions(name)[:, :, 0] - (x0 + shift)
        com = com + (u[:, :-1] + u[:, 1:]).sum(axis=1) / (2 * ELEMENTS) / 2
    np.testing.assert_allclose(com, F * t ** 2 / (2 * RHOA * 2 * L), rtol=1e-8, atol=1e-14)


def test_welded_rods_on_a_sliding_drive_equal_one_rod():
    """A lateral and axial tip force: the welded pair and the one rod of the same length
    and elements move alike (same nodes, same positions to the solver tolerance)."""
    force = [0.4, 0.05, -0.03]
    pair, one = sj.run(welded_scene(force)), sj.run(one_rod_scene(force))
    assert pair.converged and one.converged
    both = np.concatenate([pair.positions("a"), pair.positions("b")[:, 1:]], axis=1)
    ref = one.positions("ab")
    scale = np.abs(ref - ref[:1]).max()
    assert scale > 1e-3
    np.testing.assert_allclose(both, ref, atol=1e-7 * scale + 1e-12)


def test_a_joint_on_a_sliding_node_is_refused():
    d = welded_scene([1.0, 0.0, 0.0])
    d["constraints"] = [dict(slide("b"))]
    with pytest.raises(ValueError, match=r"^constraints\[0\]\.slides_along: a joint acts"):
        sj.Scene.from_dict(d)


def test_gradient_through_welded_rods_on_a_sliding_drive_equals_finite_differences():
    import jax.numpy as jnp

    model = sj.build_model(sj.Scene.from_dict(welded_scene([0.4, 0.05, -0.03])))
    settings = sj.DynamicSettings(dt=0.01, steps=10, rho_inf=0.9)

    def tip(theta):
        m = model.replace(nodal_dead=model.nodal_dead * theta[0],
                          stiffness=model.stiffness * theta[1])
        return sj.simulate(m, settings, differentiable=True).p[-1, -1] @ jnp.array(
            [1.0, 2.0, -1.0])

    assert_gradient_equals_central_differences(tip, [1.0, 1.0])


# ------------------------------------------------ rod-rod contact with joints and bodies

N_TOP, L_TOP, R_C = 4, 0.2, 0.005


def cantilever_on_a_rod(welded: bool, kind="static"):
    """A cantilever along x (clamped at x = -L/2) pressed by a tip force onto a rod along
    y clamped at both ends, crossing at the cantilever's middle node; ``welded``: the
    cantilever is two rods welded at that node (a coupling node of the joint)."""
    from simsoft_jax.physics.terms.contact import SMOOTHING
    z = 2 * R_C - SMOOTHING * 2 * R_C      # a smoothing width into the contact
    if welded:
        top = [crossing_rod("a", -L_TOP / 2, L_TOP / 2, N_TOP // 2, z=z),
               crossing_rod("b", 0.0, L_TOP / 2, N_TOP // 2, z=z)]
        joints = [{"kind": "weld", "a": {"rod": "a", "node": -1},
                   "b": {"rod": "b", "node": 0}}]
    else:
        top, joints = [crossing_rod("a", -L_TOP / 2, L_TOP, N_TOP, z=z)], []
    solver = ({"kind": "static", "load_steps": 5} if kind == "static" else
              {"kind": "dynamic", "dt": 0.005, "t_end": 0.03, "rho_inf": 0.8})
    return {"solver": solver,
            "rods": top + [crossing_rod("bottom", -L_TOP / 2, L_TOP, N_TOP, along_y=True)],
            "constraints": [{"kind": "clamp", "rod": "a", "node": 0}]
                           + [{"kind": "clamp", "rod": "bottom", "node": n} for n in (0, -1)],
            "joints": joints,
            "loads": [{"kind": "force", "rod": "b" if welded else "a", "node": -1,
                       "vector": [0.0, 0.0, -2.0]}],
            "contact": {"radius": R_C, "self": True, "max_pairs": 6,
                        "quadrature_points": 4}}


@functools.lru_cache(maxsize=None)
def cantilever_run(welded: bool, kind: str):
    """``sj.run`` of :func:`cantilever_on_a_rod`, once per module for the tests below."""
    return sj.run(sj.Scene.from_dict(cantilever_on_a_rod(welded, kind)))


@pytest.mark.parametrize("kind", ["static", "dynamic"])
def test_welded_cantilever_on_a_rod_equals_one_rod(kind):
    """Rod-rod contact with a weld at the crossing: the welded pair gives the one rod's
    answer (the weld's two elements never touch each other), and the contact holds it
    (its middle stays on the lower rod while a free cantilever would sink through)."""
    pair, one = cantilever_run(True, kind), cantilever_run(False, kind)
    assert pair.converged and one.converged
    both = np.concatenate([pair.positions("a"), pair.positions("b")[..., 1:, :]], axis=-2)
    ref = one.positions("a")
    np.testing.assert_allclose(both, ref, atol=1e-8)
    np.testing.assert_allclose(pair.positions("bottom"), one.positions("bottom"), atol=1e-8)
    middle = ref[..., N_TOP // 2, 2] - one.positions("bottom")[..., N_TOP // 2, 2]
    assert np.all(middle > 1.5 * R_C)          # on top of the lower rod, not through it
    if kind == "static":
        tip = ref[..., -1, 2] - ref[..., 0, 2]
        free_tip = -2.0 * L_TOP ** 3 / 3.0      # the free cantilever's F L^3 / 3 EI
        assert tip > 0.5 * free_tip             # the contact carries part of the load


# ------------------------------------------------ stability count of the coupled tangent

# the count, compiled: one program per structure instead of its hundreds of operations
# compiled one by one
negative_eigenvalues = jax.jit(stability.negative_eigenvalues)


@jax.jit
def _tangent_parts(model, R, p):
    """The rods' dense tangent (6N, 6N) and the rod-rod contact's coupling factors B, C
    at the full loads (one compiled program per structure; eagerly, each of its
    operations compiles on its own: hundreds of small programs)."""
    from simsoft_jax.math import linalg
    from simsoft_jax.couplings import rod_pairs
    from simsoft_jax.physics.assembly import residual_and_tangent
    from simsoft_jax.model.loads import full_loads

    loaded = full_loads(model)
    r, blocks = residual_and_tangent(loaded, R, p, 1.0)
    _, blocks, c = rod_pairs.system(loaded, R, p, r, blocks)
    return linalg.dense(blocks), c.B, c.C


def _dense_contact_count(model, R, p):
    """Negative eigenvalues of the symmetric part of the whole constrained tangent with
    the rod-rod contact, assembled densely here (chains + U W U^T), and its smallest
    eigenvalue magnitude."""
    K, B, C = map(np.asarray, _tangent_parts(model, R, p))
    n = R.shape[0]
    U = B.reshape(6 * n, -1)
    W = np.einsum("anj,njb->ab", C, B)
    K = K + U @ W @ U.T
    eigenvalues = np.linalg.eigvalsh(0.5 * (K + K.T))
    return int(np.sum(eigenvalues < 0.0)), float(np.abs(eigenvalues).min())


def test_stability_count_with_rod_contact_equals_the_dense_count():
    """The count through the bordered system (stable crossing: 0) and, with a softening
    that makes the rods' tangent indefinite, the same count as the dense tangent."""
    result = cantilever_run(False, "static")
    assert result.converged and result.stability["negative_eigenvalues"] == 0
    model, eq = result.model, result.raw
    assert _dense_contact_count(model, eq.R, eq.p)[0] == 0
    for factor in (-0.2, -0.5):
        soft = model.replace(stiffness=np.asarray(model.stiffness) * np.where(
            np.arange(model.stiffness.shape[0])[:, None] % 3 == 1, factor, 1.0))
        dense, smallest = _dense_contact_count(soft, eq.R, eq.p)
        assert dense > 0 and smallest > 1e-6      # no eigenvalue near zero: a sharp count
        assert int(negative_eigenvalues(soft, eq)) == dense


def test_stability_count_with_contact_and_a_weld_equals_one_rod():
    """Joints and rod-rod contact together: the welded pair counts as the one rod, for a
    stable equilibrium and for an indefinite (softened) tangent."""
    pair, one = cantilever_run(True, "static"), cantilever_run(False, "static")
    assert pair.stability["negative_eigenvalues"] == one.stability["negative_eigenvalues"] == 0
    for model, result in ((pair.model, pair), (one.model, one)):
        assert result.converged
    soft = lambda m: m.replace(stiffness=np.asarray(m.stiffness) * np.where(  # noqa: E731
        np.arange(m.stiffness.shape[0])[:, None] == 1, -0.5, 1.0))
    count_pair = int(negative_eigenvalues(soft(pair.model), pair.raw))
    count_one = int(negative_eigenvalues(soft(one.model), one.raw))
    assert count_one > 0 and count_pair == count_one
