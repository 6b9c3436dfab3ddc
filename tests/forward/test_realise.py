"""Random explicit stands and the derived stand quantities they must agree with."""

import numpy as np
import pytest

from forward import derived
from forward.height_families import height_distribution
from forward.realise import draw_heights, realise, scene_extras
from forward.stand_params import StandParams

PARAMS = StandParams(
    density=800.0,
    height_mean=16.0,
    height_sd=4.0,
    shape_mix={"cone": 0.4, "ellipsoid": 0.6},
    cohort2_fraction=0.3,
    cohort2_height_mean=5.0,
    cohort2_height_sd=1.0,
    cohort2_shape_mix="hemi-ellipsoid",
    crown_length_ratio=0.5,
    crown_radius_intercept=0.3,
    crown_radius_slope=0.08,
    favd=0.7,
    favd_ratio={"hemi-ellipsoid": 1.5},
    understory_height=1.5,
    understory_lai=0.4,
)


@pytest.mark.parametrize("family", ["truncnorm", "weibull"])
def test_heights_by_inverse_cdf_are_scipys_draws(family):
    """One cohort: the closed-form quantile of the generator's uniforms gives the very
    heights scipy's ``rvs`` draws from the same generator."""
    params = StandParams(density=500.0, height_family=family, height_mean=16.0, height_sd=4.0)
    heights, _ = draw_heights(params, 500, np.random.default_rng(4))
    law = height_distribution(family, 16.0, 4.0, params.height_truncation)
    rng = np.random.default_rng(4)
    rng.choice(1, size=500, p=[1.0])  # the cohort draw comes first
    np.testing.assert_allclose(heights, law.rvs(size=500, random_state=rng), rtol=1e-12)


def test_poisson_realisation_marks_follow_the_parameters():
    rng = np.random.default_rng(11)
    stand = realise(PARAMS, 500.0, rng)  # 25 ha: 20 000 stems on average
    n_mean = PARAMS.density_per_m2 * 500.0**2
    assert abs(stand.n_trees - n_mean) < 4 * np.sqrt(n_mean)
    assert stand.x.min() >= 0 and stand.x.max() <= 500 and stand.y.max() <= 500
    low = stand.shape == 2  # hemi-ellipsoids: cohort 2 only
    assert low.mean() == pytest.approx(0.3, abs=4 * np.sqrt(0.21 / stand.n_trees))
    assert stand.height[low].mean() == pytest.approx(5.0, abs=0.05)
    np.testing.assert_allclose(stand.favd[low], 1.05)
    np.testing.assert_allclose(stand.crown_length, 0.5 * stand.height)
    # crown volume and leaf area per hectare against their expectations
    area_ha = 500.0**2 / 1e4
    assert stand.crown_volume.sum() / area_ha == pytest.approx(
        derived.crown_volume_per_ha(PARAMS), rel=0.02
    )
    lai = stand.leaf_area.sum() / 500.0**2 + PARAMS.understory_lai
    assert lai == pytest.approx(derived.leaf_area_index(PARAMS), rel=0.02)
    assert np.mean(stand.height) == pytest.approx(derived.mean_height(PARAMS), rel=0.01)


def test_canopy_cover_matches_a_rasterised_realisation():
    rng = np.random.default_rng(12)
    side = 200.0
    stand = realise(PARAMS, side, rng)
    grid = (np.arange(200) + 0.5) * side / 200
    gx, gy = np.meshgrid(grid, grid)
    covered = np.zeros(gx.shape, bool)
    for x, y, r in zip(stand.x, stand.y, stand.crown_radius):
        covered |= (gx - x) ** 2 + (gy - y) ** 2 < r * r
    # edge trees outside the plot are missing: compare away from the border
    inner = (gx > 10) & (gx < side - 10) & (gy > 10) & (gy < side - 10)
    assert covered[inner].mean() == pytest.approx(derived.canopy_cover(PARAMS), abs=0.03)


def test_expected_tallest_tree_and_dominant_height():
    rng = np.random.default_rng(13)
    diameter = 25.0
    tallest = []
    for _ in range(400):
        stand = realise(PARAMS, diameter, rng)
        inside = (stand.x - 12.5) ** 2 + (stand.y - 12.5) ** 2 <= 12.5**2
        tallest.append(stand.height[inside].max(initial=0.0))
    se = np.std(tallest) / np.sqrt(len(tallest))
    assert np.mean(tallest) == pytest.approx(
        derived.expected_max_height(PARAMS, diameter), abs=4 * se
    )
    big = realise(PARAMS, 300.0, rng)
    top = np.sort(big.height)[-(100 * 9) :]  # 100 per ha over 9 ha
    assert derived.dominant_height(PARAMS) == pytest.approx(top.mean(), abs=0.3)


def test_crown_volume_profile_integrates_to_the_volume():
    z = np.linspace(0.0, 45.0, 1501)
    total = np.trapezoid(derived.crown_volume_profile(PARAMS, z), z) * 1e4
    assert total == pytest.approx(derived.crown_volume_per_ha(PARAMS), rel=1e-3)


def test_clustered_and_regular_patterns_keep_the_density():
    rng = np.random.default_rng(14)
    side, cells = 160.0, 8
    counts = {}
    for pattern, options in [
        ("poisson", {}),
        ("thomas", {"cluster_size": 8, "cluster_sd": 2.0}),
        ("hardcore", {"min_distance": 2.5}),
    ]:
        stand = realise(PARAMS, side, rng, pattern=pattern, **options)
        assert stand.n_trees == pytest.approx(PARAMS.density_per_m2 * side**2, rel=0.1)
        counts[pattern] = np.histogram2d(stand.x, stand.y, cells, [[0, side]] * 2)[0].ravel()
        if pattern == "hardcore":
            d = np.hypot(stand.x[:, None] - stand.x, stand.y[:, None] - stand.y)
            np.fill_diagonal(d, np.inf)
            assert d.min() >= 2.5 - 1e-9
    dispersion = {k: c.var() / c.mean() for k, c in counts.items()}
    assert dispersion["thomas"] > 2 * dispersion["poisson"]
    assert dispersion["hardcore"] < dispersion["poisson"]


def test_scene_extras_and_argument_checks():
    ground, understory, rho_v = scene_extras(PARAMS)
    assert ground.reflectance == PARAMS.ground_reflectance and rho_v == 0.45
    assert understory.height == 1.5 and understory.lai == 0.4
    with pytest.raises(TypeError):
        realise(PARAMS, 10.0, 42)
    with pytest.raises(ValueError, match="point pattern"):
        realise(PARAMS, 10.0, np.random.default_rng(0), pattern="lattice")
