"""A discrepancy covariance between bins: the rotated likelihood against the dense
multivariate normal, the covariance simulated from explicit realisations, and an
inversion that uses it."""

from dataclasses import replace

import numpy as np
import pytest
from scipy import stats
from scipy.integrate import quad

from forward.expected import ExpectedWaveformModel
from forward.expected.vectors import VECTOR_FIELDS, params_from_vector
from forward.instrument import instrument_preset
from lidarinv.examples import SYNTHETIC_SHOTS, synthetic_shot
from lidarinv.inference import InversionSettings, SamplerSettings, build_problem, invert_shot
from lidarinv.inference.likelihood.covariance import Rotation
from lidarinv.inference.likelihood.gaussian import ShotLikelihood
from lidarinv.inference.passes.realisations import (
    discrepancy_covariance,
    footprint_cover,
    realisation_residuals,
)
from lidarinv.inference.settings import RealisationSettings

STAND = SYNTHETIC_SHOTS["gedi-mixed"].params


@pytest.fixture(scope="module")
def shot():
    return synthetic_shot(SYNTHETIC_SHOTS["gedi-mixed"], np.random.default_rng(11))


@pytest.fixture(scope="module")
def problems(shot):
    return {
        # the shot's noise is white: the rotation is checked against σn²·I + C
        marginalise: build_problem(
            shot, InversionSettings(marginalise_gain=marginalise, correlated_noise=False)
        )
        for marginalise in (False, True)
    }


def _random_covariance(bins, rng, rank=12, scale=20.0):
    """A smooth low-rank covariance plus a diagonal (DN²), like a realisation one."""
    z = np.arange(bins)
    centres = rng.uniform(0, bins, rank)
    basis = np.exp(-0.5 * ((z[:, None] - centres) / 4.0) ** 2) * rng.normal(0, scale, rank)
    return basis @ basis.T + np.diag(rng.uniform(0.0, 4.0, bins))


def _with_covariance(problem, covariance):
    post = problem.log_posterior
    return post.with_likelihood(post.likelihood.with_fixed_discrepancy(covariance))


def _truth_rows(problem, shot, rng, n=3):
    truth = np.array([shot.truth[name] for name in problem.space.names])
    return truth * rng.uniform(0.97, 1.03, (n, truth.size))


@pytest.mark.parametrize("support", ["all bins", "canopy bins"])
def test_rotated_likelihood_is_the_dense_multivariate_normal(problems, shot, rng, support):
    problem = problems[False]
    covariance = _random_covariance(problem.window.axis.size, rng)
    if support == "canopy bins":  # none above the canopy or below the ground return
        inside = (problem.window.axis > 0.5) & (problem.window.axis < shot.truth["top_height"])
        covariance *= np.outer(inside, inside)
    post = _with_covariance(problem, covariance)
    x = _truth_rows(problem, shot, rng)
    terms = post.evaluate(x, keep_signal=True)
    values = problem.space.values(x)
    if support == "canopy bins":
        assert post.likelihood.rotation.rotated.size == np.sum(inside)
    for r in range(x.shape[0]):
        mean = values["baseline"][r] + values["gain"][r] * terms.signal[r]
        dense = covariance + values["noise_sigma"][r] ** 2 * np.eye(covariance.shape[0])
        expected = stats.multivariate_normal(mean, dense).logpdf(problem.window.samples)
        assert terms.log_likelihood[r] == pytest.approx(expected, abs=1e-7)


def test_gain_integrated_out_under_a_covariance_matches_quadrature(problems, shot, rng):
    marginalised, sampled = problems[True], problems[False]
    covariance = _random_covariance(marginalised.window.axis.size, rng)
    post_m = _with_covariance(marginalised, covariance)
    post_s = _with_covariance(sampled, covariance)
    prior = sampled.space.by_name["gain"].prior
    x = _truth_rows(marginalised, shot, rng, n=2)
    terms = post_m.evaluate(x)
    for r, row in enumerate(x):
        _, best, _, _ = terms.gain_fit[r]
        s = 1.0 / np.sqrt(terms.gain_fit[r, 0])
        values = dict(zip(marginalised.space.names, row))

        def log_joint(a, values=values):
            full = np.array([[values.get(n, a) for n in sampled.space.names]])
            return post_s.evaluate(full).log_likelihood[0] + prior.log_pdf(a)

        peak = log_joint(best)
        integral = quad(
            lambda a, peak=peak: np.exp(log_joint(a) - peak), best - 12 * s, best + 12 * s
        )[0]
        assert terms.log_likelihood[r] == pytest.approx(np.log(integral) + peak, abs=1e-6)


