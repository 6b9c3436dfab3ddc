"""A footprint conditioned on its tallest stem: the latent's law against explicit stands,
its inverse, the posterior that carries it, and the discrepancy it leaves."""

import numpy as np
import pytest
from scipy import stats

from forward.realise import realise
from forward.stand import Stand
from lidarinv.examples import SYNTHETIC_SHOTS, synthetic_shot
from lidarinv.inference import InversionSettings, build_problem
from lidarinv.inference.model.stand import StandMapping, default_template
from lidarinv.inference.model.tallest_stem import (
    TALLEST_STEM,
    TALLEST_STEM_POSITION,
    tallest_stem_within,
)
from lidarinv.inference.passes import realisations as realisations_module
from lidarinv.inference.passes.realisations import realisation_residuals
from lidarinv.inference.posterior import LogPosterior

SIGMA_F = 5.5  # m, GEDI-like footprint σ
VALUES = {
    "cover": 0.5,
    "pai": 2.5,
    "top_height": 24.0,
    "height_sd": 3.0,
    "crown_length_ratio": 0.5,
    "cone_fraction": 0.4,
    "crown_radius_slope": 0.1,
    "understory_height": 1.0,
    "understory_lai": 0.3,
    "rho_ratio": 1.5,
    "ground_elevation": 0.0,
}


def _values(n, **changes):
    return {k: np.full(n, float(changes.get(k, v))) for k, v in {**VALUES, **changes}.items()}


@pytest.fixture(scope="module")
def mapping():
    return StandMapping(default_template(), footprint_sigma_m=SIGMA_F)


def _survival(h):
    """S(h) of VALUES' heights: normal, mean 18 m, sd 3 m, truncated at ±2 sd."""
    mass = stats.norm.cdf(2.0) - stats.norm.cdf(-2.0)
    return np.clip((stats.norm.cdf(2.0) - stats.norm.cdf((h - 18.0) / 3.0)) / mass, 0, 1)


def test_law_of_the_latent_stem_is_that_of_the_tallest_stem_of_explicit_stands(mapping, rng):
    """The density of H, with the chance of no stem, integrates to the CDF of the tallest
    of Poisson(λA) stems, exp(−λA·S(h)), which the tallest stem within 2σf of the centre
    of explicit stands follows (KS); the stem's position is uniform in r²/R² there."""
    heights = np.linspace(12.0, 24.0, 4001)
    values = _values(heights.size, **{TALLEST_STEM_POSITION: 0.5})
    values[TALLEST_STEM] = heights
    _, derived = mapping.model_vectors(values)
    stems = derived["density"][0] * 1e-4 * mapping.tallest_stem_area
    density = np.exp(derived["tallest_stem_log_density"])
    steps = 0.5 * (density[1:] + density[:-1]) * np.diff(heights)
    cdf = np.exp(-stems) + np.concatenate([[0.0], np.cumsum(steps)])
    np.testing.assert_allclose(cdf, np.exp(-stems * _survival(heights)), atol=1e-5)
    params = default_template().with_values(
        density=float(derived["density"][0]),
        height_mean=VALUES["top_height"] - 2.0 * VALUES["height_sd"],
        height_sd=VALUES["height_sd"],
        crown_radius_slope=VALUES["crown_radius_slope"],
    )
    side = 6.0 * SIGMA_F
    explicit = np.array(
        [
            tallest_stem_within(realise(params, side, rng), (side / 2, side / 2), SIGMA_F)
            for _ in range(1500)
        ]
    )
    assert stats.kstest(explicit[:, 0], lambda h: np.interp(h, heights, cdf)).pvalue > 0.01
    assert stats.kstest(explicit[:, 1], "uniform").pvalue > 0.01


