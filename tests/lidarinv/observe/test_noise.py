"""Noise of recorded waveforms: mean, σ and autocorrelation from the signal-free bins,
for white, correlated and integer-quantised noise."""

import numpy as np
import pytest

import forward as fw
from lidarinv.observe import analyse, estimate_noise, noise_floor, observe, product_noise
from lidarinv.observe.noise import (
    autocorrelation,
    clipped_mean_sigma,
    filtered_sigma,
    with_smoothed_noise,
)
from lidarinv.observe.signal import smooth


@pytest.fixture(scope="module")
def forest_waveform():
    inst = fw.instrument_preset("gedi")
    stand = fw.Stand.from_arrays(x=[0.0, 4.0, -3.0], y=[0.0, -2.0, 3.0], height=[22.0, 17.0, 12.0],
                                 crown_length=[9.0, 7.0, 5.0], crown_radius=[4.0, 3.5, 3.0],
                                 favd=0.6, shape="ellipsoid")  # fmt: skip
    heights = np.arange(-100, 500) * inst.bin_height  # signal in ~1/3 of the window
    return inst, fw.WaveformSimulator(inst).simulate(stand, center=(0.0, 0.0), heights=heights)


def test_noise_of_forest_shots_is_unbiased(forest_waveform):
    """The analysis masks the signal it finds: the returns do not pull the mean or σ up."""
    inst, wf = forest_waveform
    rng = np.random.default_rng(7)
    means, sigmas = [], []
    for _ in range(60):
        obs = observe(wf, gain=1500.0, baseline=20.0, noise_sigma=1.0, rng=rng, instrument=inst)
        noise = analyse(obs).noise
        means.append(noise.mean)
        sigmas.append(noise.sigma)
    assert np.mean(means) == pytest.approx(20.0, abs=0.03)
    assert np.mean(sigmas) == pytest.approx(1.0, rel=0.03)
    assert np.std(means) < 0.1


def test_integer_counts_below_one_count_of_noise_keep_their_spread():
    """Rounded samples with σ = 0.45 counts: a median absolute deviation would be 0; the
    clipped σ is the spread of the recorded values, √(σ² + 1/12) by Sheppard."""
    rng = np.random.default_rng(3)
    samples = np.round(50.0 + 0.45 * rng.standard_normal(4000))
    assert np.median(np.abs(samples - np.median(samples))) == 0.0
    noise = estimate_noise(samples, np.ones(samples.size, bool))
    assert noise.quantum == 1.0
    assert noise.mean == pytest.approx(50.0, abs=0.03)
    assert noise.sigma == pytest.approx(np.sqrt(0.45**2 + 1 / 12), rel=0.05)


def test_autocorrelation_of_correlated_noise_and_its_smoothed_sigma():
    """Filtered noise (R(1) ≈ 0.9): the estimated R matches the filter's, and the σ of
    the smoothed noise, measured, is far above the white-noise formula."""
    rng = np.random.default_rng(5)
    kernel = np.exp(-0.5 * (np.arange(-9, 10) / 3.0) ** 2)
    exact = np.array([np.sum(kernel[: kernel.size - k] * kernel[k:]) for k in range(4)])
    exact /= exact[0]
    w = np.zeros(3000)
    obs = observe(w, heights=0.15 * np.arange(w.size), gain=1.0, baseline=10.0,
                  noise_sigma=2.0, rng=rng, noise_filter=kernel)  # fmt: skip
    free = np.ones(w.size, bool)
    noise = estimate_noise(obs.samples, free, max_lag=3)
    np.testing.assert_allclose(noise.autocorrelation, exact, atol=0.05)
    smoothed = smooth(obs.samples, 4.0)
    interior = free.copy()
    interior[:12] = interior[-12:] = False
    noise = with_smoothed_noise(noise, smoothed, interior, 4.0)
    white = product_noise(10.0, 2.0, 4.0).smoothed_sigma
    # σ of the filtered noise smoothed by a Gaussian of 4 bins: σ·sqrt(Σ_ij k_i k_j R(i−j))
    gauss = np.exp(-0.5 * (np.arange(-16, 17) / 4.0) ** 2)
    gauss /= gauss.sum()
    combined = np.convolve(gauss, kernel / np.sqrt(np.sum(kernel**2)))
    expected = 2.0 * np.sqrt(np.sum(combined**2))
    assert noise.smoothed_sigma == pytest.approx(expected, rel=0.15)
    assert noise.smoothed_sigma > 2.0 * white


def test_filtered_sigma_of_white_noise_is_the_closed_form():
    """White noise through a Gaussian of σ w bins keeps σ/√(2√π·w) of its σ."""
    for width in (2.0, 4.0, 6.5):
        radius = int(np.ceil(4 * width))
        weights = np.exp(-0.5 * (np.arange(-radius, radius + 1) / width) ** 2)
        weights /= weights.sum()
        sigma = filtered_sigma(3.0, [1.0, 0.0, 0.0], weights)
        assert sigma == pytest.approx(3.0 / np.sqrt(2 * np.sqrt(np.pi) * width), rel=1e-3)
        assert product_noise(0.0, 3.0, width).smoothed_sigma == pytest.approx(sigma, rel=1e-3)


def test_autocorrelation_skips_masked_bins():
    rng = np.random.default_rng(2)
    x = rng.standard_normal(2000)
    mask = np.ones(x.size, bool)
    mask[900:1100] = False
    x[900:1100] += 50.0  # a return, masked out
    r = autocorrelation(x, mask, 0.0, 2)
    assert r[0] == 1.0 and abs(r[1]) < 0.08 and abs(r[2]) < 0.08


def test_clipping_drops_spikes_and_never_returns_zero_spread():
    rng = np.random.default_rng(8)
    x = rng.standard_normal(1000)
    x[::100] += 30.0
    mean, sigma = clipped_mean_sigma(x)
    assert abs(mean) < 0.1 and sigma == pytest.approx(1.0, rel=0.08)
    assert clipped_mean_sigma(np.array([3.0, 3.0, 3.0, 4.0]))[1] > 0


def test_noise_floor_and_bad_noise_input():
    assert noise_floor(10.0, 2.0, 3.0) == 16.0
    with pytest.raises(ValueError):
        noise_floor(np.nan, 1.0, 3.0)
    with pytest.raises(ValueError, match="NaN"):
        estimate_noise([1.0, np.nan, 2.0])
    with pytest.raises(ValueError, match="too short"):
        estimate_noise(np.zeros(10))
    with pytest.raises(ValueError, match="signal-free bins"):
        estimate_noise(np.zeros(100), np.zeros(100, bool))
    with pytest.raises(ValueError, match="no usable noise"):
        product_noise(np.nan, 1.0)
