"""Two plausible grounds: where the analysis flags the ground ambiguous, the inversion's
ground prior holds both (an even mixture of truncated normals), and the result gives the
evidence for each."""

import copy
from dataclasses import replace

import numpy as np
import pytest
from scipy.integrate import quad

from lidarinv.examples import SYNTHETIC_SHOTS, synthetic_shot
from lidarinv.inference import InversionSettings
from lidarinv.inference.model.parameters import Parameter
from lidarinv.inference.model.prior_table import PriorTable
from lidarinv.inference.model.priors import TruncatedNormal, TruncatedNormalMixture, make_prior
from lidarinv.inference.model.space import ParameterSpace
from lidarinv.inference.passes.ambiguity import describe_modes, ground_modes
from lidarinv.inference.shot import GROUND_AMBIGUOUS, Shot

MIXTURE = TruncatedNormalMixture(10.0, 0.3, 4.0, 0.6, 0.5, 0.0, 14.0)


def test_the_mixture_is_a_density_with_mass_at_both_grounds():
    total, _ = quad(lambda z: np.exp(MIXTURE.exact_log_pdf(z)), 0.0, 14.0, points=[4, 10])
    assert total == pytest.approx(1.0, abs=1e-6)
    draws = MIXTURE.sample(np.random.default_rng(1), 40000)
    assert np.mean(np.abs(draws - 10.0) < 1.5) == pytest.approx(0.5, abs=0.01)
    assert np.mean(np.abs(draws - 4.0) < 3.0) == pytest.approx(0.5, abs=0.01)
    assert MIXTURE.exact_log_pdf(-1.0) == -np.inf and MIXTURE.exact_log_pdf(np.nan) == -np.inf
    # the table that the posterior evaluates takes the mixture's density, not its form's
    table = PriorTable([TruncatedNormal(0.0, 1.0, -5.0, 5.0), MIXTURE])
    x = np.array([[0.3, 4.2], [1.0, 7.0]])
    np.testing.assert_allclose(table.log_pdf(x)[:, 1], MIXTURE.exact_log_pdf(x[:, 1]))
    assert make_prior(MIXTURE.describe()) == MIXTURE  # a priors file can name it


def test_the_posterior_share_of_each_ground_is_its_evidence():
    space = ParameterSpace([Parameter("ground_elevation", "m", MIXTURE)])
    near_alternative = np.random.default_rng(2).normal(4.0, 0.2, (900, 1))
    near_chosen = np.random.default_rng(3).normal(10.0, 0.1, (100, 1))
    modes = ground_modes(space, np.vstack([near_alternative, near_chosen]))
    assert modes["grounds"] == [10.0, 4.0] and modes["prior_weights"] == [0.5, 0.5]
    assert modes["posterior_probability"] == pytest.approx([0.1, 0.9], abs=0.01)
    assert "P = 0.10 at the analysis's ground" in describe_modes(modes)
    modes = ground_modes(space, near_alternative)
    assert describe_modes(modes) is None  # one ground holds all but 1 : 20 of the mass
    single = ParameterSpace([Parameter("ground_elevation", "m", TruncatedNormal(1, 1, -5, 5))])
    assert ground_modes(single, near_chosen) is None


@pytest.fixture(scope="module")
def shot():
    observation = synthetic_shot(SYNTHETIC_SHOTS["gedi-mixed"], np.random.default_rng(4))
    return Shot.from_observation(observation, InversionSettings())


def _ambiguous(shot, depth_m):
    analysis = copy.copy(shot.analysis)
    analysis.flags = [*analysis.flags, GROUND_AMBIGUOUS]
    analysis.ground_alternative = analysis.ground - depth_m
    return replace(shot, analysis=analysis)


def test_an_ambiguous_shot_takes_both_grounds_into_its_prior(shot):
    plain = shot.nuisance_priors()["ground_elevation"]
    assert isinstance(plain, TruncatedNormal)
    prior = _ambiguous(shot, 6.0).nuisance_priors()["ground_elevation"]
    assert isinstance(prior, TruncatedNormalMixture)
    assert prior.mean == pytest.approx(shot.ground)
    assert prior.alt_mean == pytest.approx(shot.ground - 6.0)  # registered as the chosen
    assert prior.lower < prior.alt_mean - 3 * prior.alt_sd and prior.upper >= plain.upper
    density = np.exp(
        prior.exact_log_pdf(np.array([shot.ground, shot.ground - 6.0, shot.ground - 3.0]))
    )
    assert density[0] > 100 * density[2] and density[1] > 100 * density[2]


def test_a_mode_above_a_marginal_ground_enters_the_prior_and_bounds_the_canopy(shot):
    """Where the chosen ground is a marginal return below the lowest mode, the mode is the
    alternative: the prior reaches it, and the canopy stays inside the window over it."""
    plain = shot.nuisance_priors()
    priors = _ambiguous(shot, -3.0).nuisance_priors()
    prior = priors["ground_elevation"]
    assert prior.alt_mean == pytest.approx(shot.ground + 3.0)
    assert (
        prior.upper > prior.alt_mean + 3 * prior.alt_sd
        and prior.lower <= plain["ground_elevation"].lower
    )
    assert priors["top_height"].upper == pytest.approx(plain["top_height"].upper - 3.0)


def test_the_window_reaches_below_the_alternative_ground(shot, monkeypatch):
    """The likelihood must see the lower return for the data to weigh it."""
    import lidarinv.inference.shot as shot_module

    low, _ = shot.pulse_range
    # the alternative's pulse starts a metre below where the plain window starts
    depth = shot.ground - (shot.window.axis[0] - 1.0 - low)
    assert shot.observation.axis[0] < shot.window.axis[0] - 3.0  # the record reaches there
    flagged = _ambiguous(shot, depth).analysis
    monkeypatch.setattr(shot_module, "analyse", lambda *args, **kwargs: flagged)
    widened = Shot.from_observation(shot.observation, InversionSettings())
    assert widened.window.axis[0] < widened.alternative_ground()[0] + low
    assert widened.window.axis[0] < shot.window.axis[0] - 1.0
    assert widened.window.axis[-1] == shot.window.axis[-1]
