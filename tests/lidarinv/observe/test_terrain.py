"""Terrain context: a ground that leaves its track neighbours is flagged."""

import numpy as np
import pytest

from lidarinv.observe.terrain import EARTH_RADIUS_M, check_terrain, local_metres, robust_plane


def _track(n=40, spacing_m=60.0, slope=0.15, roughness_m=0.3, seed=2):
    """A GEDI-like track heading north-east over a sloped, slightly rough terrain."""
    rng = np.random.default_rng(seed)
    s = np.arange(n) * spacing_m
    lat = -13.7 + np.degrees(s * np.cos(0.6) / EARTH_RADIUS_M)
    lon = -44.1 + np.degrees(s * np.sin(0.6) / (EARTH_RADIUS_M * np.cos(np.radians(13.7))))
    ground = 800.0 + slope * s + 3.0 * np.sin(s / 700.0) + roughness_m * rng.standard_normal(n)
    return lat, lon, ground


def test_local_metres_recover_the_spacing():
    lat, lon, _ = _track()
    east, north = local_metres(lat, lon)
    assert np.hypot(np.diff(east), np.diff(north)) == pytest.approx(60.0, rel=1e-3)


def test_robust_plane_ignores_one_wrong_point():
    east, north = np.meshgrid(np.arange(4.0) * 20, np.arange(3.0) * 20)
    east, north = east.ravel(), north.ravel()
    values = 5.0 + 0.1 * east - 0.2 * north
    values[4] += 15.0
    coef, _ = robust_plane(east, north, values)
    assert coef == pytest.approx([5.0, 0.1, -0.2], abs=1e-6)


def test_smooth_sloped_track_is_not_flagged():
    lat, lon, ground = _track()
    check = check_terrain(lat, lon, ground, np.full(ground.size, 0.1))
    assert not check.outlier.any()
    assert np.nanmax(np.abs(check.residual)) < 2.0  # the slope (9 m per shot) is followed


def test_ground_on_the_canopy_is_flagged_and_only_it():
    lat, lon, ground = _track()
    wrong = ground.copy()
    wrong[17] += 12.0  # a canopy layer taken for the ground
    wrong[30] -= 6.0  # a noise excursion below it
    check = check_terrain(lat, lon, wrong, np.full(ground.size, 0.1))
    assert np.flatnonzero(check.outlier).tolist() == [17, 30]
    assert check.expected[17] == pytest.approx(ground[17], abs=1.0)


def test_rougher_terrain_allows_more():
    lat, lon, smooth = _track(roughness_m=0.1)
    _, _, rough = _track(roughness_m=1.0)
    a = check_terrain(lat, lon, smooth).allowance
    b = check_terrain(lat, lon, rough).allowance
    assert np.nanmedian(b) > 5 * np.nanmedian(a)


def test_tracks_are_checked_apart_and_a_rough_dem_is_left_out():
    lat, lon, ground = _track()
    track = np.where(np.arange(ground.size) < 20, "BEAM0000", "BEAM0101")
    rng = np.random.default_rng(8)
    dem = ground + 4.0 * rng.standard_normal(ground.size)  # rougher than the grounds
    check = check_terrain(lat, lon, ground, track=track, dem=dem)
    assert not check.outlier.any()
    assert np.nanmedian(check.allowance) < 4.0
