"""Drive constraints with ``slides_along``: the node follows its prescribed rotation and
the position components normal to e, and slides freely along the world direction e."""
import numpy as np

import simsoft_jax as sj
from conftest import assert_gradient_equals_central_differences

L, RHOA, F = 1.0, 2.0, 1.5
ELEMENTS = 4


def rod_scene(tip_force, drive=None, t_end=0.5, dt=0.01):
    drive = drive or {"times": [0.0, 1.0], "displacement": [[0, 0, 0], [0, 0, 0]],
                      "rotation": [[0, 0, 0], [0, 0, 0]], "slides_along": [1, 0, 0]}
    return {
        "name": "slider",
        "solver": {"kind": "dynamic", "t_end": t_end, "dt": dt, "rho_inf": 0.9},
        "rods": [{
            "name": "rod",
            "stiffness": {"EA": 1e5, "GAy": 1e5, "GAz": 1e5, "GJ": 1.0, "EIy": 1.0,
                          "EIz": 1.0},
            "inertia": {"rhoA": RHOA, "rhoJ": 2e-3, "rhoIy": 1e-3, "rhoIz": 1e-3},
            "elements": ELEMENTS,
            "geometry": {"kind": "straight", "length": L},
        }],
        "constraints": [dict({"kind": "drive", "rod": "rod", "node": 0}, **drive)],
        "loads": [{"kind": "force", "rod": "rod", "node": -1, "vector": list(tip_force),
                   "frame": "world"}],
    }


def test_axial_tip_force_translates_the_rod_along_the_slide():
    r = sj.run(rod_scene([F, 0.0, 0.0]))
    assert r.converged and r.failed_at is None
    t, p, R = r.time, r.positions("rod"), r.rotations("rod")
    x0 = np.linspace(0.0, L, ELEMENTS + 1)
    # centre of mass of the linearly interpolated straight rod: exact rigid acceleration
    u = p[:, :, 0] - x0
    com = (u[:, :-1] + u[:, 1:]).sum(axis=1) / (2 * ELEMENTS)
    expected = F * t ** 2 / (2 * RHOA * L)
    np.testing.assert_allclose(com, expected, rtol=1e-9, atol=1e-14)
    # node 0 slides with the rod (axial vibrations are of order F L / EA)
    np.testing.assert_allclose(p[:, 0, 0], expected, rtol=0, atol=3 * F * L / 1e5)
    assert p[-1, 0, 0] > 0.9 * expected[-1]
    np.testing.assert_allclose(p[:, :, 1:], 0.0, atol=1e-12)
    np.testing.assert_allclose(R, np.broadcast_to(np.eye(3), R.shape), atol=1e-12)


def test_normal_tip_force_keeps_the_prescribed_components():
    load = 0.05
    r = sj.run(rod_scene([0.0, load, 0.0]))
    assert r.converged
    p, R = r.positions("rod"), r.rotations("rod")
    # held components: y, z of the node and its rotation
    np.testing.assert_allclose(p[:, 0, 1:], 0.0, atol=1e-12)
    np.testing.assert_allclose(R[:, 0], np.broadcast_to(np.eye(3), R[:, 0].shape), atol=1e-12)
    # the slide is only second order in the deflection: the lateral response matches the
    # same rod fully held at node 0 (clamp) to first order
    clamp = rod_scene([0.0, load, 0.0])
    clamp["constraints"] = [{"kind": "clamp", "rod": "rod", "node": 0}]
    pc = sj.run(clamp).positions("rod")
    tip, tip_c = p[:, -1, 1], pc[:, -1, 1]
    scale = np.abs(tip_c).max()
    assert scale > 1e-3
    np.testing.assert_allclose(tip, tip_c, atol=1e-3 * scale)
    assert np.abs(p[:, 0, 0]).max() < scale ** 2 / L


def test_sliding_drive_follows_the_prescribed_motion_normal_to_the_slide():
    e = np.array([1.0, 1.0, 0.0]) / np.sqrt(2.0)
    drive = {"times": [0.0, 0.3], "displacement": [[0, 0, 0], [0.02, -0.05, 0.04]],
             "rotation": [[0, 0, 0], [0.3, -0.2, 0.4]], "slides_along": list(e)}
    t_end = 0.4
    r = sj.run(rod_scene([F, 0.3, -0.2], drive, t_end=t_end))
    assert r.converged
    t, p, R = r.time, r.positions("rod"), r.rotations("rod")
    frac = np.minimum(t / 0.3, 1.0)[:, None]
    pc = frac * np.array([0.02, -0.05, 0.04])
    d = p[:, 0] - pc
    normal = d - (d @ e)[:, None] * e
    np.testing.assert_allclose(normal, 0.0, atol=1e-9)
    assert np.abs(d @ e).max() > 1e-3           # it did slide
    for k in range(len(t)):
        rv = frac[k, 0] * np.array([0.3, -0.2, 0.4])
        np.testing.assert_allclose(R[k, 0], np.asarray(sj.lie.exp_so3(rv)), atol=1e-9)


def _final_com_x(model, steps):
    """x of the centre of mass of the linearly interpolated rod at the last step."""
    p = sj.simulate(model, sj.DynamicSettings(dt=0.01, steps=steps, rho_inf=0.9),
                    differentiable=True).p[-1]
    u = p[:, 0]
    return (u[:-1] + u[1:]).sum() / (2 * ELEMENTS)


def test_gradient_through_a_sliding_drive_equals_the_rigid_closed_form():
    import jax

    model = sj.build_model(sj.Scene.from_dict(rod_scene([F, 0.0, 0.0])))
    assert model.structure.slide_drives == (0,)
    steps = 20
    t = 0.01 * steps
    # an axial tip force translates the whole rod along the slide: com = F t^2 / (2 rhoA L)
    scale = jax.grad(lambda k: _final_com_x(model.replace(
        nodal_dead=model.nodal_dead * k), steps))(1.0)
    np.testing.assert_allclose(scale, F * t ** 2 / (2 * RHOA * L), rtol=1e-8)


def test_gradient_through_a_turning_sliding_drive_equals_finite_differences():
    import jax.numpy as jnp

    e = np.array([1.0, 1.0, 0.0]) / np.sqrt(2.0)
    drive = {"times": [0.0, 0.3], "displacement": [[0, 0, 0], [0.02, -0.05, 0.04]],
             "rotation": [[0, 0, 0], [0.3, -0.2, 0.4]], "slides_along": list(e)}
    model = sj.build_model(sj.Scene.from_dict(rod_scene([F, 0.3, -0.2], drive)))
    settings = sj.DynamicSettings(dt=0.01, steps=12, rho_inf=0.9)

    def tip(theta):
        m = model.replace(nodal_dead=model.nodal_dead * theta[0],
                          stiffness=model.stiffness * theta[1],
                          drive_slide=model.drive_slide * theta[2])
        return sj.simulate(m, settings, differentiable=True).p[-1, -1] @ jnp.array(
            [0.3, 1.0, -0.5])

    # the slide direction's length does not matter (it is normalised): that component is 0
    assert_gradient_equals_central_differences(tip, [1.0, 1.0, 1.0], every_component=False)