def test_latent_stem_conditions_the_model_vectors(mapping, rng):
    """Cohort 1 is capped at H and the stem is an apex cohort of its footprint weight,
    on average over the position the disc's weight over its area."""
    n = 1000
    values = _values(n, **{TALLEST_STEM: 0.0, TALLEST_STEM_POSITION: 0.0})
    values[TALLEST_STEM] = rng.uniform(13.0, 24.0, n)
    values[TALLEST_STEM_POSITION] = rng.uniform(size=n)
    vectors, derived = mapping.model_vectors(values)
    column = dict(zip(mapping.model_free, vectors.T))
    np.testing.assert_array_equal(column["height_cap"], values[TALLEST_STEM])
    np.testing.assert_array_equal(derived["tallest_stem"], values[TALLEST_STEM])
    weight = np.exp(-2.0 * values[TALLEST_STEM_POSITION]) / (2 * np.pi * SIGMA_F**2)
    np.testing.assert_allclose(column["apex_density"], 1e4 * weight, rtol=1e-12)
    area = np.pi * (2.0 * SIGMA_F) ** 2
    mean = np.mean(column["apex_density"])
    assert mean == pytest.approx(1e4 * (1 - np.exp(-2.0)) / area, rel=0.05)


def test_no_stem_and_heights_off_the_support(mapping):
    """H in the metre below the stand's lowest tree (12 m) is a disc without a stem, of
    probability e^{−λA} spread over that metre: no apex and no tree below the cap. That
    range joins the support, so a short stem and none are neighbours. Heights the stand
    cannot hold have density zero: above its top, and more than a metre below its lowest
    tree."""
    values = _values(7, **{TALLEST_STEM_POSITION: 0.3})
    values[TALLEST_STEM] = np.array([11.5, 11.0, 12.0 - 1e-9, 12.0 + 1e-9, 24.5, 10.9, 5.0])
    vectors, derived = mapping.model_vectors(values)
    stems = derived["density"] * 1e-4 * mapping.tallest_stem_area
    law = derived["tallest_stem_log_density"]
    np.testing.assert_allclose(law[:3], -stems[:3], rtol=1e-12)
    density = stats.truncnorm(-2, 2, loc=18.0, scale=3.0).pdf(12.0 + 1e-9)
    assert law[3] == pytest.approx(np.log(stems[3] * density) - stems[3], rel=1e-6)
    assert np.all(law[4:] == -np.inf)
    assert np.all(derived["tallest_stem"][:3] == 0.0)
    assert np.all(vectors[:3, mapping.model_free.index("apex_density")] == 0.0)
    assert np.all(vectors[:3, mapping.model_free.index("height_cap")] < 1e-3)
    np.testing.assert_allclose(mapping.lowest_height(values), 12.0, rtol=1e-12)


@pytest.fixture(scope="module")
def shot():
    return synthetic_shot(SYNTHETIC_SHOTS["gedi-mixed"], np.random.default_rng(11))


@pytest.fixture(scope="module")
def problem(shot):
    """The latent tallest stem with its position sampled too."""
    free_position = {TALLEST_STEM_POSITION: {"fixed": None}}
    return build_problem(shot, InversionSettings(tallest_stem=True, priors=free_position))


def test_position_is_held_at_the_discs_mean_weight_by_default(shot):
    space = build_problem(shot, InversionSettings(tallest_stem=True)).space
    assert TALLEST_STEM in space.names and TALLEST_STEM_POSITION not in space.names
    held = space.by_name[TALLEST_STEM_POSITION].fixed
    assert np.exp(-2.0 * held) == pytest.approx(0.5 * (1.0 - np.exp(-2.0)), rel=1e-12)


