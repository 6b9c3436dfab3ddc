"""The local misfit check: a return the fit leaves out is found however wide the model
error's band, a fit that only reshapes a return is not, and noise alone flags a shot no
more often than the false-alarm level."""

import numpy as np
import pytest
from scipy.stats import norm

from forward.pulse import GaussianPulse
from lidarinv.inference.results.local_misfit import (
    describe_local_misfit,
    local_misfit,
    return_width_bins,
    windows,
)

BINS, SAMPLES, BASELINE = 400, 200, 10.0
AXIS = np.arange(BINS) * 0.15


def _gaussian(centre, sigma, amplitude):
    return amplitude * np.exp(-0.5 * ((np.arange(BINS) - centre) / sigma) ** 2)


def _replicates(mean, sd, rng):
    """Replicated waveforms: the mean plus white noise of per-bin sd ``sd``."""
    return mean + sd * rng.standard_normal(mean.shape)


def _check(observed, mean, sd, rng, width=10):
    mean = np.broadcast_to(mean, (SAMPLES, BINS))
    replicated = _replicates(mean, np.broadcast_to(sd, (SAMPLES, BINS)), rng)
    return local_misfit(observed, replicated, mean, np.full(SAMPLES, BASELINE), AXIS, width)


def test_windows_cover_every_bin_at_every_width():
    spans = windows(100, 7)
    widths = np.unique(spans[:, 1] - spans[:, 0])
    np.testing.assert_array_equal(widths, [7, 14, 28, 56])
    for w in widths:
        own = spans[spans[:, 1] - spans[:, 0] == w]
        covered = np.zeros(100, bool)
        for start, stop in own:
            covered[start:stop] = True
        assert covered.all()


def test_return_width_of_a_gaussian_pulse_is_its_central_95_percent():
    pulse = GaussianPulse(4.0)
    width = 2 * norm.isf(0.025) * pulse.sigma_m
    assert return_width_bins(pulse, 0.15) == int(np.ceil(width / 0.15))
    widened = 2 * norm.isf(0.025) * np.hypot(pulse.sigma_m, 1.0)
    assert return_width_bins(pulse, 0.15, 1.0) == int(np.ceil(widened / 0.15))


def test_a_canopy_return_the_fit_leaves_out_is_a_misfit_under_a_wide_model_error():
    """The fit holds the ground only; the waveform also holds a canopy return 3× stronger.
    The model error (½ of the signal per bin, its ceiling) widens the band over the
    ground; the canopy's missing energy is still found, where it lies."""
    rng = np.random.default_rng(1)
    noise = 1.0
    ground, canopy = _gaussian(60, 4, 20.0), _gaussian(250, 15, 60.0)
    fit = BASELINE + ground
    observed = BASELINE + ground + canopy + noise * rng.standard_normal(BINS)
    sd = np.sqrt(noise**2 + (0.5 * (observed - BASELINE).clip(0)) ** 2)  # η of the shot's signal
    check = _check(observed, fit, sd, rng)
    assert check["local_misfit"] and check["local_z"] > check["local_threshold"] > 0
    low, high = check["local_window_m"]
    assert low <= AXIS[250] <= high  # the window holds the missing return
    flag = describe_local_misfit(check)[0]
    assert flag.startswith("misfit") and "leaves out" in flag


def test_a_return_the_fit_only_reshapes_is_not_a_misfit():
    """The fit's return is narrower than the waveform's, the same energy: the residuals'
    sums over a return's width and wider stay within the model error's."""
    rng = np.random.default_rng(2)
    observed_return, fit_return = _gaussian(200, 6, 50.0), _gaussian(200, 4, 75.0)
    observed = BASELINE + observed_return + rng.standard_normal(BINS)
    sd = np.sqrt(1.0 + (0.5 * observed_return) ** 2)
    check = _check(observed, BASELINE + fit_return, sd, rng, width=30)
    assert not check["local_misfit"], check
    assert describe_local_misfit(check) == []


def test_noise_alone_flags_no_more_often_than_the_false_alarm_level():
    """Data drawn from the model itself: at a 1 % false alarm per shot, at most a few of
    100 shots are flagged (Bonferroni over overlapping windows is conservative)."""
    rng = np.random.default_rng(3)
    mean = BASELINE + _gaussian(200, 8, 40.0)
    flagged = sum(
        _check(mean + rng.standard_normal(BINS), mean, 1.0, rng)["local_misfit"] for _ in range(100)
    )
    assert flagged <= 3


def test_mismatched_bins_are_refused():
    with pytest.raises(ValueError, match="share their bins"):
        local_misfit(np.zeros(10), np.zeros((3, 9)), np.zeros((3, 9)), np.zeros(3), AXIS[:10], 3)
