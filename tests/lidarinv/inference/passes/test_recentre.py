"""The centre of the following covariance: the pilot MAP or the optimum of the posterior
its simulation defines, whichever the covariance simulated about it rates higher."""

import numpy as np
import pytest

from lidarinv.examples import SYNTHETIC_SHOTS, synthetic_shot
from lidarinv.inference import InversionSettings, SamplerSettings, build_problem
from lidarinv.inference.invert import prepare_problem
from lidarinv.inference.passes.realisations import SimulatedDiscrepancy, realisation_covariance
from lidarinv.inference.passes.recentre import CENTRES, recentre
from lidarinv.inference.sampling.start import MapEstimate, laplace_covariance, local_optimum
from lidarinv.inference.settings import RealisationSettings

QUICK = SamplerSettings(candidates=256, starts=4, polish=1)
FEW = RealisationSettings(count=16, resamples=0)


@pytest.fixture(scope="module")
def shot():
    return synthetic_shot(SYNTHETIC_SHOTS["gedi-mixed"], np.random.default_rng(11))


def test_the_centre_whose_own_covariance_reaches_higher_is_kept(shot):
    """A pilot at half the true top height: each candidate's optimum is at least its own
    log-posterior at the centre, the higher one is chosen, and the realisations kept are
    those simulated about it."""
    problem = build_problem(shot, InversionSettings(cohorts=1, sampler=QUICK))
    names = problem.space.names
    low = np.array([shot.truth[name] for name in names])
    low[names.index("top_height")] *= 0.5
    wrong = problem.space.to_unbounded(low[None, :])[0]
    pilot_posterior = problem.log_posterior
    log_prob = lambda u: pilot_posterior(u)[:, 0]
    wrong_estimate = MapEstimate(wrong, float(log_prob(wrong[None, :])[0]), True, 0)
    wrong_estimate.covariance = laplace_covariance(log_prob, wrong)
    rng = np.random.default_rng(3)
    covariance, simulation = realisation_covariance(
        pilot_posterior, problem.instrument, rng, FEW, QUICK, wrong_estimate
    )
    diagonal = np.full(covariance.shape[0], 1.0)
    likelihood = pilot_posterior.likelihood.with_fixed_discrepancy(covariance + np.diag(diagonal))
    fixed = pilot_posterior.with_likelihood(likelihood)
    recentring = recentre(fixed, problem.instrument, rng, FEW, QUICK, simulation, diagonal)
    optima = recentring.optima
    assert set(optima) == set(CENTRES)
    assert optima["pilot"] > float(fixed(wrong[None, :])[0, 0]) + 10.0  # it climbs away
    assert recentring.chosen == max(optima, key=optima.get)
    kept = recentring.simulation
    assert isinstance(kept, SimulatedDiscrepancy) and kept.seconds > simulation.seconds
    assert kept.residuals.shape == simulation.residuals.shape
    same = np.array_equal(kept.residuals, simulation.residuals)
    assert same == (recentring.chosen == "pilot")


def test_local_optimum_reaches_a_peak_and_refuses_no_support():
    """On a Gaussian log-density the run from afar ends at its peak, 0; where the density
    is nowhere finite it reports −inf."""
    centre, scale = np.array([1.0, -2.0, 0.5]), np.array([0.5, 2.0, 1.0])

    def gaussian(u):
        return -0.5 * np.sum(((u - centre) / scale) ** 2, axis=1)

    assert local_optimum(gaussian, np.zeros(3)) == pytest.approx(0.0, abs=1e-6)
    nowhere = lambda u: np.full(u.shape[0], -np.inf)
    assert local_optimum(nowhere, np.zeros(3)) == -np.inf


def test_only_the_following_covariance_chooses_a_centre_and_says_which(shot):
    """Under ``following`` the preparation records both centres' optima and starts from
    the chosen one: the pilot's MAP where the pilot wins, else a point the posterior under
    the pilot's covariance rates at least as high. ``realisations`` records none."""
    prepared = {}
    for model in ("realisations", "following"):
        settings = InversionSettings(
            cohorts=1, discrepancy_model=model, realisations=FEW, sampler=QUICK
        )
        prepared[model] = prepare_problem(shot, settings, np.random.default_rng(5))
        assert prepared[model].discrepancy_draws.residuals.shape[0] == FEW.count
    assert "recentring" not in prepared["realisations"].diagnostics()
    recorded = prepared["following"].diagnostics()["recentring"]
    assert recorded["chosen"] in CENTRES and set(recorded["optima"]) == set(CENTRES)
    best = max(recorded["optima"], key=recorded["optima"].get)
    assert recorded["chosen"] == best
    fixed = prepared["realisations"].problem.log_posterior  # the same generator's
    pilot = np.atleast_2d(prepared["realisations"].start)[:1]
    start = np.atleast_2d(prepared["following"].start)[:1]
    if recorded["chosen"] == "pilot":
        np.testing.assert_array_equal(start, pilot)
    else:
        assert fixed(start)[0, 0] >= fixed(pilot)[0, 0] - 1e-6
