"""The instrument model's error, sized by a shot's residuals: it recovers the error that made
them and stays at its least value where the noise explains them."""

import numpy as np
import pytest

from lidarinv.inference.passes.model_error import (
    MISFIT_FLAG,
    MODEL_ERROR_CEILING,
    bounded_floor,
    describe_floor,
    describe_misfit,
    exceeds_ceiling,
    floor_for_residuals,
)


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


def test_the_need_is_measured_beyond_the_ceiling_and_the_raise_is_worded():
    residuals, base, unit = _shot(np.random.default_rng(3), 5.0)
    assert floor_for_residuals(residuals, base, unit, 0.1) == pytest.approx(5.0, rel=0.05)
    assert floor_for_residuals(np.array([]), np.array([]), np.array([]), 0.1) == 0.1
    assert "30 % of the signal per bin instead of 10 %" in describe_floor(0.3, 0.1)


def test_a_fit_that_needs_more_than_the_ceiling_is_a_misfit():
    """Residuals made by an error of 90 % of the signal need more than the instrument
    model may lack: the likelihood keeps the ceiling and the shot is flagged a misfit."""
    residuals, base, unit = _shot(np.random.default_rng(4), 0.9)
    needed = floor_for_residuals(residuals, base, unit, 0.1)
    assert needed > MODEL_ERROR_CEILING
    assert bounded_floor(needed, 0.1) == MODEL_ERROR_CEILING
    assert exceeds_ceiling(needed, 0.1)
    flag = describe_misfit(needed)
    assert flag.startswith(MISFIT_FLAG) and "90 %" in flag and "50 %" in flag


def test_an_error_within_the_ceiling_is_taken_whole_and_not_a_misfit():
    residuals, base, unit = _shot(np.random.default_rng(5), 0.3)
    needed = floor_for_residuals(residuals, base, unit, 0.1)
    assert bounded_floor(needed, 0.1) == needed and not exceeds_ceiling(needed, 0.1)


def test_residuals_where_the_model_predicts_no_signal_exceed_any_error():
    """Signal recorded where the shot's own signal is nil (a return the stand model left
    out, measured against the observed signal, cannot be hidden by a fraction of it)."""
    rng = np.random.default_rng(6)
    residuals, base, unit = _shot(rng, 0.0)
    unit[:800] = 0.0
    residuals[:800] += 30.0  # a missed return, many noise σ, where ŝ = 0
    needed = floor_for_residuals(residuals, base, unit, 0.1)
    assert needed == np.inf and exceeds_ceiling(needed, 0.1)
    assert "more than any model error" in describe_misfit(needed)
