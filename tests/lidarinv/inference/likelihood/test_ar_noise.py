"""Autoregressive noise: Yule–Walker fit, exact whitening and log-determinant against the
dense Toeplitz covariance."""

import numpy as np
import pytest
from scipy.signal import lfilter

from lidarinv.inference.likelihood.ar_noise import AutoregressiveNoise, levinson_durbin
from lidarinv.observe.noise import autocorrelation


def _ar_series(phi, n, rng):
    white = rng.standard_normal(n + 500)
    return lfilter([1.0], np.concatenate([[1.0], -np.asarray(phi)]), white)[500:]


@pytest.mark.parametrize("phi", [[0.6], [1.2, -0.5], [1.5, -0.9, 0.3]])
def test_whitening_is_the_inverse_cholesky_factor(phi):
    rng = np.random.default_rng(1)
    x = _ar_series(phi, 20000, rng)
    r = autocorrelation(x, np.ones(x.size, bool), x.mean(), 12)
    noise = AutoregressiveNoise.fit(r, x.size)
    n = 40
    sigma = noise.covariance(n)
    inverse_factor = noise.whiten(np.eye(n)).T  # column i is L⁻¹ e_i
    np.testing.assert_allclose(inverse_factor @ sigma @ inverse_factor.T, np.eye(n), atol=1e-9)
    assert np.allclose(np.triu(inverse_factor, 1), 0.0)
    assert noise.log_det(n) == pytest.approx(np.linalg.slogdet(sigma)[1], rel=1e-9)


def test_fit_recovers_the_process_and_its_order():
    rng = np.random.default_rng(2)
    for phi in ([0.7], [1.2, -0.5]):
        x = _ar_series(phi, 50000, rng)
        r = autocorrelation(x, np.ones(x.size, bool), x.mean(), 12)
        noise = AutoregressiveNoise.fit(r, x.size)
        assert noise.order >= len(phi)
        np.testing.assert_allclose(noise.coefficients[: len(phi)], phi, atol=0.03)
        assert np.all(np.abs(noise.coefficients[len(phi) :]) < 0.03)
    white = rng.standard_normal(3000)
    r = autocorrelation(white, np.ones(white.size, bool), 0.0, 12)
    assert AutoregressiveNoise.fit(r, white.size).order <= 1


def test_whitened_ar_noise_is_white():
    rng = np.random.default_rng(3)
    x = _ar_series([1.2, -0.5], 30000, rng)
    x /= x.std()
    r = autocorrelation(x, np.ones(x.size, bool), 0.0, 16)
    noise = AutoregressiveNoise.fit(r, x.size)
    z = noise.whiten(x)
    assert z.std() == pytest.approx(1.0, rel=0.03)
    lag = [np.mean(z[:-k] * z[k:]) / z.var() for k in (1, 2, 3)]
    assert np.all(np.abs(lag) < 0.03)
    # the AR model reproduces the measured autocorrelation
    np.testing.assert_allclose(noise.autocorrelation(8), r[:8], atol=0.03)


def test_bad_autocorrelations_are_refused():
    with pytest.raises(ValueError, match="R\\(0\\) = 1"):
        AutoregressiveNoise.fit([0.5, 0.2], 100)
    with pytest.raises(ValueError, match="positive definite"):
        levinson_durbin([1.0, 1.0, 1.0], 2)
    assert AutoregressiveNoise.fit([1.0], 100).order == 0


def test_the_ar1_with_the_integrated_time_of_gedi_like_noise():
    """Its zero-frequency spectral density is the measured one: the variance of a long
    mean of the noise is the same under the model as in the data."""
    from lidarinv.inference.likelihood.ar_noise import integrated_time

    rng = np.random.default_rng(4)
    kernel = np.exp(-0.5 * (np.arange(-8, 9) / 2.0) ** 2)
    x = np.convolve(rng.standard_normal(200000), kernel / np.sqrt(np.sum(kernel**2)), "valid")
    r = autocorrelation(x, np.ones(x.size, bool), 0.0, 24)
    noise = AutoregressiveNoise.matching_integrated_time(r)
    assert noise.order == 1 and noise.integrated_time == pytest.approx(integrated_time(r))
    block = 200  # variance of 200-bin means: σ²·τ/200 for a long block
    means = x[: x.size // block * block].reshape(-1, block).mean(axis=1)
    model = noise.covariance(block).sum() / block**2
    assert means.var() == pytest.approx(model, rel=0.15)
    assert AutoregressiveNoise.matching_integrated_time([1.0, -0.2]).order == 0
