"""The cosseratbench adapter (the ``bench`` extra), scored by the benchmark's own metrics
against its analytic references: Euler-Bernoulli tip deflection for the cantilever, the
linear hanging-cable mode (computed by cosseratbench) for the pendulum. Skipped when
cosseratbench is not installed."""
import importlib
import sys

import pytest

cosseratbench = pytest.importorskip("cosseratbench")

from cosseratbench import registry  # noqa: E402

from conftest import REPO_ROOT  # noqa: E402
from simsoft_jax.apps.cosseratbench_solver import SimsoftJaxSolver  # noqa: E402

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib


def test_entry_point_names_the_adapter_and_it_is_a_solver():
    project = tomllib.loads((REPO_ROOT / "pyproject.toml").read_text())["project"]
    target = project["entry-points"]["cosseratbench.solvers"]["simsoft_jax"]
    module, _, name = target.partition(":")
    solver = getattr(importlib.import_module(module), name)()
    assert isinstance(solver, cosseratbench.Solver) and solver.name == "simsoft_jax"
    assert "cosseratbench" in " ".join(project["optional-dependencies"]["bench"])
    # contact is not modelled, so the contact experiments are reported unsupported
    capstan = cosseratbench.run(registry.load_experiment("capstan"), solver)
    assert capstan.outcome == "unsupported"


def test_cantilever_tip_deflection_within_1e_3_at_20_elements():
    """The reference neglects shear (+1.0e-3 of the deflection here, ``3 EI / (k G A L^2)``)
    and geometric nonlinearity (about -4e-4), so 1e-3 is as close as it can judge. Measured
    3.2e-5 at 20 elements (the elements' error, -6e-4, and those two nearly cancel there;
    the converged value is 5.9e-4, see docs/cosseratbench.md). A static solve: the run has
    settled exactly."""
    result = cosseratbench.run(registry.load_experiment("cantilever"), SimsoftJaxSolver(),
                               n_elements=20)
    assert result.outcome == "completed"
    assert result.metrics["tip_deflection_error"] < 1e-3
    assert result.metrics["settling_residual"] == 0.0


@pytest.mark.slow
def test_pendulum_period_and_amplitude_at_10_elements():
    """Measured: period error 1.4e-4, amplitude change 1.3e-6 (no damping is added; the
    benchmark bounds a meaningful period error near 2e-5)."""
    result = cosseratbench.run(registry.load_experiment("pendulum"), SimsoftJaxSolver(),
                               n_elements=10)
    assert result.outcome == "completed"
    assert result.metrics["period_error"] < 5e-4
    assert abs(result.metrics["amplitude_change"]) < 1e-4