def test_a_diagonal_covariance_is_the_per_bin_variance(problems, shot, rng):
    for problem in problems.values():
        variance = rng.uniform(0.0, 30.0, problem.window.axis.size)
        x = _truth_rows(problem, shot, rng)
        per_bin = _with_covariance(problem, variance).evaluate(x).log_posterior
        as_matrix = _with_covariance(problem, np.diag(variance)).evaluate(x).log_posterior
        np.testing.assert_allclose(as_matrix, per_bin, rtol=0, atol=1e-8)


@pytest.mark.parametrize(
    "change, message",
    [
        (lambda c: c[:-1, :-1], "must be"),
        (lambda c: np.where(np.eye(c.shape[0], dtype=bool), np.nan, c), "NaN"),
        (lambda c: c + np.triu(np.ones_like(c), 1), "not symmetric"),
        (lambda c: c - 10 * np.max(c) * np.eye(c.shape[0]), "positive semi-definite"),
    ],
    ids=["shape", "nan", "asymmetric", "indefinite"],
)
def test_bad_covariances_are_refused_by_name(problems, rng, change, message):
    problem = problems[True]
    covariance = _random_covariance(problem.window.axis.size, rng)
    with pytest.raises(ValueError, match=message):
        _with_covariance(problem, change(covariance))


def test_a_covariance_needs_exact_bins_and_no_shot_noise(problems, rng):
    problem = problems[False]
    post = problem.log_posterior
    covariance = _random_covariance(problem.window.axis.size, rng)
    with pytest.raises(ValueError, match="shot noise"):
        ShotLikelihood(post.data, 1.0, 0.0, covariance)
    censored = replace(post.data, censored=post.data.samples < np.median(post.data.samples))
    with pytest.raises(ValueError, match="censored"):
        ShotLikelihood(censored, fixed_discrepancy=covariance)
    with pytest.raises(ValueError, match="censored"):
        Rotation.of(covariance, censored)


def test_full_vectors_turn_back_into_the_stand():
    instrument = instrument_preset("gedi")
    heights = np.arange(-5.0, 30.0, instrument.bin_height)
    model = ExpectedWaveformModel(instrument, heights, STAND)
    stand, ground = params_from_vector(model.full_vector(STAND, 2.5), STAND)
    assert stand == STAND and ground == 2.5
    with pytest.raises(ValueError, match=str(len(VECTOR_FIELDS))):
        params_from_vector(np.ones(3), STAND)


def test_shrinkage_moves_the_covariance_between_second_moment_and_its_diagonal(rng):
    residuals = rng.normal(size=(5, 9)) * np.linspace(1, 3, 9)
    second = residuals.T @ residuals / 5
    np.testing.assert_allclose(discrepancy_covariance(residuals, 0.0), second)
    np.testing.assert_allclose(discrepancy_covariance(residuals, 1.0), np.diag(np.diag(second)))
    mixed = discrepancy_covariance(residuals, 0.3)
    np.testing.assert_allclose(np.diag(mixed), np.diag(second))
    assert np.linalg.eigvalsh(mixed).min() > 0  # full rank from 5 residuals of 9 bins
    with pytest.raises(ValueError, match="NaN"):
        discrepancy_covariance(np.where(residuals > 2, np.nan, residuals), 0.3)
    with pytest.raises(ValueError, match="shrinkage"):
        RealisationSettings(shrinkage=1.5)
    with pytest.raises(ValueError, match="at least 2"):
        RealisationSettings(count=1)
    with pytest.raises(ValueError, match="instrument_floor"):
        RealisationSettings(instrument_floor=-0.1)


