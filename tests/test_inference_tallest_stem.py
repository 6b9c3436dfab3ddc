"""A footprint conditioned on its tallest stem: the latent's law against explicit stands,
its inverse, the posterior that carries it, and the discrepancy it leaves."""

import numpy as np
import pytest
from scipy import stats

from forward.realise import realise
from forward.stand import Stand
from lidarinv.inference import InversionSettings, build_problem
from lidarinv.inference import realisations as realisations_module
from lidarinv.inference.posterior import LogPosterior
from lidarinv.inference.realisations import realisation_residuals
from lidarinv.inference.stand_mapping import (
    TALLEST_STEM,
    TALLEST_STEM_POSITION,
    StandMapping,
    default_template,
)
from lidarinv.inference.synthetic import SYNTHETIC_SHOTS, synthetic_shot, tallest_stem_within

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


def test_latent_stem_has_the_law_of_the_tallest_stem_of_explicit_stands(mapping, rng):
    """H drawn through a uniform latent matches the tallest stem within 2σf of the centre
    of explicit Poisson stands, and so does the uniform position (two-sample KS); they
    condition the model vectors: cohort 1 capped at H, the stem's footprint weight of
    apex trees, on average the disc's weight over its area."""
    n = 1500
    values = _values(n, **{TALLEST_STEM: 0.0, TALLEST_STEM_POSITION: 0.0})
    values[TALLEST_STEM] = rng.uniform(size=n)
    values[TALLEST_STEM_POSITION] = rng.uniform(size=n)
    vectors, derived = mapping.model_vectors(values)
    latent = derived["tallest_stem"]
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
            for _ in range(n)
        ]
    )
    assert stats.ks_2samp(latent, explicit[:, 0]).pvalue > 0.01
    assert stats.kstest(explicit[:, 1], "uniform").pvalue > 0.01
    assert np.all(latent <= VALUES["top_height"] + 1e-9)
    column = dict(zip(mapping.model_free, vectors.T))
    np.testing.assert_allclose(column["height_cap"], latent, rtol=1e-12)
    weight = np.exp(-2.0 * values[TALLEST_STEM_POSITION]) / (2 * np.pi * SIGMA_F**2)
    np.testing.assert_allclose(column["apex_density"], 1e4 * weight, rtol=1e-12)
    area = np.pi * (2.0 * SIGMA_F) ** 2
    mean = np.mean(column["apex_density"])
    assert mean == pytest.approx(1e4 * (1 - np.exp(-2.0)) / area, rel=0.05)


def test_quantile_inverts_the_draw(mapping, rng):
    n = 200
    values = _values(n, **{TALLEST_STEM: 0.0, TALLEST_STEM_POSITION: 0.3})
    values[TALLEST_STEM] = rng.uniform(0.01, 1.0, n)
    _, derived = mapping.model_vectors(values)
    values["density_m2"] = derived["density"] * 1e-4
    back = mapping.tallest_stem_quantile(values, derived["tallest_stem"])
    np.testing.assert_allclose(back, values[TALLEST_STEM], rtol=1e-9)
    # a disc without a stem: below the chance of none, and no stem in the model either
    none = mapping.tallest_stem_quantile(values, np.zeros(n))
    stems = derived["density"] * 1e-4 * mapping.tallest_stem_area
    assert np.all((none > 0) & (none < np.exp(-stems)))
    values[TALLEST_STEM] = none
    vectors, derived = mapping.model_vectors(values)
    assert np.all(derived["tallest_stem"] == 0.0)
    assert np.all(vectors[:, mapping.model_free.index("apex_density")] == 0.0)


@pytest.fixture(scope="module")
def shot():
    return synthetic_shot(SYNTHETIC_SHOTS["gedi-mixed"], np.random.default_rng(11))


@pytest.fixture(scope="module")
def problem(shot):
    return build_problem(shot, InversionSettings(tallest_stem=True))


def test_the_posterior_carries_the_latent_and_rejects_it_outside_0_1(problem, shot):
    space = problem.space
    assert {TALLEST_STEM, TALLEST_STEM_POSITION} <= set(space.names)
    assert problem.log_posterior.mapping.conditioned
    row = np.array([shot.truth.get(name, 0.5) for name in space.names])
    x = np.repeat(row[None, :], 4, axis=0)
    x[:, space.names.index(TALLEST_STEM)] = [0.3, 0.9, -0.1, 1.5]
    log_post = problem.log_posterior.evaluate(x).log_posterior
    assert np.all(np.isfinite(log_post[:2])) and np.all(log_post[2:] == -np.inf)
    unconditioned = build_problem(shot, InversionSettings())
    with pytest.raises(ValueError, match=TALLEST_STEM):
        LogPosterior(space, unconditioned.log_posterior.mapping, *_rest(unconditioned))


def _rest(problem):
    post = problem.log_posterior
    return post.model, post.data, post.shot_factor, post.discrepancy


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
    path.write_text("[tallest_stem_quantile]\nfree = true\n")
    settings = InversionSettings.from_priors_file(path)
    assert settings.tallest_stem
    assert TALLEST_STEM in build_problem(shot, settings).space.names
    path.write_text("[tallest_stem_quantile]\nfixed = 0.5\n")
    fixed = build_problem(shot, InversionSettings.from_priors_file(path))
    assert TALLEST_STEM not in fixed.space.names and fixed.log_posterior.mapping.conditioned
    assert TALLEST_STEM_POSITION in fixed.space.names
