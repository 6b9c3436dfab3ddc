"""The gain integrated out analytically: against quadrature, the sampled-gain likelihood,
and exact conditional draws; when it applies and what the results hold."""

from dataclasses import replace

import numpy as np
import pytest
from scipy import stats
from scipy.integrate import quad

from lidarinv.examples import SYNTHETIC_SHOTS, synthetic_shot
from lidarinv.inference import InversionSettings, SamplerSettings, build_problem, invert_shot
from lidarinv.inference.likelihood.gaussian import ShotLikelihood
from lidarinv.inference.likelihood.marginal import GainMarginal, gain_marginal_obstacle
from lidarinv.inference.model.priors import LogUniform, TruncatedLogNormal, TruncatedNormal, Uniform
from lidarinv.inference.shot import WindowData

PRIORS = [
    LogUniform(100.0, 40000.0),
    Uniform(100.0, 40000.0),
    TruncatedNormal(2000.0, 500.0, 100.0, 40000.0),
    TruncatedLogNormal(2000.0, 0.3, 100.0, 40000.0),
]

#: (â, s): a peak far narrower than the prior, wide ones, one cut by a bound, beyond it.
FITS = [
    (2400, 0.5),
    (2400, 3),
    (2400, 100),
    (2400, 600),
    (120, 10),
    (102, 2),
    (95, 2),
    (80, 3),
    (41000, 200),
    (200, 80),
    (-50, 20),
]


def _quadrature(prior, best, s):
    """log ∫ π(a)·exp(−½((a − â)/s)²) da by adaptive quadrature around the integrand's peak."""
    lo, hi = prior.lower, prior.upper
    grid = np.linspace(max(lo, best - 40 * s), min(hi, best + 40 * s), 4001)
    if grid[0] >= grid[-1]:  # the peak lies beyond a bound: the integrand decays from it
        grid = (
            np.linspace(lo, lo + 40 * s, 4001) if best < lo else np.linspace(hi - 40 * s, hi, 4001)
        )
    log_f = prior.log_pdf(grid) - 0.5 * ((grid - best) / s) ** 2
    peak = grid[np.argmax(log_f)]
    scale = np.max(log_f)
    value = quad(
        lambda a: np.exp(prior.log_pdf(a) - 0.5 * ((a - best) / s) ** 2 - scale),
        grid[0],
        grid[-1],
        points=[peak] if grid[0] < peak < grid[-1] else None,
        limit=500,
        epsabs=0,
        epsrel=1e-13,
    )[0]
    return np.log(value) + scale


@pytest.mark.parametrize("prior", PRIORS, ids=lambda p: type(p).__name__)
def test_integral_over_the_gain_matches_adaptive_quadrature(prior):
    marginal = GainMarginal(prior)
    fits = np.array([[1.0 / s**2, best, 3.0, 5.0] for best, s in FITS])
    got = marginal.log_likelihood(fits) + 0.5 * (3.0 + 5.0)
    expected = [_quadrature(prior, best, s) for best, s in FITS]
    np.testing.assert_allclose(got, expected, rtol=0, atol=2e-7)


def test_a_model_without_signal_leaves_the_prior_to_integrate_to_one():
    fit = np.array([[0.0, 0.0, 12.0, 7.0]])
    assert GainMarginal(LogUniform(1.0, 10.0)).log_likelihood(fit)[0] == pytest.approx(-9.5)


@pytest.fixture(scope="module")
def shot():
    return synthetic_shot(SYNTHETIC_SHOTS["gedi-mixed"], np.random.default_rng(101), shot_id=1)


@pytest.fixture(scope="module")
def problems(shot):
    marginalised = build_problem(shot, InversionSettings())
    sampled = build_problem(shot, InversionSettings(marginalise_gain=False))
    return marginalised, sampled


def test_marginal_likelihood_is_the_sampled_gain_likelihood_integrated_over_its_prior(
    problems, shot
):
    marginalised, sampled = problems
    assert marginalised.space.marginalised == ("gain",)
    assert "gain" not in marginalised.space.names and "gain" in sampled.space.names
    prior = sampled.space.by_name["gain"].prior
    rng = np.random.default_rng(0)
    truth = np.array([shot.truth[n] for n in marginalised.space.names])
    for row in (truth, truth * rng.uniform(0.95, 1.05, truth.size)):
        terms = marginalised.log_posterior.evaluate(row[None, :])
        _, best, _, _ = terms.gain_fit[0]
        s = 1.0 / np.sqrt(terms.gain_fit[0, 0])
        values = dict(zip(marginalised.space.names, row))

        def log_joint(a, values=values):
            full = np.array([[values.get(n, a) for n in sampled.space.names]])
            return sampled.log_posterior.evaluate(full).log_likelihood[0] + prior.log_pdf(a)

        peak = log_joint(best)
        integral = quad(
            lambda a, peak=peak: np.exp(log_joint(a) - peak),
            best - 12 * s,
            best + 12 * s,
            points=[best],
        )[0]
        assert terms.log_likelihood[0] == pytest.approx(np.log(integral) + peak, abs=1e-6)


