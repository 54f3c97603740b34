"""Failure status (core redesign): every solve ends with a status code and a message that
says why and where; ``throw=True`` raises; derivatives of a failed solve are NaN; the
static loop ends on a non-finite residual (it used to spin forever)."""
import json
import subprocess
import sys

import jax
import numpy as np
import pytest

import simsoft_jax as sj

BEAM = {"solver": {"kind": "static"},
        "rods": [{"name": "beam", "material": "aluminum_7075",
                  "section": {"shape": "rectangle", "width": 0.01, "height": 0.02},
                  "elements": 6, "geometry": {"kind": "straight", "length": 1.0}}],
        "constraints": [{"kind": "clamp", "rod": "beam", "node": 0}],
        "loads": [{"kind": "force", "rod": "beam", "node": -1, "vector": [0.0, 0.0, -50.0]}]}


# Too few Newton iterations for the whole load at once and no halving of the load step
HARD = sj.StaticSettings(max_iterations=2, load_steps=1, min_step_fraction=1.0)


def overflowing():
    """A tip force of 1e300 N: every residual overflows to a non-finite number."""
    return dict(BEAM, loads=[{"kind": "force", "rod": "beam", "node": -1,
                              "vector": [0.0, 0.0, -1e300]}])


def test_failed_static_solve_says_why_and_where():
    eq = sj.solve_static(sj.build_model(sj.Scene.from_dict(BEAM)), HARD)
    assert not bool(eq.converged)
    assert sj.Status(int(eq.status)) == sj.Status.STEP_TOO_SMALL
    assert sj.Status(int(eq.cause)) == sj.Status.MAX_ITERATIONS
    assert 0.0 <= float(eq.load_level) < 1.0
    message = eq.message()
    assert "failed at load level" in message and "iteration limit" in message
    with pytest.raises(sj.SolveError, match="iteration limit"):
        sj.solve_static(sj.build_model(sj.Scene.from_dict(BEAM)), HARD, throw=True)


def test_gradient_of_a_failed_static_solve_is_nan():
    model = sj.build_model(sj.Scene.from_dict(BEAM))
    grad = jax.grad(lambda k: sj.solve_static(model.replace(stiffness=model.stiffness * k),
                                              HARD).p[-1, 2])(1.0)
    assert np.isnan(float(grad))
    ok = sj.build_model(sj.Scene.from_dict(BEAM))
    grad = jax.grad(lambda k: sj.solve_static(ok.replace(stiffness=ok.stiffness * k)).p[-1, 2])(1.0)
    assert np.isfinite(float(grad)) and float(grad) > 0.0


def test_non_finite_residual_ends_with_a_status():
    """:func:`overflowing`: the solve ends (the accept/retry loop used to spin forever on a
    non-finite trial, which was neither accepted nor counted) with status NONFINITE as
    the cause."""
    eq = sj.solve_static(sj.build_model(sj.Scene.from_dict(overflowing())))
    assert not bool(eq.converged)
    assert sj.Status(int(eq.cause)) == sj.Status.NONFINITE
    assert "not finite" in eq.message()


def test_failed_rollout_status_and_nan_gradient():
    """A dynamic step that cannot converge in one Newton iteration (max_iterations = 1),
    whatever its sub-step (the differentiable rollout sub-steps like the plain one): the
    run stops at t = 0 with a status (sub-step too small) and its cause (the iteration
    limit), and its derivative is NaN; throw=True raises."""
    scene = dict(BEAM, solver={"kind": "dynamic", "t_end": 0.1, "dt": 0.01},
                 loads=[{"kind": "force", "rod": "beam", "node": -1, "vector": [0, 0, -0.5]}])
    model = sj.build_model(sj.Scene.from_dict(scene))
    settings = sj.DynamicSettings(dt=0.01, steps=5, max_iterations=1)
    traj = sj.simulate(model, settings, differentiable=True)
    assert not bool(traj.converged) and float(traj.failed_at) == 0.0
    assert sj.Status(int(traj.status)) == sj.Status.STEP_TOO_SMALL
    assert sj.Status(int(traj.cause)) == sj.Status.MAX_ITERATIONS
    assert "failed at t = 0 s" in traj.message()
    grad = jax.grad(lambda k: sj.simulate(model.replace(stiffness=model.stiffness * k), settings,
                                          differentiable=True).p[-1, -1, 2])(1.0)
    assert np.isnan(float(grad))
    with pytest.raises(sj.SolveError, match="iteration limit"):
        sj.simulate(model, settings, differentiable=True, throw=True)


def test_cli_prints_the_failure(tmp_path):
    path = tmp_path / "hard.json"
    path.write_text(json.dumps(overflowing()))
    out = tmp_path / "out.json"
    proc = subprocess.run([sys.executable, "-m", "simsoft_jax.cli", "run", str(path), "-o",
                           str(out)], capture_output=True, text=True, timeout=600)
    assert proc.returncode == 1, proc.stderr
    assert "failed at load level" in proc.stderr and "not finite" in proc.stderr
    result = json.loads(out.read_text())
    assert result["converged"] is False and result["status"] == "step_too_small"
    assert "not finite" in result["message"]
