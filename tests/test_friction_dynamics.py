"""Stick-slip (elastic-plastic) friction in dynamics (``[contact] friction_law =
"stick_slip"``, :mod:`simsoft_jax.physics.terms.contact` (S1)-(S3)) at an ordinary time step
(dt = 2 ms): a stiff rod on an inclined plane held below the friction angle and sliding
with Coulomb's acceleration above it, the capstan held and slipping around the threshold
``exp(mu theta)``, Newton's iterations per step, and a gradient through a rollout against
central finite differences. References are closed forms (derived in each test).
"""
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import simsoft_jax as sj

DT, G = 2.0e-3, 9.81

# the block: a short stiff rod lying along x on the plane z = 0, gravity tilted in the xz
# plane (the plane is the incline); contact radius R_B, penalty K_B
L_B, N_B, R_B, K_B, RHOA_B, MU_B = 0.1, 4, 0.01, 1.0e6, 1.0, 0.5


def resting_penetration(tan_angle):
    """The block's penetration (m) at rest on the incline: its weight per length rhoA g cos a
    on L spread on the contact length L + 2 R_B (the end caps), ``psi'(delta) = q`` solved
    on the penalty's cubic start (or beyond it)."""
    from simsoft_jax.physics.terms.contact import SMOOTHING
    q = RHOA_B * G * np.cos(np.arctan(tan_angle)) * L_B / (L_B + 2 * R_B)
    eps = SMOOTHING * R_B
    cubic = np.sqrt(2.0 * eps * q / K_B)
    return cubic if cubic < eps else q / K_B + 0.5 * eps


def block_scene(tan_angle, t_end=0.2, law="stick_slip", mu=MU_B):
    """The block at rest on the incline, sunk to its resting penetration (no bounce)."""
    a = np.arctan(tan_angle)
    return {
        "solver": {"kind": "dynamic", "t_end": t_end, "dt": DT, "rho_inf": 0.5},
        "gravity": {"vector": [G * np.sin(a), 0.0, -G * np.cos(a)]},
        "rods": [{"name": "block", "elements": N_B,
                  "geometry": {"kind": "straight", "length": L_B},
                  "base": {"position": [0.0, 0.0, -resting_penetration(tan_angle)]},
                  "stiffness": {"EA": 1e6, "GAy": 1e6, "GAz": 1e6, "GJ": 10.0, "EIy": 10.0,
                                "EIz": 10.0},
                  "inertia": {"rhoA": RHOA_B, "rhoJ": 1e-4, "rhoIy": 5e-5, "rhoIz": 5e-5}}],
        "obstacles": [{"name": "incline", "kind": "plane", "point": [0.0, 0.0, -R_B],
                       "normal": [0.0, 0.0, 1.0], "friction": mu}],
        "contact": {"radius": R_B, "stiffness": K_B, "friction_law": law}}


# the capstan: a rope over a fixed drum of radius RC (axis y through the origin), its
# two straight ends hanging down along -z, pulled down by T0 (first node) and T1 (last)
# (the penalty K_R makes the contact time pi sqrt(rhoA/k) = 20 ms ten steps long: resting
# contact is resolved in time, and the step-refusal of fast impacts never triggers)
RC, R_R, MU_C, THETA = 0.1, 0.01, 0.3, np.pi
EA_R, EI_R, RHOA_R, K_R = 1.0e3, 1.0e-5, 1.0, 2.4e4
DEPTH = 0.01 * R_R
RW = RC + R_R - DEPTH
NV, NA = 8, 26                          # elements on each straight end, on the wrap
H_R = RW * THETA / NA
T0 = 1.0


def _rope_start():
    """Node positions and rotations of the rope: up along x = -RW, over the drum, down
    along x = +RW (arclength s from the lower left end)."""
    points, rotations = [], []
    lv = NV * H_R
    for s in H_R * np.arange(2 * NV + NA + 1):
        phi = np.clip((s - lv) / RW, 0.0, THETA) - 0.5 * np.pi   # -pi/2 .. pi/2 over the top
        before = min(s - lv, 0.0)
        after = max(s - lv - RW * THETA, 0.0)
        t = np.array([np.cos(phi), 0.0, -np.sin(phi)])          # unit tangent
        x = RW * np.array([np.sin(phi), 0.0, np.cos(phi)]) + (before + after) * t
        points.append(x.tolist())
        rotations.append(np.column_stack([t, [0.0, 1.0, 0.0], np.cross(t, [0.0, 1.0, 0.0])])
                         .tolist())                             # local y along world y
    return points, rotations


