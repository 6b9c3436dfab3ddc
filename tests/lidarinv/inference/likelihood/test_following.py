"""The discrepancy covariance that follows each row's stand: the compiled band-plus-low-rank
forms against the dense multivariate normal, the fixed covariance recovered at the pilot's
own stand, and the physics it is for: no crowns in a bin, no spread there."""

import numpy as np
import pytest

from lidarinv.inference.likelihood.ar_noise import AutoregressiveNoise
from lidarinv.inference.likelihood.following import KEPT_SHARE, FollowingCovariance
from lidarinv.inference.likelihood.gaussian import ShotLikelihood
from lidarinv.inference.model.priors import LogUniform
from lidarinv.inference.passes.realisations import discrepancy_covariance
from lidarinv.inference.results.realisation_spread import DiscrepancyDraws, resampled_likelihood
from lidarinv.inference.shot import WindowData
from lidarinv.testing import dense_log_likelihood

BINS = 48
SHRINKAGE = 0.3
AXIS = np.arange(BINS) * 0.3
GROUND = 1.5 * np.exp(-0.5 * ((AXIS - 2.0) / 0.4) ** 2)
LOWER = np.exp(-0.5 * ((AXIS - 6.0) / 1.0) ** 2)
UPPER = 0.3 * np.exp(-0.5 * ((AXIS - 11.0) / 1.2) ** 2)
PILOT = 0.02 * (GROUND + LOWER + UPPER)  # a lower storey and a sparse upper one


def _residuals(rng, count=200):
    """Realisations of the pilot: the upper storey present or not, the lower one's
    return scattered, as explicit stands give (DN)."""
    upper = rng.choice([-1.0, 2.0], size=count, p=[2 / 3, 1 / 3])[:, None] * UPPER
    lower = 0.2 * rng.standard_normal(count)[:, None] * LOWER
    return 2000.0 * 0.02 * (upper + lower) + 0.5 * rng.standard_normal((count, BINS))


def _noise(phi):
    if phi == 0:
        return None
    return AutoregressiveNoise(np.array([phi]), 1 - phi**2, np.array([1.0, phi]))


def _likelihood(rng, phi, gain_prior=None, samples_signal=PILOT, kept_share=KEPT_SHARE):
    residuals = _residuals(rng)
    floor = (0.05 * 2000.0 * PILOT) ** 2
    noise = _noise(phi)
    correlation = np.eye(BINS) if noise is None else noise.covariance(BINS)
    samples = 40.0 + 2000.0 * samples_signal
    samples = samples + 1.5 * np.linalg.cholesky(correlation) @ rng.standard_normal(BINS)
    data = WindowData(axis=AXIS, samples=samples, censored=np.zeros(BINS, bool),
                      saturated=np.zeros(BINS, bool))  # fmt: skip
    covariance = discrepancy_covariance(residuals, SHRINKAGE) + np.diag(floor)
    fixed = ShotLikelihood(data, fixed_discrepancy=covariance, noise_correlation=noise,
                           gain_prior=gain_prior)  # fmt: skip
    following = FollowingCovariance.of(residuals, SHRINKAGE, PILOT, floor, fixed.whitening,
                                       kept_share)  # fmt: skip
    return fixed, fixed.with_following(following), residuals, floor, correlation


def _rows(n=4):
    grid = np.linspace(0.7, 1.3, n)
    rows = np.array([0.02 * (GROUND + g * LOWER + (2 - g) * UPPER) for g in grid])
    values = {"gain": 2000.0 * grid[::-1] ** 0.1, "baseline": 40.0 + 0.1 * grid,
              "noise_sigma": 1.5 * grid}  # fmt: skip
    return rows, values


@pytest.mark.parametrize("phi", [0.0, 0.6])
def test_following_likelihood_is_the_dense_normal_of_each_rows_scaled_covariance(phi):
    rng = np.random.default_rng(1)
    _, like, residuals, floor, correlation = _likelihood(rng, phi, kept_share=1.0)
    rows, values = _rows()
    fast, _ = like.log_likelihood(rows, values)
    realised = discrepancy_covariance(residuals, SHRINKAGE)
    for r in range(rows.shape[0]):
        scale = np.sqrt(like.following.scales(rows[r : r + 1])[0])
        covariance = scale[:, None] * realised * scale[None, :] + np.diag(floor)
        reference = dense_log_likelihood(
            like.data.samples, rows[r : r + 1], values["gain"][r : r + 1],
            values["baseline"][r : r + 1], values["noise_sigma"][r : r + 1], correlation,
            covariance,
        )  # fmt: skip
        assert fast[r] == pytest.approx(reference[0], abs=1e-8)


