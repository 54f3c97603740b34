"""simsoft_jax.analysis.advisor: power-law fits and suggested resolutions on synthetic
work-precision data with known exact laws (independent reference: the closed forms)."""
import numpy as np
import pytest

from simsoft_jax.analysis import advisor


def test_fit_power_law_recovers_an_exact_law():
    n = np.array([2, 4, 8, 16, 32])
    law = advisor.fit_power_law(n, 0.3 * n ** -2.0)
    assert law.exponent == pytest.approx(-2.0, abs=1e-12)
    assert law.coefficient == pytest.approx(0.3, rel=1e-12)
    assert (law.x_min, law.x_max) == (2, 32)
    assert law(10) == pytest.approx(0.003, rel=1e-12)


def test_fit_power_law_needs_two_positive_errors():
    with pytest.raises(ValueError, match="two points"):
        advisor.fit_power_law([4, 8], [1e-3, 0.0])


def test_suggest_elements_is_the_fewest_meeting_the_target():
    n = np.array([2, 4, 8, 16, 32])
    s = advisor.suggest_elements(n, 0.3 * n ** -2.0, target=1e-3)
    # 0.3 / n^2 <= 1e-3  <=>  n >= sqrt(300) = 17.3, and the grid holds every integer here
    assert s.elements == 18 and s.dt is None
    assert s.predicted_error <= 1e-3 and not s.extrapolated
    assert advisor.suggest_elements(n, 0.3 * n ** -2.0, target=1e-6).extrapolated


def test_suggest_resolution_minimizes_cost_under_the_error_budget():
    n = np.array([5, 10, 20, 40])
    dts = np.array([0.04, 0.02, 0.01, 0.005])
    space = lambda k: 0.5 * k ** -2.0  # noqa: E731
    time = lambda h: 20.0 * h ** 2.0  # noqa: E731
    target = 2e-3
    s = advisor.suggest_resolution(n, space(n), dts, time(dts), target)
    assert s.predicted_error == pytest.approx(space(s.elements) + time(s.dt), rel=1e-9)
    assert s.predicted_error <= target
    assert s.relative_cost == pytest.approx(s.elements / s.dt)
    # brute force over the same grid: nothing cheaper meets the target
    grid_dt = 0.04 / 2.0 ** np.arange(13)
    for k in range(1, 1001):
        for h in grid_dt:
            if space(k) + time(h) <= target:
                assert k / h >= s.relative_cost * (1 - 1e-12)


def test_suggest_resolution_returns_the_most_accurate_pair_when_unreachable():
    n = np.array([5, 10, 20])
    dts = np.array([0.04, 0.02, 0.01])
    s = advisor.suggest_resolution(n, 1e-2 * n ** -1.0, dts, 1e-3 * dts, target=1e-9)
    assert s.predicted_error > 1e-9 and s.extrapolated
    assert (s.elements, s.dt) == (1000, 0.04 / 2.0**12)


def test_data_without_convergence_is_refused():
    n = np.array([5, 10, 20])
    dts = np.array([0.04, 0.02, 0.01])
    with pytest.raises(ValueError, match="dt: the error does not fall"):
        advisor.suggest_resolution(n, n ** -2.0, dts, [2.5e-2, 2.7e-2, 1.7e-2], 1e-3)
    with pytest.raises(ValueError, match="elements: the error does not fall"):
        advisor.suggest_elements(n, [1e-2, 1.1e-2, 0.9e-2], 1e-3)
