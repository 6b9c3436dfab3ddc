"""Sampling coordinates (crown base, ground centroid): exact inverses, exact Jacobians,
priors unchanged."""

import numpy as np
import pytest
from jacobian_check import assert_exact_jacobian

from lidarinv.inference.model import coordinates, top_coordinates
from lidarinv.inference.model.parameters import default_space
from lidarinv.inference.model.priors import LogUniform, Uniform

BOUNDS = (0.1, 1.0)


def test_crown_base_coordinate_round_trip_with_exact_jacobian():
    rng = np.random.default_rng(3)
    ratio = rng.uniform(0.1, 0.999, 300)
    mean = rng.uniform(0.5, 40.0, 300)
    b = coordinates.crown_base_from_ratio(ratio, mean, BOUNDS)
    back, log_jac = coordinates.ratio_from_crown_base(b, mean, BOUNDS)
    np.testing.assert_allclose(back, ratio, rtol=1e-12)
    h = 1e-6
    slope = (
        coordinates.ratio_from_crown_base(b + h, mean, BOUNDS)[0]
        - coordinates.ratio_from_crown_base(b - h, mean, BOUNDS)[0]
    ) / (2 * h)
    np.testing.assert_allclose(log_jac, np.log(np.abs(slope)), atol=1e-6)
    # no stand (mean height ≤ 0) or a ratio outside the prior: no coordinate
    bad = coordinates.crown_base_from_ratio(np.array([0.5, 1.0, 0.05]), [-1.0, 9.0, 9.0], BOUNDS)
    assert np.all(np.isnan(bad))
    assert np.all(np.isnan(coordinates.ratio_from_crown_base(np.zeros(2), [0.0, -3.0])[0]))


def test_crown_base_coordinate_is_the_log_crown_base_away_from_its_upper_end():
    """With ℓ₁ = 1 and deep crowns (B ≪ B₁), b is ln B: the ridge B = const is straight."""
    mean = np.array([5.0, 20.0, 60.0])
    ratio = np.full(3, 0.99)
    b = coordinates.crown_base_from_ratio(ratio, mean, BOUNDS)
    np.testing.assert_allclose(b, np.log((1.0 - ratio) * mean), atol=0.012)


def test_crown_base_coordinate_spans_the_prior_without_leaving_it():
    b = np.linspace(-60.0, 60.0, 2001)
    ratio, log_jac = coordinates.ratio_from_crown_base(b, 12.0, BOUNDS)
    assert np.all((ratio >= BOUNDS[0]) & (ratio <= BOUNDS[1]))
    assert np.all(np.isfinite(log_jac))
    assert ratio[0] == pytest.approx(BOUNDS[1]) and ratio[-1] == pytest.approx(BOUNDS[0])


@pytest.mark.parametrize("mean_height", [1.5, 15.0, 60.0])
def test_crown_base_coordinate_keeps_the_ratio_prior(mean_height, nuisance_priors):
    """The ratio's prior carried to the crown-base coordinate with the Jacobian integrates
    to one."""
    prior = default_space(nuisance_priors).by_name["crown_length_ratio"].prior
    form = prior.form()
    b = np.linspace(np.log(mean_height) - 40.0, np.log(mean_height) + 40.0, 400_001)
    ratio, log_jac = coordinates.ratio_from_crown_base(b, mean_height, (form.lower, form.upper))
    with np.errstate(invalid="ignore"):
        density = np.exp(prior.log_pdf(ratio) + log_jac)
    assert np.trapezoid(density, b) == pytest.approx(1.0, abs=1e-4)


