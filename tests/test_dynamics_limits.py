"""What a dynamic step cannot resolve is sub-stepped or reported, never silently converged.

Rotation: a node may not turn by pi/2 or more in one (sub-)step (the branch of the
exponential map, status ``off_branch``); the differentiable rollout sub-steps the same way. Reference: a free straight rod spinning about
its own axis at omega = 100 rad/s turns rigidly, ``R(t) = Rx(omega t)`` (no force acts:
each section spins about its principal axis); at dt = 0.1 s that is 10 rad per step.

Contact: an impact must last at least ten steps (contact time ``pi sqrt(rhoA/k)``).
Reference: a straight rod dropped flat from a gap h0 onto a frictionless plane under
gravity falls freely for ``sqrt(2 h0 / g)`` and, the penalty being conservative, can
rise after the bounce at most back to h0.
"""
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import simsoft_jax as sj
from conftest import dropped_rod_scene

OMEGA, DT, T_END = 100.0, 0.1, 1.0
R_C, H0, G = 0.02, 0.05, 9.81


def spin(dt=DT, drive=False):
    scene = {"name": "spin", "solver": {"kind": "dynamic", "dt": dt, "t_end": T_END},
             "rods": [{"name": "c", "elements": 4,
                       "stiffness": {"EA": 1e4, "GAy": 1e4, "GAz": 1e4, "GJ": 1.0,
                                     "EIy": 1.0, "EIz": 1.0},
                       "inertia": {"rhoA": 1.0, "rhoJ": 0.01, "rhoIy": 0.01, "rhoIz": 0.01},
                       "geometry": {"kind": "straight", "length": 1.0}}]}
    if drive:
        scene["constraints"] = [{"kind": "drive", "rod": "c", "node": 0, "times": [0.0, T_END],
                                 "rotation": [[0, 0, 0], [OMEGA * T_END, 0, 0]]}]
    else:
        scene["initial_velocity"] = [{"rod": "c", "angular": [OMEGA, 0.0, 0.0]}]
    return scene


def angle_about_x(R):
    return np.arctan2(R[..., 2, 1], R[..., 1, 1])


def wrapped(a):
    return np.angle(np.exp(1j * a))


def test_spin_of_ten_radians_per_step_is_sub_stepped_and_exact():
    """Every step of 10 rad is cut into sub-steps below pi/2 (at least 7 of them), and
    the rod turns as the rigid spin does at every saved time."""
    result = sj.run(spin())
    assert result.converged
    assert np.all(np.asarray(result.raw.substeps) >= 7)
    angles = angle_about_x(result.rotations("c"))                  # (T, nodes)
    expected = wrapped(OMEGA * result.time)[:, None]
    np.testing.assert_allclose(wrapped(angles - expected), 0.0, atol=1e-8)
    np.testing.assert_allclose(result.positions("c")[-1], result.positions("c")[0], atol=1e-9)


def test_drive_turning_ten_radians_per_step_is_sub_stepped():
    """A drive that turns its node 10 rad per step (a step's increment would wrap to
    10 - 4 pi = -2.57 rad) is followed in sub-steps below pi/2; the driven node keeps the
    drive's angle."""
    result = sj.run(spin(drive=True))
    assert result.converged
    assert np.all(np.asarray(result.raw.substeps) >= 7)
    base = angle_about_x(result.rotations("c")[:, 0])
    np.testing.assert_allclose(wrapped(base - OMEGA * result.time), 0.0, atol=1e-9)


def test_differentiable_rollout_sub_steps_and_its_gradient_is_the_spin_rate():
    """The differentiable rollout sub-steps the 10 rad steps as the plain one does, and
    the derivative of the final spin angle in the initial spin rate is the elapsed time
    (rigid spin: angle = omega t), through every sub-step's implicit derivative."""
    model = sj.build_model(sj.Scene.from_dict(spin()))
    settings = sj.DynamicSettings(dt=DT, steps=3)

    def final_angle(omega):
        """The final spin angle; aux: the differentiable rollout's convergence and
        sub-steps (from the gradient's own program: a plain call of the differentiable
        rollout would compile another)."""
        changed = model.replace(v0=model.v0.at[:, 3].set(omega))
        traj = sj.simulate(changed, settings, differentiable=True)
        R = traj.R[-1, -1]
        return jnp.arctan2(R[2, 1], R[1, 1]), (traj.converged, traj.substeps)

    (value, (converged, substeps)), slope = jax.jit(jax.value_and_grad(
        final_angle, has_aux=True))(jnp.asarray(OMEGA))
    assert bool(converged)
    assert np.all(np.asarray(substeps) >= 7)
    assert abs(float(wrapped(float(value) - OMEGA * 3 * DT))) < 1e-8
    assert abs(float(slope) - 3 * DT) < 1e-8


def drop(stiffness):
    return dropped_rod_scene(stiffness, H0, R_C, g=G)


def test_stiff_contact_the_step_cannot_resolve_is_reported():
    """k = 1e9 N/m^2: contact time pi sqrt(0.5/1e9) = 7e-5 s, below a tenth of the
    smallest sub-step dt/64 = 1.6e-4 s: the run stops at the impact (free fall lasts
    sqrt(2 h0/g) = 0.101 s) with the cause contact_unresolved, having never climbed."""
    result = sj.run(drop(1e9))
    assert not result.converged
    assert sj.Status(int(result.raw.status)) == sj.Status.STEP_TOO_SMALL
    assert sj.Status(int(result.raw.cause)) == sj.Status.CONTACT_UNRESOLVED
    assert abs(float(result.raw.failed_at) - np.sqrt(2 * H0 / G)) < 0.011
    assert "contact time" in result.raw.message()
    assert result.positions("rod")[..., 2].max() <= H0 + 1e-12


@pytest.mark.parametrize("stiffness", [1e4, 1e6])
def test_contact_the_sub_steps_resolve_rises_at_most_to_its_drop_height(stiffness):
    """k = 1e4 and 1e6 N/m^2 (contact times 22 and 2.2 ms): the impact is sub-stepped,
    the run converges, and after the bounce the rod rises at most to h0 (a conservative
    penalty; generalized-alpha with rho_inf = 0.9 loses a little), and at least to 0.8 h0
    (it did bounce)."""
    result = sj.run(drop(stiffness))
    assert result.converged
    assert int(np.max(result.raw.substeps)) > 1
    z = result.positions("rod")[..., 2].mean(axis=1)
    bounce = int(np.argmin(z))
    assert 0.8 * H0 < z[bounce:].max() <= H0
