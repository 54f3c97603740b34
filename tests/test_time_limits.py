"""Time (issue 17): dynamic runs end exactly at t_end and save it, whatever t_end/dt and
save_every; time laws with features shorter than dt are warned about; step counts above
solver.max_steps need an explicit opt-in; tolerance >= 1 is rejected.

References, two rigid motions of a free rod that the Lie-group generalized-alpha scheme
reproduces to round-off at any step size, so the saved states are compared with the
closed form at 1e-12 (a run ending at 0.09 s instead of 0.1 s misses by millimetres):
free fall under gravity (every node at p0 - g t^2 / 2 along world z, frames unchanged;
the Newmark update is exact for constant acceleration) and a spin about the rod's own
axis without gravity (positions unchanged, frames turned by R_x(omega t); q exp(h v) is
the exact flow for constant body velocity, and an axisymmetric spin has no gyroscopic
moment).
"""
import warnings

import numpy as np
import pytest

import simsoft_jax as sj
from conftest import rot_x

G, OMEGA = 9.81, 3.0


def falling_spinner(t_end, dt, save_every=1, spin=False, **solver):
    """Free fall (spin False) or a spin about the axis without gravity (spin True)."""
    d = {
        "solver": {"kind": "dynamic", "t_end": t_end, "dt": dt, "save_every": save_every,
                   **solver},
        "gravity": {"vector": [0.0, 0.0, -G]},
        "rods": [{"name": "rod", "elements": 2, "geometry": {"kind": "straight", "length": 0.3},
                  "stiffness": {"EA": 1e4, "GAy": 1e4, "GAz": 1e4, "GJ": 1.0, "EIy": 1.0,
                                "EIz": 1.0},
                  "inertia": {"rhoA": 0.1, "rhoJ": 2e-4, "rhoIy": 1e-4, "rhoIz": 1e-4}}],
    }
    if spin:
        del d["gravity"]
        d["initial_velocity"] = [{"rod": "rod", "angular": [OMEGA, 0.0, 0.0]}]
    return d


def check_exact_motion(result, spin):
    p0 = np.array([[0.0, 0.0, 0.0], [0.15, 0.0, 0.0], [0.3, 0.0, 0.0]])
    for t, p, R in zip(result.time, result.positions("rod"), result.rotations("rod")):
        drop = 0.0 if spin else -0.5 * G * t * t
        turn = rot_x(OMEGA * t) if spin else np.eye(3)
        np.testing.assert_allclose(p, p0 + [0.0, 0.0, drop], rtol=0, atol=1e-12)
        np.testing.assert_allclose(R, np.broadcast_to(turn, R.shape), rtol=0, atol=1e-12)


@pytest.mark.parametrize("dt, save_every, times", [
    (0.03, 1, [0.0, 0.03, 0.06, 0.09, 0.1]),      # t_end/dt = 3.33
    (0.01, 3, [0.0, 0.03, 0.06, 0.09, 0.1]),      # 10 steps, saves every 3
    (0.025, 2, [0.0, 0.05, 0.1]),                 # divides evenly: no closing chunk
])
def test_runs_end_exactly_at_t_end(dt, save_every, times):
    r = sj.run(falling_spinner(0.1, dt, save_every))
    assert r.converged and r.status == "converged"
    assert r.time[-1] == 0.1                      # exactly
    np.testing.assert_allclose(r.time, times, rtol=0, atol=1e-15)
    check_exact_motion(r, spin=False)
    # the old behaviour (stop at 0.09 s) would put the tip 9.3 mm too high
    assert r.positions("rod")[-1, -1, 2] == pytest.approx(-0.5 * G * 0.01, abs=1e-12)


def test_spin_ends_at_t_end_with_the_exact_angle():
    """t_end 0.1, dt 0.03: the frames end turned by omega t_end = 0.3 rad (0.27 rad if the
    run stopped at 0.09 s)."""
    r = sj.run(falling_spinner(0.1, 0.03, spin=True))
    assert r.converged and r.time[-1] == 0.1
    check_exact_motion(r, spin=True)
    R_tip = r.rotations("rod")[-1, -1]
    assert np.arctan2(R_tip[2, 1], R_tip[1, 1]) == pytest.approx(0.3, abs=1e-12)


def test_step_count_limit_needs_opt_in():
    with pytest.raises(ValueError, match=r"^solver\.dt: t_end / dt = 1e\+07 time steps, "
                                         r"more than solver\.max_steps \(1000000\)"):
        sj.Scene.from_dict(falling_spinner(1.0, 1e-7))
    scene = sj.Scene.from_dict(falling_spinner(1.0, 1e-7, max_steps=10**7))
    assert scene.solver.dt == 1e-7
    with pytest.raises(ValueError, match=r"^solver\.max_steps: must be >= 1"):
        sj.Scene.from_dict(falling_spinner(1.0, 0.1, max_steps=0))


@pytest.mark.parametrize("tolerance", [1.0, 10.0])
def test_tolerance_must_be_below_one(tolerance):
    d = falling_spinner(0.1, 0.01, tolerance=tolerance)
    with pytest.raises(ValueError, match=r"^solver\.tolerance: must be < 1"):
        sj.Scene.from_dict(d)


@pytest.mark.parametrize("profile, key", [
    ({"kind": "ramp", "t0": 0.02, "t1": 0.025}, r"loads\[0\]\.profile: rises in t1 - t0 = 0.005 s"),
    ({"kind": "smoothstep", "t1": 0.001}, r"loads\[0\]\.profile: rises in t1 - t0 = 0.001 s"),
    ({"kind": "table", "t": [0.0, 0.05, 0.052, 0.054], "scale": [0.0, 0.0, 1.0, 0.0]},
     r"loads\[0\]\.profile\.t: samples 0.002 s apart"),
])
def test_time_law_features_shorter_than_dt_warn(profile, key):
    d = falling_spinner(0.1, 0.01)
    d["loads"] = [{"kind": "force", "rod": "rod", "node": -1, "vector": [0.0, 1.0, 0.0],
                   "profile": profile}]
    with pytest.warns(UserWarning, match="^" + key) as record:
        sj.Scene.from_dict(d)
    assert len(record) == 1 and "solver.dt = 0.01 s" in str(record[0].message)
    d["solver"]["dt"] = 0.001                      # resolved: no warning
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        sj.Scene.from_dict(d)


def test_drive_samples_closer_than_dt_warn():
    d = falling_spinner(0.1, 0.01)
    d["constraints"] = [{"kind": "drive", "rod": "rod", "node": 0, "times": [0.0, 0.004],
                         "displacement": [[0, 0, 0], [0, 0, 0.001]]}]
    with pytest.warns(UserWarning, match=r"^constraints\[0\]\.times: samples 0.004 s apart"):
        sj.Scene.from_dict(d)


def test_drive_samples_spaced_by_dt_up_to_round_off_do_not_warn():
    d = falling_spinner(0.1, 0.01)
    times = [k * 0.01 for k in range(11)]
    gaps = [b - a for a, b in zip(times, times[1:])]
    assert min(gaps) < 0.01            # the round-off the check must tolerate
    d["constraints"] = [{"kind": "drive", "rod": "rod", "node": 0, "times": times,
                         "displacement": [[0.0, 0.0, 1e-4 * k] for k in range(11)]}]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        sj.Scene.from_dict(d)