def test_the_posterior_carries_the_law_of_the_latent(problem, shot):
    """The log-prior holds the stem's law given the stand (not its sampled range), and a
    stem above the stand's top or a position outside [0, 1] has no density."""
    space = problem.space
    assert {TALLEST_STEM, TALLEST_STEM_POSITION} <= set(space.names)
    post = problem.log_posterior
    assert post.mapping.conditioned
    top = shot.truth["top_height"]
    row = np.array([shot.truth.get(name, 0.5) for name in space.names])
    x = np.repeat(row[None, :], 5, axis=0)
    stem, position = space.names.index(TALLEST_STEM), space.names.index(TALLEST_STEM_POSITION)
    x[:, stem] = [top - 1.0, top - 0.2, top + 0.1, top - 0.2, top - 0.2]
    x[:, position] = [0.5, 0.5, 0.5, -0.1, 1.2]
    terms = post.evaluate(x)
    assert np.all(np.isfinite(terms.log_posterior[:2])) and np.all(
        terms.log_posterior[2:] == -np.inf
    )
    _, derived = post.mapping.model_vectors(space.values(x[:2]))
    law = derived["tallest_stem_log_density"]
    assert terms.log_prior[1] - terms.log_prior[0] == pytest.approx(law[1] - law[0], rel=1e-9)
    assert law[1] > law[0]  # in a dense stand the disc's tallest stem is near the top
    plain = build_problem(shot, InversionSettings()).space
    rest = np.delete(x[:2], [stem, position], axis=1)
    np.testing.assert_allclose(terms.log_prior[:2], plain.log_prior(rest) + law, rtol=1e-12)
    unconditioned = build_problem(shot, InversionSettings())
    with pytest.raises(ValueError, match=TALLEST_STEM):
        post = unconditioned.log_posterior
        LogPosterior(space, post.model, post.likelihood)


def test_residuals_are_taken_against_each_stands_own_tallest_stem(problem, shot, monkeypatch):
    """A stand whose tallest stem within the disc is 15 m: conditioned on it, the model
    puts no canopy above it, so neither waveform has signal there and the residuals
    vanish; the whole stand's expectation has crowns up to its 24 m top there."""
    side = 3.0 * problem.instrument.footprint_diameter_m
    centre = side / 2
    heights = np.array([15.0, 12.0, 10.0, 13.0])
    stand = Stand(
        x=centre + np.array([0.0, 3.0, -4.0, 2.0]),
        y=centre + np.array([0.0, -2.0, 1.0, 4.0]),
        height=heights,
        crown_length=0.5 * heights,
        crown_radius=0.1 * heights,
        shape=np.zeros(4, np.int8),
        favd=np.full(4, 0.8),
    )
    monkeypatch.setattr(realisations_module, "realise", lambda *args: stand)
    space = problem.space
    row = np.array([shot.truth.get(name, 0.5) for name in space.names])
    row[space.names.index("top_height")] = 24.0
    row[space.names.index(TALLEST_STEM)] = 20.0  # a pilot's stem, replaced by the stand's
    x = np.repeat(row[None, :], 2, axis=0)
    rng = np.random.default_rng(1)
    conditioned = realisation_residuals(problem.log_posterior, problem.instrument, x, rng)
    reach = 6.0 * problem.instrument.pulse.sigma_m
    above = problem.window.axis - row[space.names.index("ground_elevation")] > 15.0 + reach
    assert np.max(np.abs(conditioned[:, above])) < 1e-6 * np.max(np.abs(conditioned))
    assert np.max(np.abs(conditioned)) > 0
    plain = build_problem(shot, InversionSettings())
    latents = [space.names.index(name) for name in (TALLEST_STEM, TALLEST_STEM_POSITION)]
    x_plain = np.delete(x, latents, axis=1)
    residuals = realisation_residuals(plain.log_posterior, plain.instrument, x_plain, rng)
    assert np.max(-residuals[:, above]) > 0.01 * np.max(np.abs(residuals))


def test_a_priors_file_table_turns_the_latent_on(tmp_path, shot):
    path = tmp_path / "priors.toml"
    path.write_text("[tallest_stem_height]\nfree = true\n")
    settings = InversionSettings.from_priors_file(path)
    assert settings.tallest_stem
    assert TALLEST_STEM in build_problem(shot, settings).space.names
    path.write_text("[tallest_stem_height]\nfixed = 20.0\n")
    fixed = build_problem(shot, InversionSettings.from_priors_file(path))
    assert TALLEST_STEM not in fixed.space.names and fixed.log_posterior.mapping.conditioned
    path.write_text("[tallest_stem_position]\nfree = true\n")
    free = build_problem(shot, InversionSettings.from_priors_file(path))
    assert {TALLEST_STEM, TALLEST_STEM_POSITION} <= set(free.space.names)
    path.write_text(
        '[tallest_stem_height]\nkind = "truncated-normal"\nmean = 20.0\nsd = 1.0\n'
        "lower = 0.0\nupper = 40.0\n"
    )
    with pytest.raises(ValueError, match="uniform range"):
        build_problem(shot, InversionSettings.from_priors_file(path))


