"""Static stability: negative eigenvalues of the constrained tangent (simsoft_jax.solvers.stability).

Reference: a clamped-free straight column of square section under a dead axial
compressive tip force P. The straight shape is an equilibrium for any P; Euler's critical
loads are ``(2k-1)^2 P_cr``, ``P_cr = pi^2 EI / (4 L^2)``, each twice (two bending planes),
so the tangent has 0 negative eigenvalues below P_cr, 2 between P_cr and 9 P_cr and 4
between 9 P_cr and 25 P_cr. The block-LDL^T count is also checked against numpy's
``eigvalsh`` of the dense symmetric constrained tangent.
"""
import json
import os
import subprocess
import sys
from pathlib import Path

import jax
import numpy as np
import pytest

import simsoft_jax as sj
from simsoft_jax.solvers import stability
from simsoft_jax.physics.assembly import residual_and_tangent
from simsoft_jax.model.loads import full_loads

L, EI, ELEMENTS = 1.0, 1.0, 24
P_CR = np.pi**2 * EI / (4 * L**2)

# compiled, one program per structure (eagerly, each of their operations compiles on its
# own: about two hundred small programs)
negative_eigenvalues = jax.jit(stability.negative_eigenvalues)
full_tangent = jax.jit(lambda model, R, p: residual_and_tangent(full_loads(model), R, p, 1.0)[1])


def column(P, elements=ELEMENTS):
    stiff = {"EA": 1e5, "GAy": 1e5, "GAz": 1e5, "GJ": 1.0, "EIy": EI, "EIz": EI}
    return {"name": "column", "solver": {"kind": "static", "load_steps": 2},
            "rods": [{"name": "c", "stiffness": stiff, "elements": elements,
                      "inertia": {"rhoA": 1.0, "rhoJ": 1.0, "rhoIy": 1.0, "rhoIz": 1.0},
                      "geometry": {"kind": "straight", "length": L}}],
            "constraints": [{"kind": "clamp", "rod": "c", "node": 0}],
            "loads": [{"kind": "force", "rod": "c", "node": -1, "vector": [-P, 0.0, 0.0],
                       "frame": "world"}]}


def dense_count(model, eq):
    """Negative eigenvalues of the dense symmetric constrained tangent (numpy)."""
    diag, upper, lower = map(np.asarray, full_tangent(model, eq.R, eq.p))
    n = diag.shape[0]
    K = np.zeros((6 * n, 6 * n))
    for i in range(n):
        K[6 * i:6 * i + 6, 6 * i:6 * i + 6] = diag[i]
    for i in range(n - 1):
        K[6 * i:6 * i + 6, 6 * i + 6:6 * i + 12] = upper[i]
        K[6 * i + 6:6 * i + 12, 6 * i:6 * i + 6] = lower[i]
    return int(np.sum(np.linalg.eigvalsh(0.5 * (K + K.T)) < 0.0))


@pytest.mark.parametrize("factor, expected", [(0.5, 0), (2.0, 2), (5.0, 2), (12.0, 4)])
def test_euler_column_counts_buckling_modes(factor, expected):
    result = sj.run(column(factor * P_CR))
    assert result.converged
    tip = result.positions("c")[-1]
    assert abs(tip[1]) < 1e-12 and abs(tip[2]) < 1e-12      # still straight
    n = int(negative_eigenvalues(result.model, result.raw))
    assert n == expected
    assert dense_count(result.model, result.raw) == expected
    assert result.stability == {"negative_eigenvalues": expected, "stable": expected == 0}
    assert result.to_dict()["stability"] == result.stability


def test_discrete_critical_load_within_one_percent():
    """The count switches from 0 to 2 between 0.99 and 1.01 P_cr (24 elements)."""
    counts = [int(negative_eigenvalues(r.model, r.raw)) for r in
              (sj.run(column(f * P_CR)) for f in (0.99, 1.01))]
    assert counts == [0, 2]


def test_vmap_over_models_and_equilibria():
    """jit + vmap over a batch of (model, equilibrium) pairs of one structure."""
    results = [sj.run(column(f * P_CR)) for f in (0.5, 2.0, 12.0)]
    stack = lambda *xs: np.stack(xs)  # noqa: E731
    models = jax.tree_util.tree_map(stack, *[r.model for r in results])
    eqs = jax.tree_util.tree_map(stack, *[r.raw for r in results])
    counts = jax.jit(jax.vmap(stability.negative_eigenvalues))(models, eqs)
    assert counts.tolist() == [0, 2, 4]


def test_cli_warns_for_an_unstable_equilibrium(tmp_path):
    scene = tmp_path / "column.json"
    scene.write_text(json.dumps(column(2.0 * P_CR)))
    out = tmp_path / "out.json"
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[1])}
    cmd = [sys.executable, "-m", "simsoft_jax.cli", "run", str(scene), "-o", str(out)]
    proc = subprocess.run(cmd, capture_output=True, text=True, env=env)
    assert proc.returncode == 0, proc.stderr
    assert "warning: unstable equilibrium: 2 negative eigenvalues" in proc.stderr
    assert json.loads(out.read_text())["stability"] == {"negative_eigenvalues": 2,
                                                       "stable": False}
    proc = subprocess.run(cmd + ["--force", "--no-stability"], capture_output=True,
                          text=True, env=env)
    assert proc.returncode == 0 and "warning" not in proc.stderr
    assert json.loads(out.read_text())["stability"] is None


@pytest.mark.parametrize("factor", [0.5, 2.0])
def test_kept_tangent_is_the_tangent_at_the_equilibrium(factor):
    """The last Newton pass's tangent that sj.run counts on equals the tangent assembled
    anew at the returned equilibrium (same state, same loads), and counts the same."""
    scene = sj.Scene.from_dict(column(factor * P_CR))
    model = sj.build_model(scene)
    settings = sj.statics.settings_from_scene(scene.solver)
    eq = jax.jit(lambda m: sj.statics.equilibrium(m, sj.statics.as_traced(settings),
                                                  keep_tangent=True))(model)
    assert bool(eq.converged)
    fresh = full_tangent(model, eq.R, eq.p)
    for kept, new in zip(eq.tangent, fresh):
        scale = np.max(np.abs(np.asarray(new)))
        np.testing.assert_allclose(np.asarray(kept), np.asarray(new), rtol=0, atol=1e-12 * scale)
    assert int(negative_eigenvalues(model, eq, eq.tangent)) == \
        dense_count(model, eq) == int(negative_eigenvalues(model, eq))
