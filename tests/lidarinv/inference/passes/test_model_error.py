"""The instrument model's error, sized by a shot's residuals: it recovers the error that made
them and stays at its least value where the noise explains them."""

import numpy as np
import pytest

from lidarinv.inference.passes.model_error import LARGEST_FLOOR, describe_floor, floor_for_residuals


def _shot(rng, eta, bins=4000):
    """Residuals of a waveform whose per-bin sd is √(σn² + (η·s)²), s a canopy-like signal."""
    signal = 40.0 * np.exp(-0.5 * ((np.arange(bins) % 400 - 200) / 60.0) ** 2)
    base = np.full(bins, 4.0)
    unit = signal**2
    return rng.normal(0.0, np.sqrt(base + eta**2 * unit)), base, unit


def test_the_error_that_made_the_residuals_is_recovered():
    residuals, base, unit = _shot(np.random.default_rng(1), 0.3)
    assert floor_for_residuals(residuals, base, unit, 0.1) == pytest.approx(0.3, rel=0.05)


def test_residuals_the_noise_explains_keep_the_least_error():
    residuals, base, unit = _shot(np.random.default_rng(2), 0.0)
    assert floor_for_residuals(residuals, base, unit, 0.1) < 0.12
    assert floor_for_residuals(0.5 * residuals, base, unit, 0.1) == 0.1


def test_the_error_is_capped_and_the_raise_is_worded():
    residuals, base, unit = _shot(np.random.default_rng(3), 5.0)
    assert floor_for_residuals(residuals, base, unit, 0.1) == LARGEST_FLOOR
    assert floor_for_residuals(np.array([]), np.array([]), np.array([]), 0.1) == 0.1
    assert "30 % of the signal per bin instead of 10 %" in describe_floor(0.3, 0.1)