@pytest.mark.parametrize("log_scale", [False, True])
def test_height_sd_cap_keeps_every_mean_height_positive_with_exact_jacobian(log_scale):
    rng = np.random.default_rng(8)
    lower, upper = 0.1, 10.0
    w_lower, w_upper = (np.log(lower), np.log(upper)) if log_scale else (lower, upper)
    top = rng.uniform(1.0, 40.0, 400)
    sd = np.exp(rng.uniform(w_lower, w_upper, 400)) if log_scale else rng.uniform(lower, upper, 400)
    capped, log_jac = top_coordinates.height_sd_capped(sd, top, w_lower, w_upper, log_scale, 2.0)
    assert np.all(top - 2.0 * capped > 0) and np.all(capped >= lower)
    back = top_coordinates.height_sd_uncapped(capped, top, w_lower, w_upper, log_scale, 2.0)
    np.testing.assert_allclose(back, sd, rtol=1e-12)
    h = 1e-7 * sd
    slope = (
        top_coordinates.height_sd_capped(sd + h, top, w_lower, w_upper, log_scale, 2.0)[0]
        - top_coordinates.height_sd_capped(sd - h, top, w_lower, w_upper, log_scale, 2.0)[0]
    ) / (2 * h)
    np.testing.assert_allclose(log_jac, np.log(slope), atol=1e-6)
    # a top below twice the prior's smallest sd admits none
    assert np.isnan(
        top_coordinates.height_sd_capped(0.5, 0.15, w_lower, w_upper, log_scale, 2.0)[0]
    )


BOTH = ("cover-pai", "crown-base")


def test_space_samples_the_crown_base_of_the_mean_tree(nuisance_priors):
    space = default_space(nuisance_priors, ridges=BOTH)
    assert "crown-base" in space.signature()
    r, top, sd = (space.names.index(k) for k in ("crown_length_ratio", "top_height", "height_sd"))
    x = space.sample_prior(np.random.default_rng(5), 400)
    x = x[x[:, top] > 2.0 * x[:, sd]][:50]
    u = space.to_unbounded(x)
    mean = x[:, top] - 2.0 * x[:, sd]
    expected = coordinates.crown_base_from_ratio(x[:, r], mean, (0.1, 1.0))
    np.testing.assert_allclose(u[:, r], expected, rtol=1e-12)
    back, _ = space.from_unbounded(u)
    np.testing.assert_allclose(back, x, rtol=1e-10)
    # no move leaves the prior: the largest sd at the smallest top keeps a mean height
    u_edge = u[:1].copy()
    u_edge[0, sd], u_edge[0, top], u_edge[0, r] = 30.0, -30.0, 30.0
    x_edge, log_jac = space.from_unbounded(u_edge)
    assert np.isfinite(space.log_prior(x_edge)[0]) and np.isfinite(log_jac[0])
    assert x_edge[0, top] - 2.0 * x_edge[0, sd] > 0


def test_crown_base_uses_a_fixed_height_and_can_be_turned_off(nuisance_priors):
    fixed_top = default_space(nuisance_priors, ridges=BOTH)
    fixed_top = fixed_top.with_changes({"top_height": {"fixed": 25.0}})
    r, sd = fixed_top.names.index("crown_length_ratio"), fixed_top.names.index("height_sd")
    x = fixed_top.sample_prior(np.random.default_rng(6), 20)
    x[:, sd] = np.minimum(x[:, sd], 10.0)
    u = fixed_top.to_unbounded(x)
    expected = coordinates.crown_base_from_ratio(x[:, r], 25.0 - 2.0 * x[:, sd], (0.1, 1.0))
    np.testing.assert_allclose(u[:, r], expected)
    assert "crown-base" in default_space(nuisance_priors).signature()  # on by default
    per_parameter = default_space(nuisance_priors, ridges=("cover-pai",))
    assert "crown-base" not in per_parameter.signature()
    r = per_parameter.names.index("crown_length_ratio")
    x = per_parameter.sample_prior(np.random.default_rng(7), 5)
    prior = per_parameter.by_name["crown_length_ratio"].prior
    np.testing.assert_allclose(per_parameter.to_unbounded(x)[:, r], prior.to_unbounded(x[:, r]))
    fixed_ratio = default_space(nuisance_priors, ridges=BOTH)
    fixed_ratio = fixed_ratio.with_changes({"crown_length_ratio": {"fixed": 0.4}})
    assert "crown-base" not in fixed_ratio.signature()
    with pytest.raises(ValueError, match="unknown sampling coordinates"):
        default_space(nuisance_priors, ridges=("crown-tip",))


