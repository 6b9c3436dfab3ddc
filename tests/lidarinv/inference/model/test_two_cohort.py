"""The two-storey stand mapping: its limits, its mixture identities, its settings, and
the one-cohort optimum as a start for its MAP search."""

from dataclasses import replace

import numpy as np
import pytest

from forward import poisson_stand
from lidarinv.examples import SYNTHETIC_SHOTS, ShotRecipe, synthetic_shot
from lidarinv.inference import InversionSettings, SamplerSettings
from lidarinv.inference.model.mixture_cut import mixture_cut, mixture_sum
from lidarinv.inference.model.parameters import default_space
from lidarinv.inference.model.priors import Uniform
from lidarinv.inference.model.stand import StandMapping, default_template
from lidarinv.inference.model.tallest_stem import TALLEST_STEM, disc_area
from lidarinv.inference.model.two_cohort import COHORT2, TwoCohortMapping
from lidarinv.inference.passes.cohorts import (
    STOREYS_RESOLVED_PULSE_WIDTHS,
    choose_cohorts,
    latent_start,
    nested_start,
    with_latent_stem,
)
from lidarinv.inference.problem import problem_for_shot
from lidarinv.inference.sampling.start import find_map
from lidarinv.inference.shot import Shot

N = 6


def _rows(rng, **changes):
    v = {
        "cover": rng.uniform(0.2, 0.9, N),
        "pai": rng.uniform(0.5, 5.0, N),
        "top_height": rng.uniform(12.0, 40.0, N),
        "height_sd": rng.uniform(0.5, 4.0, N),
        "crown_length_ratio": rng.uniform(0.2, 0.9, N),
        "cone_fraction": rng.uniform(0.0, 1.0, N),
        "crown_radius_slope": np.full(N, 0.1),
        "understory_height": np.full(N, 1.0),
        "understory_lai": np.full(N, 0.3),
        "rho_ratio": np.full(N, 1.5),
        "ground_elevation": np.zeros(N),
        "cohort2_fraction": rng.uniform(0.1, 0.95, N),
        "cohort2_top_ratio": rng.uniform(0.15, 0.8, N),
        "cohort2_sd_ratio": rng.uniform(0.05, 0.4, N),
    }
    v.update(changes)
    return v


def _mixture_grid(mapping, v, i, heights):
    """The mixture's height density and survival on a fine grid, row i."""
    pdf = survival = 0.0
    for share, mean, sd in mapping.cohort_heights({k: x[i : i + 1] for k, x in v.items()}):
        pdf = pdf + share * mapping.family.pdf(heights, mean, sd, mapping.truncation)
        survival = survival + share * mapping.family.sf(heights, mean, sd, mapping.truncation)
    return pdf, survival


def test_an_empty_lower_storey_gives_the_single_cohort_stand(rng):
    v = _rows(rng, cohort2_fraction=np.zeros(N))
    one, two = StandMapping(default_template()), TwoCohortMapping(default_template())
    vectors_one, derived_one = one.model_vectors(v)
    vectors_two, derived_two = two.model_vectors(v)
    for name in derived_one:
        np.testing.assert_allclose(derived_two[name], derived_one[name], rtol=1e-9)
    shared = [one.model_free.index(f) for f in one.model_free]
    np.testing.assert_allclose(vectors_two[:, shared], vectors_one, rtol=1e-12)
    z = np.linspace(0.0, 45.0, 40)
    np.testing.assert_allclose(
        two.crown_volume_profile(v, z), one.crown_volume_profile(v, z), rtol=1e-9, atol=1e-14
    )


def test_cover_and_the_dominant_height_follow_the_mixture_of_the_two_storeys(rng):
    mapping = TwoCohortMapping(default_template())
    v = _rows(rng)
    _, derived = mapping.model_vectors(v)
    heights = np.linspace(0.0, 90.0, 450_001)
    for i in range(N):
        pdf, survival = _mixture_grid(mapping, v, i, heights)
        radius = mapping.template.crown_radius_intercept + v["crown_radius_slope"][i] * heights
        area = np.trapezoid(pdf * np.pi * radius**2, heights)
        cover = poisson_stand.cover_from_density(derived["density"][i] * 1e-4, area)
        assert cover == pytest.approx(v["cover"][i], rel=1e-4)
        assert derived["mean_height"][i] == pytest.approx(
            np.trapezoid(pdf * heights, heights), rel=1e-5
        )
        tail = min(100.0 / derived["density"][i], 1.0)  # the 100 tallest stems a hectare
        top = heights >= heights[np.searchsorted(-survival, -tail)]
        dominant = np.trapezoid((pdf * heights)[top], heights[top]) / np.trapezoid(
            pdf[top], heights[top]
        )
        assert derived["dominant_height"][i] == pytest.approx(dominant, abs=2e-3)