@pytest.mark.parametrize("phi", [0.0, 0.6])
def test_at_the_pilots_own_stand_it_is_the_fixed_covariance(phi):
    rng = np.random.default_rng(2)
    prior = LogUniform(500.0, 8000.0)
    fixed, following, *_ = _likelihood(rng, phi, gain_prior=prior, kept_share=1.0)
    rows = np.tile(PILOT, (3, 1))
    values = {"baseline": np.array([39.9, 40.0, 40.1]), "noise_sigma": np.array([1.4, 1.5, 1.6])}
    ours, our_fit = following.log_likelihood(rows, values)
    theirs, their_fit = fixed.log_likelihood(rows, values)
    np.testing.assert_allclose(ours, theirs, rtol=0, atol=1e-7)
    np.testing.assert_allclose(our_fit[:, :2], their_fit[:, :2], rtol=1e-9)


def test_a_row_without_the_upper_storey_finds_no_spread_where_it_was():
    rng = np.random.default_rng(3)
    # the footprint holds the upper storey; a row without it under each covariance
    fixed, following, *_ = _likelihood(rng, 0.6, samples_signal=PILOT)
    without = np.array([0.02 * (GROUND + LOWER)])
    values = {"gain": np.array([2000.0]), "baseline": np.array([40.0]),
              "noise_sigma": np.array([1.5])}  # fmt: skip
    scales = following.following.scales(without)[0]
    # the lower storey's return, taken at the pilot's total, carries the upper one's share
    brighter = PILOT.sum() / without.sum()
    assert scales[np.argmax(UPPER)] < 0.05
    assert scales[np.argmax(LOWER)] == pytest.approx(brighter, rel=0.05)
    with_upper = np.array([PILOT])
    drop_fixed = (
        fixed.log_likelihood(without, values)[0] - fixed.log_likelihood(with_upper, values)[0]
    )
    drop_following = (
        following.log_likelihood(without, values)[0]
        - following.log_likelihood(with_upper, values)[0]
    )
    # the fixed covariance lets the storey go at a small cost; following it does not
    assert drop_following < drop_fixed - 10.0


def test_the_scale_follows_where_the_return_lies_not_its_brightness():
    rng = np.random.default_rng(5)
    following = FollowingCovariance.of(_residuals(rng), SHRINKAGE, PILOT)
    rows, _ = _rows()
    np.testing.assert_allclose(following.scales(3.0 * rows), following.scales(rows), rtol=1e-12)
    np.testing.assert_allclose(following.scales(0.5 * PILOT[None, :])[0], 1.0, rtol=1e-12)
    # a row that moves return from the upper storey to the lower one moves the spread too
    moved = following.scales(np.array([0.02 * (GROUND + 1.3 * LOWER)]))[0]
    assert moved[np.argmax(LOWER)] > 1.0 > moved[np.argmax(UPPER)]
    assert np.all(following.scales(np.zeros((1, BINS))) <= 1.0)


def test_leading_components_keep_the_asked_share():
    rng = np.random.default_rng(4)
    residuals = _residuals(rng)
    some = FollowingCovariance.of(residuals, SHRINKAGE, PILOT, kept_share=0.9)
    every = FollowingCovariance.of(residuals, SHRINKAGE, PILOT, kept_share=1.0)
    assert 1 <= some.rank < every.rank
    # what the components leave out stays on the diagonal: the variances agree
    for part in (some, every):
        dense = part.covariance(PILOT)
        np.testing.assert_allclose(np.diag(dense), np.diag(discrepancy_covariance(residuals, SHRINKAGE)),
                                   rtol=1e-9, atol=1e-9)  # fmt: skip


def test_bad_input_is_named():
    rng = np.random.default_rng(5)
    residuals = _residuals(rng)
    bad = residuals.copy()
    bad[0, 3] = np.nan
    with pytest.raises(ValueError, match="finite realisation residuals"):
        FollowingCovariance.of(bad, SHRINKAGE, PILOT)
    with pytest.raises(ValueError, match="pilot's signal must have"):
        FollowingCovariance.of(residuals, SHRINKAGE, PILOT[:-1])
    data = WindowData(axis=AXIS, samples=40 + PILOT, censored=np.zeros(BINS, bool),
                      saturated=np.zeros(BINS, bool))  # fmt: skip
    with pytest.raises(ValueError, match="pilot's fixed covariance"):
        ShotLikelihood(data, following=FollowingCovariance.of(residuals, SHRINKAGE, PILOT))


def test_the_realisation_spread_resamples_a_following_covariance_as_such():
    rng = np.random.default_rng(6)
    fixed, following, residuals, floor, _ = _likelihood(rng, 0.6)
    draws = DiscrepancyDraws(residuals, SHRINKAGE, floor)
    rows, values = _rows()
    every = np.arange(residuals.shape[0])
    # all the residuals give back the covariance sampled, whichever kind it is
    for like in (fixed, following):
        again = resampled_likelihood(like, draws, every)
        np.testing.assert_allclose(again.log_likelihood(rows, values)[0],
                                   like.log_likelihood(rows, values)[0], atol=1e-6)  # fmt: skip
    assert resampled_likelihood(following, draws, every[::2]).following is not None