@pytest.mark.parametrize(
    ("lai", "height", "ratio"), [(0.4, 0.5, 1.5), (2.5, 2.8, 0.6), (1e-6, 1.0, 3.0)]
)
def test_understory_centroid_is_the_first_moment_of_the_return(lai, height, ratio):
    """Against quadrature of the convention's profile: ρv·dP over the layer, ρg·P(0) at 0."""
    slope = coordinates.INTERCEPTION_SLOPE
    gap = lambda z: np.exp(-slope * lai * (height - z) / height)
    z = np.linspace(0.0, height, 200_001)
    canopy = ratio * np.gradient(gap(z), z)  # ρv/ρg times dP/dz
    moment = np.trapezoid(z * canopy, z)
    total = np.trapezoid(canopy, z) + gap(0.0)
    expected = moment / total
    got = coordinates.understory_centroid(lai, height, ratio)
    assert got == pytest.approx(expected, rel=1e-6, abs=1e-12)
    assert 0.0 < got < height
    assert coordinates.understory_centroid(0.0, height, ratio) == 0.0


CENTROID = ("cover-pai", "crown-base", "ground-centroid")


def test_space_samples_the_ground_centroid_with_exact_jacobian(nuisance_priors):
    """Round trip, and log|det ∂x/∂u| of all three coordinates against finite differences."""
    space = default_space(nuisance_priors, ridges=CENTROID)
    assert "ground-centroid" in space.signature()
    g, lai, height, ratio = (
        space.names.index(k)
        for k in ("ground_elevation", "understory_lai", "understory_height", "rho_ratio")
    )
    x = space.sample_prior(np.random.default_rng(8), 200)
    u = space.to_unbounded(x)
    finite = np.isfinite(u).all(axis=1)
    x, u = x[finite][:20], u[finite][:20]
    centroid = x[:, g] + coordinates.understory_centroid(x[:, lai], x[:, height], x[:, ratio])
    plain = default_space(nuisance_priors, ridges=("cover-pai", "crown-base"))
    assert not np.allclose(u[:, g], plain.to_unbounded(x)[:, g])
    # the ground column holds the centroid, on the ground prior's map widened by 3 m
    prior = nuisance_priors["ground_elevation"]
    widened = -1.0 + (centroid + 1.0) * 2.0 / 5.0
    np.testing.assert_allclose(u[:, g], prior.to_unbounded(widened), rtol=1e-10)
    back, log_jac = space.from_unbounded(u)
    np.testing.assert_allclose(back, x, rtol=1e-10, atol=1e-12)
    assert_exact_jacobian(space, u[:5], log_jac[:5])


def test_ground_centroid_reaches_the_whole_ground_prior(nuisance_priors):
    """The top of the ground prior under the tallest, densest understory maps to a finite
    coordinate; below the prior's floor the prior is −inf, not an error."""
    space = default_space(nuisance_priors, ridges=CENTROID)
    names = space.names
    x = space.sample_prior(np.random.default_rng(9), 1)
    x[0, names.index("ground_elevation")] = 1.0 - 1e-9  # the prior's upper bound is 1 m
    x[0, names.index("understory_lai")] = 3.0
    x[0, names.index("understory_height")] = 3.0 - 1e-9
    x[0, names.index("rho_ratio")] = 4.9
    assert np.isfinite(space.to_unbounded(x)[0, names.index("ground_elevation")])
    u = space.to_unbounded(x)
    u[0, names.index("ground_elevation")] = -40.0  # centroid at the floor, ground below it
    low, _ = space.from_unbounded(u)
    assert low[0, names.index("ground_elevation")] < -1.0
    assert space.log_prior(low)[0] == -np.inf