def test_both_storeys_moments_in_one_pass_equal_each_storeys_own(rng):
    mapping = TwoCohortMapping(default_template())
    v = _rows(rng)
    family, t = mapping.family, mapping.truncation
    r0, r1 = mapping.template.crown_radius_intercept, v["crown_radius_slope"]
    cohorts, (shares, args) = mapping._mixture_moments(v)
    survival = dominant_cut = 0.0
    cut = v["top_height"] * 0.7
    for k, ((share, mean, sd), got) in enumerate(zip(mapping.cohort_heights(v), cohorts)):
        m1, m2, m3 = np.moveaxis(family.raw_moments((1, 2, 3), mean, sd, t), -1, 0)
        area = poisson_stand.crown_area_moment(r0, r1, m1, m2)
        crown = poisson_stand.crown_volume_moment(r0, r1, m1, m2, m3, v["crown_length_ratio"])
        for a, b in zip(got, (share, mean, sd, m1, area, crown)):
            assert np.array_equal(a, b)  # the same numbers, to the last bit
        assert np.array_equal(shares[k], share)
        survival = survival + share * family.sf(cut, mean, sd, t)
        dominant_cut = dominant_cut + share * family.mean_above(cut, mean, sd, t)
    assert np.array_equal(mixture_sum(family.fast, "sf", cut, shares, args), survival)
    assert np.array_equal(mixture_sum(family.fast, "mean_above", cut, shares, args), dominant_cut)


@pytest.mark.parametrize("backend", ["numpy", "numba"])
def test_the_mixture_cut_leaves_the_asked_share_of_stems_above(rng, backend):
    """Σ f_k S_k(cut) = tail with scipy's truncated normals as the slow reference: where
    the upper storey alone holds the tallest stems (closed form), and where the lower
    storey reaches above that (bisected)."""
    if backend == "numba":
        pytest.importorskip("numba")
    mapping = TwoCohortMapping(default_template())
    v = _rows(rng)
    v["cohort2_top_ratio"] = np.array([0.3, 0.3, 0.95, 0.95, 0.8, 0.6]) * 0.94
    v["cohort2_fraction"] = np.array([0.5, 0.5, 0.9, 0.9, 0.7, 0.99])
    heights = mapping.cohort_heights(v)
    tail = np.array([1e-3, 0.3, 1e-3, 0.3, 0.05, 0.5])
    cut = mixture_cut(mapping.family, mapping._stacked_laws(heights), tail, backend=backend)
    family, t = mapping.family, mapping.truncation
    above = sum(share * family.sf(cut, mean, sd, t) for share, mean, sd in heights)
    np.testing.assert_allclose(above, tail, rtol=1e-5)
    share, mean, sd = heights[1]
    lower = share * family.sf(cut, mean, sd, t)  # the lower storey's stems above the cut
    assert np.any(lower == 0) and np.any(lower > 0.1 * tail)  # closed form, and bisected


def test_the_tallest_stem_of_a_two_storey_stand_follows_the_poisson_law(rng):
    mapping = TwoCohortMapping(default_template())
    v = {k: np.repeat(x[:1], 20_000) for k, x in _rows(rng).items()}
    v["density_m2"] = np.full(20_000, 0.02)
    area = 300.0
    tallest = mapping.tallest_in_area(v, area, rng.uniform(size=20_000))
    for h in np.percentile(tallest[tallest > 0], [10, 50, 90]):
        _, survival = _mixture_grid(mapping, v, 0, np.array([h]))
        expected = np.exp(-0.02 * area * survival[0])  # P(no stem above h)
        assert np.mean(tallest <= h) == pytest.approx(expected, abs=0.015)


def test_invalid_lower_storeys_are_rows_the_sampler_rejects(rng):
    mapping = TwoCohortMapping(default_template())
    v = _rows(rng)
    v["cohort2_fraction"][0] = 1.2
    v["cohort2_top_ratio"][1] = 1.0  # not below the upper storey
    v["cohort2_sd_ratio"][2] = 0.5  # mean height at zero
    np.testing.assert_array_equal(mapping.valid(v), [False, False, False, True, True, True])


def test_settings_choose_the_cohorts_and_refuse_what_cannot_be_built(tmp_path):
    space = default_space(
        {
            name: Uniform(0.0, 1.0)
            for name in ("ground_elevation", "baseline", "gain", "noise_sigma")
        },
        cohorts=2,
    )
    assert set(COHORT2) <= set(space.names)
    with pytest.raises(ValueError, match="cohorts"):
        InversionSettings(cohorts=3)
    assert InversionSettings().cohorts == "auto"
    assert InversionSettings(tallest_stem=True).cohorts == "auto"  # either model has it
    priors = tmp_path / "priors.toml"
    priors.write_text('[cohort2_top_ratio]\nkind = "uniform"\nlower = 0.2\nupper = 0.6\n')
    assert InversionSettings.from_priors_file(priors).cohorts == 2