def capstan_scene(ratio, t_end=0.2, law="stick_slip", slip_velocity=None):
    points, rotations = _rope_start()
    contact = {"radius": R_R, "stiffness": K_R, "friction_law": law}
    if slip_velocity is not None:
        contact["slip_velocity"] = slip_velocity
    ramp = {"kind": "smoothstep", "t0": 0.0, "t1": 0.05}
    return {
        "solver": {"kind": "dynamic", "t_end": t_end, "dt": DT, "rho_inf": 0.5},
        "rods": [{"name": "rope", "elements": 2 * NV + NA,
                  "geometry": {"kind": "polyline", "points": points},   # unstressed
                  "base": {"position": [0.0, 0.0, 0.0]},
                  "initial": {"points": points, "rotations": rotations},
                  "stiffness": {"EA": EA_R, "GAy": EA_R, "GAz": EA_R, "GJ": EI_R,
                                "EIy": EI_R, "EIz": EI_R},
                  "inertia": {"rhoA": RHOA_R, "rhoJ": 1e-4, "rhoIy": 1e-4, "rhoIz": 1e-4}}],
        "loads": [{"kind": "force", "rod": "rope", "node": 0, "vector": [0.0, 0.0, -T0],
                   "profile": ramp},
                  {"kind": "force", "rod": "rope", "node": -1,
                   "vector": [0.0, 0.0, -ratio * T0], "profile": ramp}],
        "obstacles": [{"name": "drum", "kind": "cylinder", "axis_point": [0.0, 0.0, 0.0],
                       "axis": [0.0, 1.0, 0.0], "radius": RC, "friction": MU_C}],
        "contact": contact}


def _block_x(res):
    """Mean x (m) of the block's nodes at the saved times."""
    return res.positions("block")[:, :, 0].mean(axis=1)


def test_block_on_an_incline_is_held_below_the_friction_angle_and_slides_above_it():
    """The block (a stiff rod lying along the slope) on an incline with mu = 0.5, at rest at
    t = 0 with its springs unstretched, dt = 2 ms. Below the friction angle (tan a =
    0.8 mu) it holds: after the first swing of its tangential springs (the friction is
    loaded from zero at t = 0; the swing is damped by rho_inf = 0.5 within 0.05 s) its
    position moves by less than 1e-6 m over the remaining 0.15 s. Above it (tan a = 1.2
    mu) it slides with Coulomb's acceleration g (sin a - mu cos a) (closed form for a block
    on an incline), fitted on x(t) over 0.05 - 0.2 s, to 1 %. Both runs take every step
    whole (no sub-step) in at most 8 Newton iterations on average, and so does the block
    dropped onto the incline at contact onset (its penalty bouncing, the friction's cap
    mu f_n changing from step to step: Newton's damping of non-shrinking corrections).
    Without it, exact Newton cycled there between the two sliding directions of the
    stations, and a step failed after 600 iterations."""
    held = sj.run(block_scene(0.8 * MU_B))
    slid = sj.run(block_scene(1.2 * MU_B))
    dropped = block_scene(0.8 * MU_B)
    dropped["rods"][0]["base"]["position"] = [0.0, 0.0, 0.0]
    for res in (held, slid, sj.run(dropped)):
        assert res.converged
        assert int(np.max(res.raw.substeps)) == 1
        assert np.mean(res.raw.iterations) <= 8.0
    x, t = _block_x(held), held.time
    settled = t >= 0.05 - 1e-12
    assert np.ptp(x[settled]) < 1e-6
    x, t = _block_x(slid), slid.time
    a = np.arctan(1.2 * MU_B)
    expected = G * (np.sin(a) - MU_B * np.cos(a))
    fit = np.polyfit(t[settled], x[settled], 2)
    assert 2.0 * fit[0] == pytest.approx(expected, rel=1e-2)


def test_capstan_holds_below_exp_mu_theta_and_slips_above_it():
    """A rope over a fixed rough drum (mu = 0.3, wrap theta = pi), its two hanging ends
    pulled down by T0 and T1 ramped up over 0.05 s (no gravity). A string on a rough drum
    holds while T1/T0 < exp(mu theta) = 2.57 (the capstan equation; the rope's bending
    stiffness shifts it by a relative ~mu sqrt(EI/(T R^2)) ~ 1 %) and slips towards T1
    above it.
    At T1/T0 = 0.85 exp(mu theta) the rope settles: its node on top of the drum moves by
    less than 0.5 mm over 0.2 - 0.3 s (a sliding rope at 1.15 exp(mu theta) moves by more
    than 5 mm over the same interval, ten times more, and faster in its second half:
    it accelerates)."""
    threshold = np.exp(MU_C * THETA)
    top = NV + NA // 2
    moved = {}
    for ratio in (0.85, 1.15):
        res = sj.run(capstan_scene(ratio * threshold, t_end=0.3))
        assert res.converged
        assert int(np.max(res.raw.substeps)) == 1
        x = res.positions("rope")[:, top, 0]
        i0, i1, i2 = (np.argmin(np.abs(res.time - t)) for t in (0.2, 0.25, 0.3))
        moved[ratio] = (x[i1] - x[i0], x[i2] - x[i1])
    assert abs(sum(moved[0.85])) < 5e-4
    assert sum(moved[1.15]) > 5e-3
    assert moved[1.15][1] > moved[1.15][0] > 0.0


