"""Couplings composed in one scene, checked against closed forms and equivalences: a rod
chain welded end to end behaves exactly as one rod, whatever else is in the scene."""
import numpy as np
import pytest

import simsoft_jax as sj

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
    import jax
    import jax.numpy as jnp

    model = sj.build_model(sj.Scene.from_dict(welded_scene([0.4, 0.05, -0.03])))
    settings = sj.DynamicSettings(dt=0.01, steps=10, rho_inf=0.9)

    def tip(theta):
        m = model.replace(nodal_dead=model.nodal_dead * theta[0],
                          stiffness=model.stiffness * theta[1])
        return sj.simulate(m, settings, differentiable=True).p[-1, -1] @ jnp.array(
            [1.0, 2.0, -1.0])

    theta = jnp.array([1.0, 1.0])
    g = jax.grad(tip)(theta)
    h = 1e-5
    fd = np.array([(tip(theta.at[i].add(h)) - tip(theta.at[i].add(-h))) / (2 * h)
                   for i in range(2)])
    assert np.abs(fd).min() > 1e-6
    np.testing.assert_allclose(g, fd, rtol=1e-5)