def test_ground_centroid_needs_an_understory(nuisance_priors):
    space = default_space(nuisance_priors, ridges=CENTROID)
    bare = space.with_changes({"understory_lai": {"fixed": 0.0}})
    assert "ground-centroid" not in bare.signature()
    fixed_ground = space.with_changes({"ground_elevation": {"fixed": 0.0}})
    assert "ground-centroid" not in fixed_ground.signature()
    assert "ground-centroid" in default_space(nuisance_priors).signature()  # on by default
    assert "ground-centroid" not in default_space(nuisance_priors, ridges=BOTH).signature()


@pytest.mark.parametrize(
    "changes",
    [
        {},
        # lower cover and PAI bounds that bind on sparse canopies (the sparse branch)
        {"cover": {"prior": Uniform(0.1, 0.95)}, "pai": {"prior": LogUniform(0.5, 15.0)}},
        # fixed inputs of the crown-base and centroid maps
        {"height_sd": {"fixed": 2.0}, "understory_lai": {"fixed": 0.4}},
        {"top_height": {"fixed": 22.0}, "rho_ratio": {"fixed": 1.5}},
    ],
)
def test_compiled_ridge_maps_equal_the_numpy_reference(changes, nuisance_priors):
    """The compiled maps give the numpy maps' values and Jacobians, and NaN where they do
    (no t within the bounds, no mean height, NaN coordinates), near the prior and far out."""
    space = default_space(nuisance_priors, overrides=changes)
    rng = np.random.default_rng(11)
    x = space.sample_prior(rng, 3000)
    u = space.to_unbounded(x)
    u = np.where(np.isfinite(u), u, 0.0)
    u[1000:] += rng.normal(0.0, 4.0, u[1000:].shape)  # well beyond the prior's bounds too
    u[::97, 0] = np.nan
    u[1:4, 0], u[4:7, 1] = [-746.0, 746.0, 1e6], [-1e6, 800.0, 0.0]  # y = 0, y = inf
    compiled, jac = space.from_unbounded(u, backend="numba")
    with np.errstate(all="ignore"):  # as the sampler calls it
        reference, jac_reference = space.from_unbounded(u, backend="numpy")
    np.testing.assert_allclose(compiled, reference, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(jac, jac_reference, rtol=1e-12, atol=1e-10)
    assert np.isnan(compiled).any() and np.isfinite(compiled[:1000]).mean() > 0.9


def test_space_samples_the_gap_above_the_tallest_stem_with_exact_jacobian(nuisance_priors):
    """With the latent tallest stem, the top height's column holds ln(top − H): round
    trip and log|det ∂x/∂u| of all four coordinates against finite differences; prior
    candidates put the stem within the stand's height range or the metre below it."""
    space = default_space(nuisance_priors, tallest_stem=True)
    assert "tallest-stem" in space.signature()
    top, stem, sd = (
        space.names.index(k) for k in ("top_height", "tallest_stem_height", "height_sd")
    )
    x = space.sample_prior(np.random.default_rng(12), 200)
    lowest = x[:, top] - np.minimum(4.0 * x[:, sd], x[:, top])  # and a metre for none
    assert np.all((x[:, stem] < x[:, top]) & (x[:, stem] >= lowest - 1.0))
    u = space.to_unbounded(x)
    x, u = x[np.isfinite(u).all(axis=1)][:20], u[np.isfinite(u).all(axis=1)][:20]
    np.testing.assert_allclose(u[:, top], np.log(x[:, top] - x[:, stem]), rtol=1e-12)
    back, log_jac = space.from_unbounded(u)
    np.testing.assert_allclose(back, x, rtol=1e-10, atol=1e-12)
    assert_exact_jacobian(space, u[:5], log_jac[:5])
    plain = default_space(nuisance_priors, tallest_stem=True, ridges=CENTROID)
    assert "tallest-stem" not in plain.signature()
    np.testing.assert_allclose(plain.from_unbounded(plain.to_unbounded(x))[0], x, rtol=1e-10)
