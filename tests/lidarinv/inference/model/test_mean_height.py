"""The mean-height coordinate: exact inverse and Jacobian, the mean height held in place as
the height sd moves, the prior and the posterior unchanged."""

from dataclasses import replace

import numpy as np
import pytest
from jacobian_check import assert_exact_jacobian, assert_log_derivative, assert_same_posterior

from lidarinv.examples import SYNTHETIC_SHOTS, synthetic_shot
from lidarinv.inference import InversionSettings
from lidarinv.inference.model import coordinates, top_coordinates
from lidarinv.inference.model.parameters import default_space
from lidarinv.inference.model.stand import TOP_SDS
from lidarinv.inference.problem import problem_for_shot
from lidarinv.inference.shot import Shot

TOP_UPPER = 45.0
WITH = (*coordinates.DEFAULT_RIDGES, "mean-height")
WITHOUT = coordinates.DEFAULT_RIDGES


def test_round_trip_with_exact_jacobian_and_the_support_of_the_prior():
    rng = np.random.default_rng(31)
    sd = rng.uniform(0.1, 10.0, 400)
    top = TOP_SDS * sd + rng.uniform(0.01, 1.0, 400) * (TOP_UPPER - TOP_SDS * sd)
    m = top_coordinates.mean_height_from_top(top, sd, TOP_UPPER, TOP_SDS)
    back, log_jac = top_coordinates.top_from_mean_height(m, sd, TOP_UPPER, TOP_SDS)
    np.testing.assert_allclose(back, top, rtol=1e-10)
    assert_log_derivative(
        lambda v: top_coordinates.top_from_mean_height(v, sd, TOP_UPPER, TOP_SDS)[0], m, log_jac
    )
    # a mean height that is not positive, or a top at the prior's upper end, has no m
    bad = top_coordinates.mean_height_from_top([3.0, TOP_UPPER, 50.0], [2.0, 1.0, 1.0], TOP_UPPER,
                                           TOP_SDS)  # fmt: skip
    assert np.all(np.isnan(bad))
    every = np.linspace(-50.0, 50.0, 1001)
    top, log_jac = top_coordinates.top_from_mean_height(every, 3.0, TOP_UPPER, TOP_SDS)
    assert np.all((top >= TOP_SDS * 3.0) & (top <= TOP_UPPER)) and np.all(np.isfinite(log_jac))


def test_the_mean_height_stays_in_place_as_the_sd_moves():
    """At fixed m, ∂μ/∂sd = −TOP_SDS·(μ/μ₁)^{p+1} (against −TOP_SDS at fixed top): the
    mean height hardly moves with the sd."""
    sd, top = np.array([0.3, 1.0, 3.0]), np.array([22.0, 24.0, 28.0])
    m = top_coordinates.mean_height_from_top(top, sd, TOP_UPPER, TOP_SDS)
    h = 1e-4
    means = [
        top_coordinates.top_from_mean_height(m, sd + d, TOP_UPPER, TOP_SDS)[0] - TOP_SDS * (sd + d)
        for d in (h, -h)
    ]
    slope = (means[0] - means[1]) / (2 * h)
    share = (top - TOP_SDS * sd) / (TOP_UPPER - TOP_SDS * sd)
    power = coordinates.LOWER_TOP_WALL_POWER
    np.testing.assert_allclose(slope, -TOP_SDS * share ** (power + 1), rtol=1e-6)
    assert np.all(np.abs(slope) < 0.06 * TOP_SDS)


@pytest.mark.parametrize("cohorts", [1, 2])
def test_space_samples_the_mean_height_with_exact_jacobian(nuisance_priors, cohorts):
    space = default_space(nuisance_priors, cohorts=cohorts, ridges=WITH)
    assert "mean-height" in space.signature()
    x = space.sample_prior(np.random.default_rng(32), 400)
    u = space.to_unbounded(x)
    finite = np.isfinite(u).all(axis=1)
    x, u = x[finite][:20], u[finite][:20]
    back, log_jac = space.from_unbounded(u)
    np.testing.assert_allclose(back, x, rtol=1e-9, atol=1e-10)
    assert_exact_jacobian(space, u[:4], log_jac[:4])


def test_the_coordinate_needs_a_free_top_and_sd_and_no_stem_gap(nuisance_priors):
    assert "mean-height" not in default_space(nuisance_priors, ridges=WITHOUT).signature()
    fixed = default_space(nuisance_priors, ridges=WITH).with_changes({"height_sd": {"fixed": 2.0}})
    assert "mean-height" not in fixed.signature()
    stem = default_space(nuisance_priors, ridges=WITH, tallest_stem=True)
    assert "tallest-stem" in stem.signature() and "mean-height" not in stem.signature()


@pytest.mark.parametrize("cohorts", [1, 2])
def test_the_posterior_is_the_same_at_matched_stands(rng, cohorts):
    """The log-posterior in either coordinate set at the same physical stand differs by the
    log-Jacobians alone, and the blobs are the same (without the tallest-stem latent, whose
    coordinate replaces the mean height's)."""
    settings = InversionSettings(discrepancy_model="observed", cohorts=cohorts, tallest_stem=False)
    shot = Shot.from_observation(synthetic_shot(SYNTHETIC_SHOTS["gedi-mixed"], rng), settings)
    problems = [problem_for_shot(shot, replace(settings, ridges=r)) for r in (WITH, WITHOUT)]
    assert "mean-height" in problems[0].space.signature()
    assert_same_posterior(problems, problems[1].space.sample_prior(rng, 64))
