"""The following covariance re-centred: realisations simulated again about the optimum of
the posterior the first simulation defines, not about a pilot that left the stand."""

import numpy as np
import pytest

from lidarinv.examples import SYNTHETIC_SHOTS, synthetic_shot
from lidarinv.inference import InversionSettings, SamplerSettings, build_problem
from lidarinv.inference.invert import prepare_problem
from lidarinv.inference.passes.realisations import SimulatedDiscrepancy, realisation_covariance
from lidarinv.inference.passes.recentre import recentred_simulation
from lidarinv.inference.sampling.start import MapEstimate, laplace_covariance
from lidarinv.inference.settings import RealisationSettings

QUICK = SamplerSettings(candidates=256, starts=4, polish=1)
FEW = RealisationSettings(count=16, resamples=0)


@pytest.fixture(scope="module")
def shot():
    return synthetic_shot(SYNTHETIC_SHOTS["gedi-mixed"], np.random.default_rng(11))


def test_a_pilot_that_dropped_the_canopy_is_left_for_the_fixed_posteriors_optimum(shot):
    """A pilot whose stand stands at half the true top height: the simulation about it
    defines a posterior whose optimum lies near the true top, and the re-centred simulation
    is made there, with as many realisations."""
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
    likelihood = pilot_posterior.likelihood.with_fixed_discrepancy(covariance)
    fixed = pilot_posterior.with_likelihood(likelihood)
    recentred = recentred_simulation(fixed, problem.instrument, rng, FEW, QUICK, simulation)
    assert isinstance(recentred, SimulatedDiscrepancy)
    assert recentred.residuals.shape == simulation.residuals.shape
    assert recentred.seconds > simulation.seconds
    assert recentred.estimate.log_prob > float(fixed(wrong[None, :])[0, 0]) + 10.0
    x, _ = problem.space.from_unbounded(recentred.estimate.u[None, :])
    top = shot.truth["top_height"]
    assert abs(x[0, names.index("top_height")] - top) < 0.2 * top  # the pilot was 0.5 off


def test_only_the_following_covariance_is_recentred(shot):
    """Under ``following`` the start is the MAP of the posterior under the fixed
    covariance, searched from the pilot's: that posterior rates it at least as high.
    ``realisations`` keeps the pilot's MAP, simulated from the same generator."""
    prepared = {}
    for model in ("realisations", "following"):
        settings = InversionSettings(
            cohorts=1, discrepancy_model=model, realisations=FEW, sampler=QUICK
        )
        prepared[model] = prepare_problem(shot, settings, np.random.default_rng(5))
        assert prepared[model].discrepancy_draws.residuals.shape[0] == FEW.count
    fixed = prepared["realisations"].problem.log_posterior
    pilot = np.atleast_2d(prepared["realisations"].start)[:1]
    recentred = np.atleast_2d(prepared["following"].start)[:1]
    assert not np.allclose(recentred, pilot)
    assert fixed(recentred)[0, 0] >= fixed(pilot)[0, 0] - 1e-6
    draws = (prepared[m].discrepancy_draws.residuals for m in prepared)
    assert not np.allclose(*draws)  # simulated again about the new centre
