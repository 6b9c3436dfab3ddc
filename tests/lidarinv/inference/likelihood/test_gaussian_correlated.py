"""The likelihood with correlated read noise (whitened AR noise) against the dense
multivariate-normal reference, with and without a discrepancy covariance, and with the
gain integrated out; where it cannot apply, the noise stays white and it says why."""

import numpy as np
import pytest
from scipy.integrate import quad

from lidarinv.inference.likelihood.ar_noise import AutoregressiveNoise
from lidarinv.inference.likelihood.gaussian import ShotLikelihood
from lidarinv.inference.model.priors import LogUniform
from lidarinv.inference.shot import WindowData
from lidarinv.testing import dense_log_likelihood

BINS = 40


def _window(rng, noise, sigma=1.5, censored=None):
    axis = np.arange(BINS) * 0.15
    signal = np.exp(-0.5 * ((axis - 3.0) / 0.6) ** 2) * 0.02
    correlated = np.linalg.cholesky(noise.covariance(BINS)) @ rng.standard_normal(BINS)
    samples = 40.0 + 2000.0 * signal + sigma * correlated
    data = WindowData(axis=axis, samples=samples,
                      censored=np.zeros(BINS, bool) if censored is None else censored,
                      saturated=np.zeros(BINS, bool), floor=41.0)  # fmt: skip
    return data, signal


def _rows(signal, n=5):
    grid = np.linspace(0.8, 1.2, n)
    return (np.outer(grid, signal), {"gain": 2000.0 * grid[::-1], "baseline": 40.0 + grid - 1,
            "noise_sigma": 1.5 * grid})  # fmt: skip


@pytest.mark.parametrize("phi", [0.4, 0.8])
@pytest.mark.parametrize("discrepancy", ["none", "diagonal", "covariance"])
def test_whitened_likelihood_is_the_dense_multivariate_normal(phi, discrepancy):
    rng = np.random.default_rng(3)
    noise = AutoregressiveNoise(np.array([phi]), 1 - phi**2, np.array([1.0, phi]))
    data, signal = _window(rng, noise)
    fixed = covariance = None
    if discrepancy == "diagonal":
        fixed = (0.3 * 2000.0 * signal) ** 2
        covariance = np.diag(fixed)
    elif discrepancy == "covariance":
        factor = rng.standard_normal((BINS, 6)) * (2000.0 * signal)[:, None] * 0.1
        fixed = covariance = factor @ factor.T
    like = ShotLikelihood(data, fixed_discrepancy=fixed, noise_correlation=noise)
    assert like.whitening is noise and like.correlation_obstacle is None
    rows, values = _rows(signal)
    fast, _ = like.log_likelihood(rows, values)
    reference = dense_log_likelihood(data.samples, rows, values["gain"], values["baseline"],
                                     values["noise_sigma"], noise.covariance(BINS), covariance)  # fmt: skip
    np.testing.assert_allclose(fast, reference, rtol=1e-7)  # an eigendecomposition apart


def test_whitened_marginal_over_the_gain_is_the_dense_integral():
    rng = np.random.default_rng(4)
    noise = AutoregressiveNoise(np.array([0.7]), 1 - 0.49, np.array([1.0, 0.7]))
    data, signal = _window(rng, noise)
    prior = LogUniform(500.0, 8000.0)
    like = ShotLikelihood(data, gain_prior=prior, noise_correlation=noise,
                          fixed_discrepancy=np.full(BINS, 0.5))  # fmt: skip
    rows = np.tile(signal, (1, 1))
    values = {"baseline": np.array([40.2]), "noise_sigma": np.array([1.4])}
    fast, _ = like.log_likelihood(rows, values)
    correlation = noise.covariance(BINS)

    def integrand(a, shift):
        dense = dense_log_likelihood(data.samples, rows, [a], values["baseline"],
                                     values["noise_sigma"], correlation, np.diag(np.full(BINS, 0.5)))  # fmt: skip
        return np.exp(dense[0] + prior.log_pdf(a) - shift)

    shift = dense_log_likelihood(data.samples, rows, [2000.0], values["baseline"], values["noise_sigma"],
                                 correlation, np.diag(np.full(BINS, 0.5)))[0]  # fmt: skip
    value = quad(integrand, 500.0, 8000.0, args=(shift,), points=[2000.0], limit=400, epsrel=1e-11)[
        0
    ]
    assert fast[0] == pytest.approx(np.log(value) + shift, abs=1e-6)


def test_correlated_noise_falls_back_to_white_where_it_cannot_apply():
    rng = np.random.default_rng(5)
    noise = AutoregressiveNoise(np.array([0.6]), 1 - 0.36, np.array([1.0, 0.6]))
    censored = np.zeros(BINS, bool)
    censored[:3] = True
    data, _signal = _window(rng, noise, censored=censored)
    like = ShotLikelihood(data, noise_correlation=noise)
    assert like.whitening is None and "censored" in like.correlation_obstacle
    data, _ = _window(rng, noise)
    like = ShotLikelihood(data, discrepancy=0.2, noise_correlation=noise)
    assert like.whitening is None and "proportional" in like.correlation_obstacle
    assert ShotLikelihood(data, noise_correlation=AutoregressiveNoise.white()).whitening is None


def test_correlated_noise_widens_what_the_data_say_about_the_baseline():
    """The baseline's precision from pure-noise bins: white noise overstates it by the
    integrated autocorrelation time."""
    rng = np.random.default_rng(6)
    noise = AutoregressiveNoise(np.array([0.8]), 1 - 0.64, np.array([1.0, 0.8]))
    data, _signal = _window(rng, noise)
    rows = np.zeros((41, BINS))
    grid = np.linspace(39.0, 41.0, 41)
    values = {"gain": np.ones(41), "baseline": grid, "noise_sigma": np.full(41, 1.5)}
    curvature = {}
    for name, correlation in (("white", None), ("ar", noise)):
        like, _ = ShotLikelihood(data, noise_correlation=correlation).log_likelihood(rows, values)
        curvature[name] = -np.polyfit(grid, like, 2)[0] * 2
    ratio = curvature["white"] / curvature["ar"]
    tau = (1 + 0.8) / (1 - 0.8)
    assert ratio == pytest.approx(tau, rel=0.3)  # edge effects of a 40-bin window