def test_two_storeys_conditioned_on_the_tallest_stem(rng):
    """Over two storeys the stem's law is that of the tallest of the mixture: its density
    and the chance of no stem integrate to exp(−λA·S(h)), S the mixture's survival; the
    stem stops both storeys, and an emergent upper storey (few stems) makes a tall stem
    likely only as its share of the stems grows."""
    from lidarinv.inference.model.two_cohort import TwoCohortMapping

    two = TwoCohortMapping(default_template(), footprint_sigma_m=SIGMA_F)
    assert two.conditioned and {"height_cap", "apex_density"} <= set(two.model_free)
    heights = np.linspace(0.5, 34.0, 20001)
    rows = {
        **_values(heights.size, top_height=34.0, height_sd=2.0),
        "cohort2_fraction": np.full(heights.size, 0.95),  # 5 % emergents over a canopy
        "cohort2_top_ratio": np.full(heights.size, 0.6),
        "cohort2_sd_ratio": np.full(heights.size, 0.1),
        TALLEST_STEM: heights,
        TALLEST_STEM_POSITION: np.full(heights.size, 0.4),
    }
    vectors, derived = two.model_vectors(rows)
    column = dict(zip(two.model_free, vectors.T))
    stems = derived["density"][0] * 1e-4 * two.tallest_stem_area
    lowest = two.lowest_height({k: v[:1] for k, v in rows.items()})[0]
    survival = 0.0
    for share, mean, sd in two.cohort_heights({k: v[:1] for k, v in rows.items()}):
        args = two.family.arguments(mean, sd, two.truncation)
        survival = survival + share * two.family.fast("sf", heights, *args)
    density = np.exp(derived["tallest_stem_log_density"])
    inside = heights >= lowest
    steps = 0.5 * (density[1:] + density[:-1]) * np.diff(heights) * inside[1:] * inside[:-1]
    cdf = np.exp(-stems) + np.concatenate([[0.0], np.cumsum(steps)])
    np.testing.assert_allclose(cdf[inside], np.exp(-stems * survival[inside]), atol=2e-4)
    np.testing.assert_array_equal(column["height_cap"][inside], heights[inside])
    # the share of emergents sets how likely a tall stem is: fewer, less likely
    few = {**rows, "cohort2_fraction": np.full(heights.size, 0.99)}
    _, fewer = two.model_vectors(few)
    tall = heights > 30.0
    law, law_fewer = derived["tallest_stem_log_density"], fewer["tallest_stem_log_density"]
    assert np.all(law_fewer[tall] < law[tall])


def test_the_stem_stops_the_lower_storey_too(shot):
    """A stem below the lower storey's top: conditioned on it, the two-storey model puts
    no canopy above it, in either storey."""
    problem = build_problem(shot, InversionSettings(cohorts=2, tallest_stem=True))
    post, space = problem.log_posterior, problem.space
    assert post.mapping.conditioned and TALLEST_STEM in space.names
    x = space.sample_prior(np.random.default_rng(3), 1)
    for name, value in {"top_height": 30.0, "height_sd": 1.0, "cohort2_fraction": 0.9,
                        "cohort2_top_ratio": 0.8, "cohort2_sd_ratio": 0.2, "cover": 0.8,
                        "ground_elevation": 0.0, TALLEST_STEM: 15.0}.items():  # fmt: skip
        x[:, space.names.index(name)] = value
    values = space.values(x)
    rows = post.model.evaluate(values)
    reach = 6.0 * problem.instrument.pulse.sigma_m + 1.0
    above = problem.window.axis > 15.0 + reach
    assert rows.valid[0] and np.any(above)
    assert np.max(np.abs(rows.signal[0, above])) < 1e-9 * np.max(rows.signal[0])
