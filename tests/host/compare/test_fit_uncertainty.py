"""The identification's standard errors hold up when residuals are correlated in time (a smooth model mismatch)."""

from __future__ import annotations

import numpy as np

from ropecam.host.compare.identify import std_from_jacobian


def _slope_fits(rho: float, trials: int, seed: int = 1) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Fit y = a + b t to samples of 4 points x 2 coordinates at 120 times whose errors are AR(1) in time with
    lag-one correlation `rho` and shared by the points of one time; returns (b estimates, textbook SE, HAC SE)."""
    rng = np.random.default_rng(seed)
    times = np.repeat(np.arange(120), 8)
    t = times / 119.0 - 0.5
    jacobian = np.column_stack([np.ones_like(t), t])
    estimates, textbook, robust = [], [], []
    for _ in range(trials):
        shock = rng.normal(size=120)
        series = np.empty(120)
        series[0] = shock[0]
        for i in range(1, 120):
            series[i] = rho * series[i - 1] + np.sqrt(1 - rho * rho) * shock[i]
        noise = series[times] + 0.3 * rng.normal(size=times.size)
        coef, *_ = np.linalg.lstsq(jacobian, noise, rcond=None)
        residuals = noise - jacobian @ coef
        estimates.append(coef[1])
        sigma2 = residuals @ residuals / (residuals.size - 2)
        textbook.append(np.sqrt(sigma2 * np.linalg.inv(jacobian.T @ jacobian)[1, 1]))
        robust.append(std_from_jacobian(jacobian, residuals, times)[1])
    return np.array(estimates), np.array(textbook), np.array(robust)


def test_correlated_residuals_widen_the_standard_error_to_the_true_scatter() -> None:
    estimates, textbook, robust = _slope_fits(rho=0.8, trials=300)
    scatter = estimates.std()
    # The textbook value treats 960 residuals as independent: several times too small.
    assert np.median(textbook) < 0.3 * scatter
    # The HAC sandwich is close to the actual scatter of the estimates (prewhitened kernel estimators run a little low).
    assert 0.7 * scatter < np.median(robust) < 1.3 * scatter


def test_residuals_uncorrelated_in_time_give_the_true_scatter_too() -> None:
    estimates, textbook, robust = _slope_fits(rho=0.0, trials=200)
    assert 0.8 * estimates.std() < np.median(robust) < 1.3 * estimates.std()
    assert np.all(robust >= textbook * (1 - 1e-12))


def test_singular_jacobian_gives_infinite_errors() -> None:
    jacobian = np.ones((10, 2))
    assert np.all(np.isinf(std_from_jacobian(jacobian, np.zeros(10), np.arange(10))))
