"""Priors, unbounded transforms and the priors file."""

import itertools

import numpy as np
import pytest
from scipy import integrate, stats

from lidarinv.inference import InversionSettings
from lidarinv.inference.model import coordinates
from lidarinv.inference.model.parameters import default_space
from lidarinv.inference.model.prior_table import UNBOUNDED_MAPS, PriorTable
from lidarinv.inference.model.priors import (
    LogUniform,
    TruncatedLogNormal,
    TruncatedNormal,
    Uniform,
    make_prior,
)
from lidarinv.inference.priors_file import read_priors_file

PRIORS = [
    Uniform(-2.0, 3.0),
    LogUniform(0.01, 20.0),
    TruncatedNormal(1.5, 0.5, 0.3, 4.0),
    TruncatedLogNormal(1.5, 0.3, 0.3, 5.0),
]


@pytest.mark.parametrize("prior", PRIORS, ids=lambda p: type(p).__name__)
def test_prior_density_is_normalised_and_zero_outside(prior):
    total, _ = integrate.quad(
        lambda x: np.exp(prior.log_pdf(x)), prior.lower, prior.upper, points=[1.0], limit=200
    )
    assert total == pytest.approx(1.0, rel=1e-6)
    assert prior.log_pdf(prior.lower - 1e-9) == -np.inf
    assert prior.log_pdf(prior.upper + 1e-9) == -np.inf
    assert prior.log_pdf(np.nan) == -np.inf


@pytest.mark.parametrize("unbounded", UNBOUNDED_MAPS)
@pytest.mark.parametrize("prior", PRIORS, ids=lambda p: type(p).__name__)
def test_transform_round_trip_and_jacobian(prior, unbounded):
    u = np.linspace(-6, 6, 25)
    x, log_jac = prior.from_unbounded(u, unbounded)
    assert np.all((x > prior.lower) & (x < prior.upper))
    np.testing.assert_allclose(prior.to_unbounded(x, unbounded), u, atol=1e-7)
    h = 1e-6
    step = prior.from_unbounded(u + h, unbounded)[0] - prior.from_unbounded(u - h, unbounded)[0]
    # near a bound the difference of two x keeps few digits: ~1e-16·|x|/h absolute
    width = prior.upper - prior.lower
    np.testing.assert_allclose(np.exp(log_jac), step / (2 * h), rtol=1e-5, atol=1e-9 * width)
    # far out in u the parameter stays at the bound and the log-density stays finite
    x_far, log_jac_far = prior.from_unbounded(np.array([-800.0, 800.0]), unbounded)
    assert np.all(np.isfinite(log_jac_far)) and np.all(np.isfinite(x_far))


def test_probit_map_makes_a_uniform_prior_standard_normal(rng):
    """Under the probit map a uniform prior is N(0, 1) in u: the log-density in u,
    log p(x(u)) + log|dx/du|, is the standard normal's."""
    prior = Uniform(0.2, 3.0)
    u = np.linspace(-7.0, 7.0, 29)
    x, log_jac = prior.from_unbounded(u, "probit")
    expected = -0.5 * u**2 - 0.5 * np.log(2 * np.pi)
    np.testing.assert_allclose(prior.log_pdf(x) + log_jac, expected, rtol=1e-12)


def test_unknown_unbounded_map_is_named():
    with pytest.raises(ValueError, match="unknown unbounded map 'tanh'"):
        PriorTable(PRIORS, "tanh")