def test_the_nested_start_is_the_one_cohort_fit_in_the_two_cohort_space(rng):
    """The one-cohort point mapped into the two-cohort space (an empty lower storey) keeps
    the one-cohort log-likelihood: the two-cohort search starts no worse than it. The
    storeys are weighed without the tallest-stem latents (``tallest_stem="auto"``)."""
    settings = InversionSettings(discrepancy_model="observed", tallest_stem=False)
    shot = Shot.from_observation(synthetic_shot(SYNTHETIC_SHOTS["gedi-mixed"], rng), settings)
    one = problem_for_shot(shot, replace(settings, cohorts=1))
    two = problem_for_shot(shot, replace(settings, cohorts=2))
    u1 = one.space.to_unbounded(one.space.sample_prior(rng, 8))
    u1 = u1[np.isfinite(one.log_posterior(u1)[:, 0])]
    u2 = np.vstack([nested_start(one.space, u, two.space) for u in u1])
    like = [
        p.log_posterior.evaluate(p.space.from_unbounded(u)[0]).log_likelihood
        for p, u in ((one, u1), (two, u2))
    ]
    assert u1.shape[0] >= 4
    np.testing.assert_allclose(like[1], like[0], atol=0.2)  # 0.1 % of the stems below


def test_the_latent_stem_is_on_by_default_for_two_storeys_only():
    """``tallest_stem="auto"`` conditions a two-storey model (or the larger model that
    ``cohorts="auto"`` may choose) and not a one-storey one; True and False hold for both,
    and anything else is refused."""
    auto = InversionSettings()
    assert auto.tallest_stem == "auto"
    assert not auto.latent_stem(1) and auto.latent_stem(2) and auto.latent_stem("auto")
    assert InversionSettings(tallest_stem=True).latent_stem(1)
    assert not InversionSettings(tallest_stem=False).latent_stem(2)
    with pytest.raises(ValueError, match="tallest_stem"):
        InversionSettings(tallest_stem="sometimes")


def test_a_two_storey_fit_gains_the_latent_stem_at_the_median_of_its_law(rng):
    """The latent's search starts from the two-storey MAP's stand with the stem at the
    median of its law: the tallest of a Poisson draw of λ·A stems from the mixture is
    below h with probability exp(−λ·A·S(h)) = ½. The search ends no worse than that
    start."""
    settings = InversionSettings(discrepancy_model="observed", cohorts=2, tallest_stem=False)
    shot = Shot.from_observation(synthetic_shot(SYNTHETIC_SHOTS["gedi-mixed"], rng), settings)
    quick = SamplerSettings(candidates=256, starts=4, polish=1)
    plain = problem_for_shot(shot, replace(settings, sampler=quick))
    post = plain.log_posterior
    estimate = find_map(lambda u: post(u)[:, 0], plain.space, rng, quick)
    latent, found = with_latent_stem(shot, plain, estimate, rng)
    assert latent.settings.tallest_stem is True and TALLEST_STEM in latent.space.names
    sigma = shot.instrument.footprint_sigma_m
    start = latent_start(plain, estimate.u, latent.space, sigma)
    x, _ = latent.space.from_unbounded(start)
    values = latent.space.values(x)
    stand = plain.space.values(plain.space.from_unbounded(estimate.u[None, :])[0])
    for name in plain.space.names:  # the MAP's stand
        np.testing.assert_allclose(values[name], stand[name], rtol=1e-9)
    mapping = plain.log_posterior.mapping
    density_m2 = mapping.model_vectors(stand)[1]["density"] * 1e-4
    stem = values[TALLEST_STEM]
    _, survival = _mixture_grid(mapping, {k: np.atleast_1d(v) for k, v in stand.items()}, 0, stem)
    stems_in_disc = density_m2[0] * disc_area(sigma)
    np.testing.assert_allclose(np.exp(-stems_in_disc * survival), 0.5, rtol=1e-3)
    assert found.log_prob >= latent.log_posterior(start)[0, 0] - 1e-6


def test_a_canopy_too_short_for_two_storeys_is_searched_with_one_cohort(rng):
    """A 3 m shrub canopy spans fewer pulse widths than two storeys and a ground need:
    the two-cohort model is not searched, and the choice says why."""
    short = replace(SYNTHETIC_SHOTS["gedi-mixed"].params, height_mean=2.5, height_sd=0.3)
    obs = synthetic_shot(ShotRecipe(short), rng)
    quick = SamplerSettings(candidates=256, starts=4)  # the one-cohort MAP is not the subject
    settings = InversionSettings(discrepancy_model="observed", sampler=quick)
    problem, _, choice = choose_cohorts(obs, settings, rng)
    assert choice.chosen == 1 and list(choice.bic) == [1] and not choice.undecided
    assert 0.0 < choice.canopy_extent_m < STOREYS_RESOLVED_PULSE_WIDTHS * choice.pulse_width_m
    assert "cohort2_fraction" not in problem.space.names
