"""The observation likelihood against scipy, and what a shot brings into its problem."""

from dataclasses import replace

import numpy as np
from scipy import stats

from forward.pulse import MeasuredPulse
from lidarinv.inference import InversionSettings, build_problem
from lidarinv.inference.likelihood import WindowData, log_likelihood, model_moments
from lidarinv.inference.synthetic import SYNTHETIC_SHOTS, synthetic_shot


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