@pytest.mark.slow    # compiles the differentiable rollout and its reverse pass: ~1 min
def test_gradient_through_a_rollout_with_stick_slip_friction_matches_finite_differences():
    """d x_final / d mu of the sliding block and d x_final / d g_x of the held block (the
    anchors carry the friction's history through every step) after 10 steps, by reverse
    mode through ``simulate(differentiable=True)`` against central finite differences of
    the same rollout (relative steps 1e-5; agreement to 1e-4). Both blocks share one
    structure: one compiled program for the gradient and the differences' values."""
    settings = sj.DynamicSettings(dt=DT, steps=10, rho_inf=0.5)

    def final_x(model):
        return sj.simulate(model, settings, differentiable=True).p[-1, :, 0].mean()

    both = jax.jit(jax.value_and_grad(final_x))
    slide = sj.build_model(sj.Scene.from_dict(block_scene(1.2 * MU_B)))
    hold = sj.build_model(sj.Scene.from_dict(block_scene(0.8 * MU_B)))
    cases = [(slide, "obstacle_friction", lambda x, q: x.at[0].set(q), MU_B),
             (hold, "gravity", lambda x, q: x.at[0].set(q), float(hold.gravity[0]))]
    for model, field, put, at in cases:
        grad = float(getattr(both(model)[1], field)[0])
        h = 1e-5 * abs(at)
        moved = [both(model.replace(**{field: put(getattr(model, field), q)}))[0]
                 for q in (at + h, at - h)]
        fd = float(moved[0] - moved[1]) / (2.0 * h)
        assert abs(grad) > 0.0
        assert grad == pytest.approx(fd, rel=1e-4)


def test_a_rope_swinging_clear_of_a_plane_with_friction_steps_like_a_frictionless_one():
    """A soft rope pinned at one end swings down from the horizontal under gravity, far
    above a plane with stick-slip friction (mu = 0.3): no station touches it, so the
    rollout is that of the same rope without the plane (independent reference: the run
    without the obstacle) to 1e-9 m, and Newton converges as fast. Newton's damping of
    non-shrinking corrections (the stick-slip law's guard against cycling) compares a fresh
    correction with the last full one: compared with the last halved one, every fresh
    correction of a converging solve was halved again and the solve crawled at rate 1/2
    per two iterations (steps of a slack rope failed at the iteration limit)."""
    def scene(plane):
        s = {"solver": {"kind": "dynamic", "t_end": 0.2, "dt": 0.02, "rho_inf": 0.5},
             "gravity": {"vector": [0.0, 0.0, -G]},
             "rods": [{"name": "rope", "elements": 20,
                       "geometry": {"kind": "straight", "length": 0.5},
                       "base": {"position": [0.0, 0.0, 0.0]},
                       "material": {"E": 1e6, "G": 1e6 / 3.0, "density": 1000.0},
                       "section": {"shape": "circle", "diameter": 0.005}}],
             "constraints": [{"kind": "pin", "rod": "rope", "node": 0}]}
        if plane:
            s["obstacles"] = [{"name": "floor", "kind": "plane", "point": [0.0, 0.0, -2.0],
                               "normal": [0.0, 0.0, 1.0], "friction": 0.3}]
            s["contact"] = {"friction_law": "stick_slip"}
        return s
    free, over = sj.run(scene(False)), sj.run(scene(True))
    assert free.converged and over.converged
    np.testing.assert_allclose(over.positions("rope"), free.positions("rope"), atol=1e-9)
    assert np.sum(over.raw.iterations) <= 1.2 * np.sum(free.raw.iterations)


def test_newton_does_not_cycle_on_a_block_held_near_the_friction_angle_at_long_steps():
    """The block on the incline at tan a = 0.9 mu and 1.1 mu with steps of 20 ms, where its
    tangential springs (K_B) are 400 times the step's inertia term rhoA / dt^2: a
    correction made while a station slides (the saturated law's slope along the slip
    vanishes) overshoots the sticking solution by about that factor, onto the other
    sliding direction. Newton cuts such a correction where the station's trial load
    passes nearest its anchor (``reversal_cut``): once the block's springs are loaded
    (after the first three steps) no step takes more than 15 Newton iterations (without
    the cut, steps 4 and 5 of the held block took 22 and 29, cycling). The answers are
    Coulomb's: held below the friction angle (it moves by less than 1e-6 m after 0.1 s),
    sliding above it with the acceleration g (sin a - mu cos a) to 1e-3."""
    for ratio in (0.9, 1.1):
        s = block_scene(ratio * MU_B, t_end=0.4)
        s["solver"]["dt"] = 0.02
        res = sj.run(s)
        assert res.converged
        assert int(np.max(np.asarray(res.raw.iterations)[3:])) <= 15
        x, t = _block_x(res), res.time
        later = t >= 0.1 - 1e-12
        a = np.arctan(ratio * MU_B)
        if ratio < 1.0:
            assert np.ptp(x[later]) < 1e-6
        else:
            fit = np.polyfit(t[later], x[later], 2)
            assert 2.0 * fit[0] == pytest.approx(G * (np.sin(a) - MU_B * np.cos(a)), rel=1e-3)