def test_the_instrument_floor_adds_the_observed_per_bin_variance_to_the_covariance(shot):
    """The simulated covariance gains (η₀·ŝ)² on its diagonal, and nothing else."""
    from lidarinv.inference.invert import prepare_problem
    from lidarinv.inference.problem import fixed_discrepancy

    covariances = {}
    for floor in (0.0, 0.1):
        settings = InversionSettings(
            realisations=RealisationSettings(count=8, instrument_floor=floor),
            sampler=SamplerSettings(candidates=64, starts=2, polish=1),
            cohorts=1,  # one MAP search: the floor is the subject, not the stand model
        )
        problem = prepare_problem(shot, settings, np.random.default_rng(5)).problem
        covariances[floor] = problem.log_posterior.likelihood.fixed_discrepancy
    added = covariances[0.1] - covariances[0.0]
    expected = fixed_discrepancy(problem.shot, replace(settings, discrepancy=0.1))
    np.testing.assert_allclose(np.diag(added), expected, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(added - np.diag(np.diag(added)), 0.0, atol=1e-9)


def test_a_two_cohort_model_simulates_more_realisations_and_records_them(shot):
    """Two cohorts simulate ``count × two_cohort_factor`` stands, one cohort ``count``,
    and the prepared problem's settings (which the result records) say how many."""
    from lidarinv.inference.invert import prepare_problem

    base = RealisationSettings(count=6, two_cohort_factor=2, resamples=0, first_fraction=1.0)
    assert base.for_cohorts(1) == base and base.for_cohorts(2).count == 12
    with pytest.raises(ValueError, match="two_cohort_factor"):
        RealisationSettings(two_cohort_factor=0)
    quick = SamplerSettings(candidates=64, starts=2, polish=1)
    for cohorts, count in ((1, 6), (2, 12)):
        settings = InversionSettings(realisations=base, sampler=quick, cohorts=cohorts)
        prepared = prepare_problem(shot, settings, np.random.default_rng(5))
        assert prepared.problem.settings.realisations.count == count
        assert prepared.discrepancy_draws.residuals.shape[0] == count


def test_realisations_scatter_about_the_expected_waveform(problems, shot, rng):
    """The mean of many explicit residuals at the truth is small against their spread,
    which is largest in the canopy and near zero far above it."""
    problem = problems[False]
    post = problem.log_posterior
    truth = np.array([shot.truth[name] for name in problem.space.names])
    x = np.repeat(truth[None, :], 120, axis=0)
    residuals = realisation_residuals(post, problem.instrument, x, rng)
    spread = residuals.std(axis=0)
    canopy = spread > 0.2 * spread.max()
    standard_error = spread[canopy] / np.sqrt(x.shape[0])
    assert np.median(np.abs(residuals.mean(axis=0)[canopy]) / standard_error) < 2.0
    top = shot.truth["top_height"]
    above = problem.window.axis > top + 6.0  # beyond the tallest crown by 6 pulse sd
    assert np.all(spread[above] < 1e-6 * spread.max())


def test_each_realisation_has_a_stream_of_its_own(problems, shot):
    """Common random numbers: a denser stand in one row (another Poisson count) leaves
    every other row's realisation as it was."""
    problem = problems[False]
    post = problem.log_posterior
    truth = np.array([shot.truth[name] for name in problem.space.names])
    x = np.repeat(truth[None, :], 4, axis=0)
    first = realisation_residuals(post, problem.instrument, x, np.random.default_rng(5))
    x[1, problem.space.names.index("cover")] *= 1.2  # more crowns: more stems
    second = realisation_residuals(post, problem.instrument, x, np.random.default_rng(5))
    unchanged = [0, 2, 3]
    np.testing.assert_array_equal(second[unchanged], first[unchanged])
    assert not np.allclose(second[1], first[1])


def test_footprint_cover_draws_scatter_about_the_stand_cover(problems, shot, rng):
    """One footprint's crown cover is a draw whose mean over footprints is the stationary
    stand's cover; the samples not given a draw are NaN."""
    problem = problems[False]
    truth = np.array([shot.truth[name] for name in problem.space.names])
    x = np.repeat(truth[None, :], 150, axis=0)
    draws = footprint_cover(problem.log_posterior, problem.instrument, x, rng, draws=120)
    drawn = draws[np.isfinite(draws)]
    assert drawn.size == 120 and np.all((drawn >= 0) & (drawn <= 1))
    assert drawn.std() > 0.01  # a footprint is a small sample of the stand
    standard_error = drawn.std() / np.sqrt(drawn.size)
    assert abs(drawn.mean() - shot.truth["cover"]) < 4 * standard_error


def test_an_inversion_with_the_simulated_covariance_runs_and_says_so(shot):
    settings = InversionSettings(
        discrepancy_model="realisations",
        realisations=RealisationSettings(count=16),
        sampler=SamplerSettings(max_steps=100, check_every=100, candidates=256, starts=8),
    )
    result = invert_shot(shot, settings, rng=np.random.default_rng(2))
    assert result.diagnostics["seconds"]["discrepancy"] > 0
    assert result.settings["discrepancy_model"] == "realisations"
    assert result.settings["realisations"]["count"] == 16
    assert np.all(np.isfinite(result.column("top_height")))


def test_where_a_covariance_cannot_apply_the_inversion_falls_back_and_says_why(shot):
    settings = InversionSettings(
        discrepancy_model="realisations",
        shot_factor=0.5,
        sampler=SamplerSettings(max_steps=100, check_every=100, candidates=256, starts=8),
    )
    result = invert_shot(shot, settings, rng=np.random.default_rng(3))
    assert any("per-bin discrepancy used instead" in flag for flag in result.flags)
    assert "discrepancy" not in result.diagnostics["seconds"]