@pytest.mark.parametrize("best, s", [(2400.0, 60.0), (104.0, 3.0)], ids=["bulk", "at-a-bound"])
def test_conditional_draws_follow_prior_times_likelihood(best, s):
    prior = LogUniform(100.0, 40000.0)
    draws = GainMarginal(prior).draw(
        np.tile([1.0 / s**2, best, 0.0, 0.0], (4000, 1)), np.random.default_rng(3)
    )
    assert np.all((draws >= prior.lower) & (draws <= prior.upper))
    total = np.exp(_quadrature(prior, best, s))

    def cdf(a):
        a = np.atleast_1d(a)
        return (
            np.array(
                [
                    quad(
                        lambda t: np.exp(prior.log_pdf(t) - 0.5 * ((t - best) / s) ** 2),
                        prior.lower,
                        x,
                        points=[best] if prior.lower < best < x else None,
                    )[0]
                    for x in a
                ]
            )
            / total
        )

    grid = np.quantile(draws, np.linspace(0.01, 0.99, 60))
    assert np.max(np.abs(cdf(grid) - np.linspace(0.01, 0.99, 60))) < 0.03
    assert stats.kstest(draws[:400], cdf).pvalue > 1e-3


def test_marginalisation_applies_only_where_it_is_exact(shot):
    window = build_problem(shot).window
    assert gain_marginal_obstacle(window, 0.0, 0.0) is None
    assert "shot noise" in gain_marginal_obstacle(window, 0.5, 0.0)
    assert "discrepancy" in gain_marginal_obstacle(window, 0.0, 0.2)
    censored = replace(window, censored=np.arange(window.axis.size) < 3)
    assert "censored" in gain_marginal_obstacle(censored, 0.0, 0.0)
    for settings in (
        InversionSettings(shot_factor=0.5),
        InversionSettings(discrepancy_model="model"),
        InversionSettings(priors={"gain": {"fixed": 2400.0}}),
        InversionSettings(marginalise_gain=False),
    ):
        space = build_problem(shot, settings).space
        assert space.marginalised == ()
    assert build_problem(
        shot, InversionSettings(priors={"gain": {"fixed": None}})
    ).space.marginalised


def test_a_posterior_asked_to_marginalise_where_it_cannot_says_why(problems):
    marginalised, _ = problems
    post = marginalised.log_posterior
    floored = WindowData(
        post.data.axis,
        post.data.samples,
        np.arange(post.data.axis.size) < 2,
        np.zeros(post.data.axis.size, bool),
        floor=50.0,
    )
    gain = post.space.by_name["gain"].prior
    with pytest.raises(ValueError, match="censored"):
        ShotLikelihood(floored, 0.0, 0.0, gain_prior=gain)
    with pytest.raises(ValueError, match="shot noise"):
        ShotLikelihood(post.data, 0.3, 0.0, gain_prior=gain)


def test_marginalised_and_sampled_chains_are_labelled_apart(problems):
    marginalised, sampled = problems
    assert "marginalised gain" in marginalised.space.signature()
    assert marginalised.space.signature() != sampled.space.signature()


def test_results_carry_drawn_gains_and_a_band_from_them(shot):
    settings = InversionSettings(sampler=SamplerSettings(max_steps=400, check_every=200))
    result = invert_shot(shot, settings, rng=np.random.default_rng(1))
    assert result.parameter_names[-1] == "gain"
    assert "gain" not in result.diagnostics["sampled"]
    assert len(result.diagnostics["tau"]) == len(result.diagnostics["sampled"])
    gain = result.column("gain")
    assert np.all(np.isfinite(gain)) and np.std(gain) > 0
    # the drawn gains scatter about the truth (GEDI-like noise: a few % wide)
    assert abs(np.median(gain) / shot.truth["gain"] - 1.0) < 0.15
    band = result.predictive
    assert np.all(band[0] <= band[2]) and np.all(band[2] <= band[4])
    peak = np.argmax(result.observed)
    assert (
        band[0, peak] < result.observed[peak] * 1.3 and band[4, peak] > result.observed[peak] * 0.7
    )