def test_mixed_prior_table_matches_each_prior_column_by_column(rng):
    table = PriorTable(PRIORS)
    u = rng.normal(0.0, 4.0, (50, len(PRIORS)))
    u[0] = [-800.0, 800.0, -800.0, 800.0]
    x, log_jac = table.from_unbounded(u)
    x_out = np.column_stack([x[:, :2], x[:, 2:] * np.array([1.0, np.nan])])
    x_out[1] = [-2.5, 25.0, 0.2, 6.0]  # each outside its support
    log_pdf = table.log_pdf(x_out)
    for i, prior in enumerate(PRIORS):
        x_ref, log_jac_ref = prior.from_unbounded(u[:, i])
        np.testing.assert_allclose(x[:, i], x_ref, rtol=1e-13)
        np.testing.assert_allclose(log_jac[:, i], log_jac_ref, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(log_pdf[:, i], prior.log_pdf(x_out[:, i]), rtol=1e-12)
    assert np.all(log_pdf[1] == -np.inf) and np.all(log_pdf[:, 3] == -np.inf)


@pytest.mark.parametrize("prior", PRIORS, ids=lambda p: type(p).__name__)
def test_prior_samples_follow_the_density(prior, rng):
    draws = prior.sample(rng, 20000)
    assert np.all((draws >= prior.lower) & (draws <= prior.upper))
    edges = np.linspace(prior.lower, prior.upper, 11)
    counts, _ = np.histogram(draws, edges)
    expected = [
        integrate.quad(lambda x: np.exp(prior.log_pdf(x)), a, b)[0] * draws.size
        for a, b in itertools.pairwise(edges)
    ]
    assert np.all(np.abs(counts - expected) < 5 * np.sqrt(np.asarray(expected)) + 5)


def test_bad_prior_specifications_are_named():
    with pytest.raises(ValueError, match="lower < upper"):
        Uniform(2.0, 1.0)
    with pytest.raises(ValueError, match="lower > 0"):
        LogUniform(0.0, 1.0)
    with pytest.raises(ValueError, match="unknown prior kind"):
        make_prior({"kind": "cauchy", "lower": 0, "upper": 1})


def test_priors_file_sets_the_ground_prior_width(tmp_path):
    path = tmp_path / "priors.toml"
    path.write_text("[ground]\nprior_sd = 0.3\n[rho_ratio]\nfixed = 1.5\n")
    settings = InversionSettings.from_priors_file(path)
    assert settings.ground_prior_sd_m == 0.3
    assert "ground" not in settings.priors and "rho_ratio" in settings.priors


def test_priors_file_chooses_the_discrepancy(tmp_path):
    path = tmp_path / "priors.toml"
    path.write_text('[discrepancy]\nmodel = "observed"\neta = 0.3\n')
    settings = InversionSettings.from_priors_file(path)
    assert settings.discrepancy_model == "observed" and settings.discrepancy == 0.3
    path.write_text("[discrepancy]\ncount = 32\n")
    settings = InversionSettings.from_priors_file(path)
    assert settings.discrepancy_model == "realisations" and settings.realisations.count == 32
    assert "discrepancy" not in settings.priors


def test_priors_file_overrides_fix_and_free(tmp_path, nuisance_priors):
    path = tmp_path / "priors.toml"
    path.write_text(
        '[top_height]\nkind = "uniform"\nlower = 5.0\nupper = 40.0\n\n'
        "[understory_lai]\nfixed = 0.0\n\n[crown_radius_slope]\nfree = true\n"
    )
    space = default_space(nuisance_priors, read_priors_file(path))
    assert space.by_name["top_height"].prior == Uniform(5.0, 40.0)
    assert "understory_lai" not in space.names
    assert "crown_radius_slope" in space.names
    values = space.values(space.sample_prior(np.random.default_rng(1), 4))
    np.testing.assert_array_equal(values["understory_lai"], 0.0)


@pytest.mark.parametrize(
    "text, message",
    [
        ("[canopy_colour]\nfixed = 1\n", "unknown parameter"),
        ("[cover]\nkind = 'uniform'\nlower = 1\n", r"\[cover\] a uniform prior needs \['upper'\]"),
        (
            "[cover]\nprior = {kind = 'uniform', lower = 0, upper = 1}\n",
            r"\[cover\].*not \['prior'\]",
        ),
        (
            "[pai]\nkind = 'log-uniform'\nlower = 'one'\nupper = 9\n",
            r"\[pai\].*lower must be a number",
        ),
        (
            "[top_height]\nkind = 'truncated-normal'\nmean = 20\nsd = 2\nlower = 10\nupper = 30\nmedian = 3\n",
            r"takes kind and \['mean', 'sd', 'lower', 'upper'\]",
        ),
        ("[cover\n", "not valid TOML"),
        ("[favd]\nlower = 2.0\nupper = 1.0\n", "lower < upper"),
        ("[favd]\nmedian = 1.0\n", "takes lower and upper"),
        ("[ground]\nprior_sd = -0.1\n", "positive number of metres"),
        ("[ground]\nsd = 0.1\n", "takes prior_sd"),
        ("[discrepancy]\nmodel = 'kriging'\n", "is not one of"),
        ("[discrepancy]\neta = -1\n", "eta must be"),
        ("[discrepancy]\ncount = 1\n", "count must be"),
        ("[discrepancy]\nshrinkage = 0.1\n", "takes model, eta and count"),
    ],
)
def test_priors_file_errors_name_the_problem(tmp_path, text, message):
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(ValueError, match=message):
        InversionSettings.from_priors_file(path)


def test_joint_cover_pai_coordinates_round_trip_with_exact_jacobian():
    rng = np.random.default_rng(4)
    cover = rng.uniform(0.001, 0.99, 200)
    pai = np.exp(rng.uniform(np.log(0.01), np.log(15.0), 200))
    s, t = coordinates.from_cover_pai(cover, pai)
    back_cover, back_pai, log_jac = coordinates.to_cover_pai(s, t)
    np.testing.assert_allclose(back_cover, cover, rtol=1e-12)
    np.testing.assert_allclose(back_pai, pai, rtol=1e-12)
    h = 1e-6
    d = {
        (k, i): (coordinates.to_cover_pai(s + h * (i == 0), t + h * (i == 1))[k]
                 - coordinates.to_cover_pai(s - h * (i == 0), t - h * (i == 1))[k]) / (2 * h)
        for k in (0, 1) for i in (0, 1)
    }  # fmt: skip
    det = d[0, 0] * d[1, 1] - d[0, 1] * d[1, 0]
    np.testing.assert_allclose(log_jac, np.log(np.abs(det)), atol=1e-6)
    assert np.all(np.isnan(coordinates.from_cover_pai(np.array([0.0, 1.0, 0.5]), 1.0)[0][:2]))


COVER_PAI_BOUNDS = ((0.001, 0.99), (0.01, 15.0))


def test_ridge_range_is_where_cover_and_pai_stay_in_bounds():
    t = np.linspace(-12.0, 12.0, 240_001)
    for s in (-6.0, -2.5, -0.5, 1.0, 1.3):
        cover, pai, _ = coordinates.to_cover_pai(np.full_like(t, s), t)
        (c_lo, c_hi), (p_lo, p_hi) = COVER_PAI_BOUNDS
        inside = (cover >= c_lo) & (cover <= c_hi) & (pai >= p_lo) & (pai <= p_hi)
        low, high = coordinates.ridge_range(s, *COVER_PAI_BOUNDS)
        np.testing.assert_allclose([low, high], [t[inside].min(), t[inside].max()], atol=2e-4)
    # more interception than cover 0.99 with PAI 15 allows, or less than cover 0.001 with
    # PAI 0.01: no t is left
    for s in (np.log(5.0), -7.0):
        assert np.all(np.isnan(coordinates.ridge_range(s, *COVER_PAI_BOUNDS)))


def test_bounded_ridge_coordinates_round_trip_with_exact_jacobian():
    rng = np.random.default_rng(6)
    (c_lo, c_hi), (p_lo, p_hi) = COVER_PAI_BOUNDS
    cover = rng.uniform(c_lo, c_hi, 300)
    pai = np.exp(rng.uniform(np.log(p_lo), np.log(p_hi), 300))
    s, v = coordinates.from_cover_pai_bounded(cover, pai, *COVER_PAI_BOUNDS)
    back_cover, back_pai, log_jac = coordinates.to_cover_pai_bounded(s, v, *COVER_PAI_BOUNDS)
    np.testing.assert_allclose(back_cover, cover, rtol=1e-11)
    np.testing.assert_allclose(back_pai, pai, rtol=1e-11)
    h = 1e-6
    to = lambda ds, dv: coordinates.to_cover_pai_bounded(s + ds, v + dv, *COVER_PAI_BOUNDS)
    d = {
        (k, i): (to(h * (i == 0), h * (i == 1))[k] - to(-h * (i == 0), -h * (i == 1))[k]) / (2 * h)
        for k in (0, 1) for i in (0, 1)
    }  # fmt: skip
    det = d[0, 0] * d[1, 1] - d[0, 1] * d[1, 0]
    np.testing.assert_allclose(log_jac, np.log(np.abs(det)), atol=1e-5)
    # every ridge position of a feasible s lands inside the bounds, walls included
    s_any, v_any = rng.uniform(-8.0, 2.0, 4000), rng.normal(0.0, 15.0, 4000)
    cover, pai, _ = coordinates.to_cover_pai_bounded(s_any, v_any, *COVER_PAI_BOUNDS)
    feasible = np.isfinite(cover)
    assert feasible.mean() > 0.8
    assert np.all((cover[feasible] >= c_lo * (1 - 1e-12)) & (cover[feasible] <= c_hi + 1e-12))
    assert np.all((pai[feasible] >= p_lo * (1 - 1e-9)) & (pai[feasible] <= p_hi * (1 + 1e-9)))


def test_bounded_ridge_coordinates_keep_the_cover_pai_prior(nuisance_priors):
    """The prior carried to (s, v) still integrates to one."""
    s, v = np.linspace(-14.0, 5.0, 1500), np.linspace(-40.0, 40.0, 1500)
    grid_s, grid_v = np.meshgrid(s, v, indexing="ij")
    cover, pai, log_jac = coordinates.to_cover_pai_bounded(grid_s, grid_v, *COVER_PAI_BOUNDS)
    space = default_space(nuisance_priors)
    with np.errstate(invalid="ignore"):
        log_density = (
            space.by_name["cover"].prior.log_pdf(cover) + space.by_name["pai"].prior.log_pdf(pai)
            + log_jac
        )  # fmt: skip
    density = np.exp(np.where(np.isfinite(log_density), log_density, -np.inf))
    total = np.trapezoid(np.trapezoid(density, v, axis=1), s)
    assert total == pytest.approx(1.0, abs=1e-3)


def test_joint_coordinates_keep_the_cover_pai_prior(nuisance_priors):
    """The prior on cover and PAI, carried to (s, t) with the Jacobian, still integrates
    to one: only the sampling coordinates change, not the posterior."""
    s, t = np.linspace(-14.0, 5.0, 1500), np.linspace(-9.0, 9.0, 1500)
    grid_s, grid_t = np.meshgrid(s, t, indexing="ij")
    cover, pai, log_jac = coordinates.to_cover_pai(grid_s, grid_t)
    space = default_space(nuisance_priors)
    density = np.exp(
        space.by_name["cover"].prior.log_pdf(cover) + space.by_name["pai"].prior.log_pdf(pai)
        + log_jac
    )  # fmt: skip
    total = np.trapezoid(np.trapezoid(density, t, axis=1), s)
    assert total == pytest.approx(1.0, abs=1e-3)


def test_parameter_space_samples_cover_and_pai_jointly_only_when_both_are_free(nuisance_priors):
    space = default_space(nuisance_priors)
    rng = np.random.default_rng(8)
    x = space.sample_prior(rng, 200)
    top, sd = (x[:, space.names.index(k)] for k in ("top_height", "height_sd"))
    x = x[top > 2.0 * sd][:50]  # a stand (the crown-base coordinate needs a mean height)
    u = space.to_unbounded(x)
    back, _ = space.from_unbounded(u)
    np.testing.assert_allclose(back, x, rtol=1e-10)
    c, a = space.names.index("cover"), space.names.index("pai")
    bounds = ((0.001, 0.99), (0.01, 15.0))  # the default priors' supports
    np.testing.assert_allclose(
        u[:, [c, a]],
        np.column_stack(coordinates.from_cover_pai_bounded(x[:, c], x[:, a], *bounds)),
    )
    per_parameter = default_space(nuisance_priors).with_changes({"cover": {"fixed": 0.5}})
    x = per_parameter.sample_prior(rng, 5)
    u = per_parameter.to_unbounded(x)
    i = per_parameter.names.index("pai")
    np.testing.assert_allclose(u[:, i], per_parameter.by_name["pai"].prior.to_unbounded(x[:, i]))


def test_parameter_space_under_the_probit_map(nuisance_priors):
    """The same values round-trip through either map; under probit a free uniform
    parameter's coordinate is its prior quantile's normal score; chains are labelled by
    the map, so one sampled under the other map is not resumed into."""
    logit_space = default_space(nuisance_priors)
    probit_space = default_space(nuisance_priors, unbounded="probit")
    x = logit_space.sample_prior(np.random.default_rng(4), 100)
    top, sd = (x[:, logit_space.names.index(k)] for k in ("top_height", "height_sd"))
    x = x[top > 2.0 * sd][:40]  # a stand (the crown-base coordinate needs a mean height)
    u = probit_space.to_unbounded(x)
    back, _ = probit_space.from_unbounded(u)
    np.testing.assert_allclose(back, x, rtol=1e-10)
    i = probit_space.names.index("understory_height")
    prior = probit_space.by_name["understory_height"].prior
    quantile = (x[:, i] - prior.lower) / (prior.upper - prior.lower)
    np.testing.assert_allclose(u[:, i], stats.norm.ppf(quantile), rtol=1e-10)
    assert probit_space.signature() != logit_space.signature()
    assert "probit" in probit_space.with_changes({"cover": {"fixed": 0.5}}).signature()
