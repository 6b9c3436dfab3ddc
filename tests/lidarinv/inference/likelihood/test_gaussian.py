"""The observation likelihood against scipy, and what a shot brings into its problem."""

from dataclasses import replace

import numpy as np
import pytest
from scipy import stats

from forward.pulse import MeasuredPulse
from lidarinv.examples import SYNTHETIC_SHOTS, synthetic_shot
from lidarinv.inference import InversionSettings, WindowData, build_problem
from lidarinv.inference.likelihood.gaussian import model_moments, row_log_likelihood
from lidarinv.inference.model.waveform import relative_heights
from lidarinv.testing import (
    assert_fast_path,
    log_likelihood,
    relative_heights_reference,
    row_log_likelihood_reference,
)


def test_gaussian_censored_and_saturated_terms_match_scipy():
    y = np.array([1.0, 2.5, 0.2, 0.2, 9.0])
    censored = np.array([False, False, True, True, False])
    saturated = np.array([False, False, False, False, True])
    data = WindowData(np.arange(5.0), y, censored, saturated, floor=0.2, saturation=9.0)
    signal = np.array([[0.5, 1.0, 0.1, 0.0, 4.0]])
    mean, variance = model_moments(signal, np.array([2.0]), np.array([0.1]), np.array([0.4]), 0.3)
    sd = np.sqrt(variance[0])
    expected = (
        stats.norm.logpdf(y[:2], mean[0, :2], sd[:2]).sum()
        + stats.norm.logcdf(0.2, mean[0, 2:4], sd[2:4]).sum()
        + stats.norm.logsf(9.0, mean[0, 4], sd[4])
    )
    np.testing.assert_allclose(log_likelihood(data, mean, variance)[0], expected, rtol=1e-12)
    # shot noise: variance σn² + g·a·W
    np.testing.assert_allclose(variance[0], 0.16 + 0.3 * 2.0 * signal[0])


def test_far_censored_tail_stays_finite():
    data = WindowData(np.arange(3.0), np.zeros(3), np.ones(3, bool), np.zeros(3, bool), floor=0.0)
    mean = np.full((1, 3), 60.0)  # 60 σ above the floor
    value = log_likelihood(data, mean, np.ones((1, 3)))[0]
    assert np.isfinite(value) and value < -1000


def test_measured_transmit_pulse_replaces_the_preset():
    obs = synthetic_shot(SYNTHETIC_SHOTS["gedi-mixed"], np.random.default_rng(3), explicit=False)
    t = np.arange(-40.0, 41.0)
    pulse = 5.0 + 100.0 * np.exp(-0.5 * (t / 6.4) ** 2)
    with_pulse = replace(obs, pulse=pulse, pulse_ns=1.0)
    assert isinstance(build_problem(with_pulse).instrument.pulse, MeasuredPulse)
    settings = InversionSettings(use_measured_pulse=False)
    assert not isinstance(build_problem(with_pulse, settings).instrument.pulse, MeasuredPulse)


def test_ground_prior_centres_on_the_detected_peak_and_window_holds_empty_bins():
    obs = synthetic_shot(SYNTHETIC_SHOTS["gedi-mixed"], np.random.default_rng(3), explicit=False)
    problem = build_problem(obs)
    prior = problem.space.by_name["ground_elevation"].prior
    assert abs(prior.mean - problem.analysis.ground) < 1e-12
    assert abs(prior.mean - 0.0) < 0.2
    top = problem.space.by_name["top_height"].prior.upper
    assert problem.window.axis[-1] > problem.analysis.signal_start + 5.0
    assert top < problem.window.axis[-1] - prior.mean


def test_ground_prior_is_a_bin_wide_unless_set():
    """Low vegetation pulls the detected peak up by about a bin, so the prior around it
    is at least a bin wide, not the peak fit's uncertainty (a fraction of a bin); an
    explicit width is used as given, and a non-positive one is refused."""
    obs = synthetic_shot(SYNTHETIC_SHOTS["gedi-mixed"], np.random.default_rng(3), explicit=False)
    problem = build_problem(obs)
    prior = problem.space.by_name["ground_elevation"].prior
    assert problem.analysis.ground_uncertainty < obs.bin_size
    assert prior.sd == obs.bin_size
    narrow = build_problem(obs, InversionSettings(ground_prior_sd_m=0.075))
    assert narrow.space.by_name["ground_elevation"].prior.sd == 0.075
    with pytest.raises(ValueError, match="ground_prior_sd_m must be positive"):
        build_problem(obs, InversionSettings(ground_prior_sd_m=0.0))


def _window(rng, bins=40):
    y = rng.normal(5.0, 2.0, bins)
    censored = np.zeros(bins, bool)
    censored[:5] = True  # floored
    saturated = np.zeros(bins, bool)
    saturated[-2:] = True
    y[censored], y[saturated] = 1.0, 30.0
    return WindowData(np.arange(bins) * 0.15, y, censored, saturated, floor=1.0, saturation=30.0)


def test_fast_likelihood_matches_the_numpy_reference_with_either_discrepancy():
    rng = np.random.default_rng(7)
    data = _window(rng)
    signal = rng.gamma(2.0, 1.0, (9, data.axis.size)) * (rng.random((9, data.axis.size)) > 0.3)
    gain, baseline, sigma = rng.uniform(1, 4, 9), rng.uniform(-1, 1, 9), rng.uniform(0.5, 2, 9)
    fixed = rng.uniform(0.0, 3.0, data.axis.size)
    for scale, extra_fixed in ((0.0, fixed), (0.25, None)):
        extra = fixed if extra_fixed is not None else (scale * gain[:, None] * signal) ** 2
        mean, variance = model_moments(signal, gain, baseline, sigma, 0.4, extra)
        args = (data, signal, gain, baseline, sigma, 0.4, scale, extra_fixed)
        reference = assert_fast_path(row_log_likelihood, row_log_likelihood_reference, *args)
        np.testing.assert_allclose(reference, log_likelihood(data, mean, variance), rtol=1e-12)


def test_fast_relative_heights_match_the_rh_of_record():
    """The compiled RH of model waveforms against lidarinv.observe.metrics.rh_metrics, row
    by row (NaN where a row has no energy)."""
    rng = np.random.default_rng(8)
    axis = 100.0 + 0.15 * np.arange(60)
    signal = rng.gamma(1.5, 1.0, (12, axis.size)) * (rng.random((12, axis.size)) > 0.5)
    # empty end bins, as every inversion window has (its margins): there rh_metrics' RH
    # runs from the lowest bin's centre to the highest's, a clip that never binds
    signal[:, :2] = signal[:, -2:] = 0.0
    signal[0] = 0.0  # no energy: NaN
    signal[1, :] = -1.0  # only negative samples count as none
    signal[2, :] = 0.0
    signal[2, 30] = 4.0  # one bin holds it all
    ground = rng.uniform(100.0, 102.0, 12)
    levels = (0.25, 0.5, 0.98)
    reference = assert_fast_path(
        relative_heights, relative_heights_reference, signal, axis, ground, levels, atol=1e-10
    )
    assert np.all(np.isnan(reference[:2]))
