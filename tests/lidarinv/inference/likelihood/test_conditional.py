"""The footprint's discrepancy drawn given the data against the dense Gaussian
conditional, in every basis the likelihood takes (white or whitened noise, a per-bin
variance or a covariance), and where it cannot be drawn."""

import numpy as np
import pytest

from lidarinv.inference.likelihood.ar_noise import AutoregressiveNoise
from lidarinv.inference.likelihood.conditional import (
    conditioning_obstacle,
    discrepancy_given_data,
)
from lidarinv.inference.likelihood.gaussian import ShotLikelihood
from lidarinv.inference.shot import WindowData

BINS = 36


class _Zeros:
    """A generator stand-in whose normal draws are all zero: the conditional mean."""

    def standard_normal(self, shape):
        return np.zeros(shape)


def _shot(rng, noise, kind):
    axis = np.arange(BINS) * 0.15
    signal = np.exp(-0.5 * ((axis - 2.5) / 0.5) ** 2) * 0.02
    scale = 2000.0 * signal
    if kind == "diagonal":  # no variance away from the return
        covariance = np.diag(np.where(scale > 1e-3 * scale.max(), 0.3 * scale, 0.0) ** 2)
        fixed = np.diag(covariance).copy()
    else:
        factor = rng.standard_normal((BINS, 5)) * scale[:, None] * 0.2
        fixed = covariance = factor @ factor.T
    truth = np.linalg.cholesky(covariance + 1e-12 * np.eye(BINS)) @ rng.standard_normal(BINS)
    read = np.linalg.cholesky(noise.covariance(BINS)) @ rng.standard_normal(BINS)
    samples = 40.0 + scale + truth + 1.5 * read
    data = WindowData(axis=axis, samples=samples, censored=np.zeros(BINS, bool),
                      saturated=np.zeros(BINS, bool))  # fmt: skip
    like = ShotLikelihood(data, fixed_discrepancy=fixed, noise_correlation=noise)
    return like, signal, covariance


@pytest.mark.parametrize("phi", [0.0, 0.7])
@pytest.mark.parametrize("kind", ["diagonal", "covariance"])
def test_draws_follow_the_dense_gaussian_conditional(phi, kind):
    rng = np.random.default_rng(7)
    noise = AutoregressiveNoise(np.array([phi]), 1 - phi**2, np.array([1.0, phi]))
    if phi == 0.0:
        noise = AutoregressiveNoise.white()
    like, signal, covariance = _shot(rng, noise, kind)
    values = {"gain": np.array([1900.0]), "baseline": np.array([40.3]),
              "noise_sigma": np.array([1.4])}  # fmt: skip
    read = 1.4**2 * noise.covariance(BINS)
    residual = like.data.samples - 40.3 - 1900.0 * signal
    gain_matrix = covariance @ np.linalg.inv(read + covariance)
    mean = gain_matrix @ residual
    spread = covariance - gain_matrix @ covariance
    exact = discrepancy_given_data(like, signal[None, :], values, _Zeros())[0]
    # an eigendecomposition apart
    np.testing.assert_allclose(exact, mean, atol=1e-5 * np.abs(mean).max())
    many = 20000
    rows = {k: np.repeat(v, many) for k, v in values.items()}
    draws = discrepancy_given_data(like, np.tile(signal, (many, 1)), rows, rng)
    np.testing.assert_allclose(draws.mean(axis=0), mean, atol=0.03 * np.abs(mean).max() + 0.02)
    sampled = np.cov(draws.T)
    scale = np.sqrt(np.outer(np.diag(spread), np.diag(spread))).max()
    np.testing.assert_allclose(sampled, spread, atol=0.05 * scale)


def test_no_variance_no_discrepancy_and_where_it_cannot_be_drawn():
    """Bins without discrepancy variance keep d = 0 however noisy; a window with censored
    samples, or shot noise, leaves d | y non-Gaussian and is refused by name."""
    rng = np.random.default_rng(2)
    like, signal, _ = _shot(rng, AutoregressiveNoise.white(), "diagonal")
    values = {"gain": np.array([1900.0]), "baseline": np.array([40.0]),
              "noise_sigma": np.array([1.4])}  # fmt: skip
    draws = discrepancy_given_data(like, signal[None, :], values, rng)[0]
    empty = like.in_basis()[2] == 0  # the basis is the bins themselves here
    assert empty.any() and np.all(draws[empty] == 0.0)
    censored = like.data.samples < 40.5
    data = WindowData(axis=like.data.axis, samples=like.data.samples, censored=censored,
                      saturated=np.zeros(BINS, bool), floor=40.5)  # fmt: skip
    refused = ShotLikelihood(data, fixed_discrepancy=np.full(BINS, 0.5))
    assert "censored" in conditioning_obstacle(refused)
    with pytest.raises(ValueError, match="censored"):
        discrepancy_given_data(refused, signal[None, :], values, rng)
    noisy = ShotLikelihood(like.data, shot_factor=0.3)
    assert "shot noise" in conditioning_obstacle(noisy)
