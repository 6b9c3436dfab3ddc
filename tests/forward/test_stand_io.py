"""Stand I/O, allometry, presets and clear errors for bad input."""

import numpy as np
import pytest

import forward as fw
from forward.examples import example


def test_csv_round_trip(tmp_path, rng):
    stand = example("jack-pine").stand.subset(slice(0, 25))
    path = tmp_path / "stems.csv"
    stand.to_csv(path)
    back = fw.Stand.from_csv(path)
    for column in ("x", "y", "height", "crown_length", "crown_radius", "favd", "dbh"):
        np.testing.assert_array_equal(getattr(back, column), getattr(stand, column))
    np.testing.assert_array_equal(back.shape, stand.shape)
    assert list(back.species) == list(stand.species)


def test_hdf5_round_trip(tmp_path):
    stand = example("jack-pine").stand.subset(slice(0, 25)).with_shape("cone")
    fw.save_stand(tmp_path / "s.h5", stand)
    back = fw.load_stand(tmp_path / "s.h5")
    np.testing.assert_array_equal(back.height, stand.height)
    assert list(back.shape_names) == ["cone"] * 25


@pytest.mark.parametrize(
    ("body", "message"),
    [
        ("x,y,height,crown_length,crown_radius,shape,favd\n0,0,10,4,1,sphere,0.5\n", "sphere"),
        ("x,y,height,crown_length,crown_radius,shape,favd\n0,0,10,4,-1,cone,0.5\n", "negative"),
        ("x,y,height,crown_length,crown_radius,shape,favd\n0,0,nan,4,1,cone,0.5\n", "non-finite"),
        (
            "x,y,height,crown_length,crown_radius,shape,favd\n0,0,10,4,abc,cone,0.5\n",
            "not a number",
        ),
        ("x,y,height,crown_radius,shape,favd\n0,0,10,1,cone,0.5\n", "crown_length"),
        ("x,y,height,crown_length,crown_radius,shape,favd\n0,0,3,4,1,cone,0.5\n", "exceeds height"),
    ],
)
def test_bad_stem_maps_name_the_problem(tmp_path, body, message):
    path = tmp_path / "bad.csv"
    path.write_text(body)
    with pytest.raises(ValueError, match=message):
        fw.Stand.from_csv(path)


def test_mismatched_columns_are_rejected():
    with pytest.raises(ValueError, match="one length"):
        fw.Stand.from_arrays(
            x=[0, 1], y=[0], height=[5, 6], crown_length=[2, 2], crown_radius=[1, 1], favd=0.5
        )


def test_bad_instrument_and_window_settings(gedi):
    with pytest.raises(ValueError, match="FWHM"):
        fw.GaussianPulse(-1.0)
    with pytest.raises(ValueError, match="hot-spot"):
        gedi.with_overrides(hotspot_k=3.0)
    with pytest.raises(ValueError, match="unknown instrument"):
        fw.instrument_preset("icesat")
    with pytest.raises(ValueError, match="tolerance"):
        fw.WaveformSimulator(gedi, fw.AccuracySettings(truncation_tolerance=0.0))
    sim = fw.WaveformSimulator(gedi)
    with pytest.raises(ValueError, match="steps of the bin height"):
        sim.simulate(fw.Stand.empty(), heights=np.arange(0, 10, 0.5))
    with pytest.raises(ValueError, match="NaN"):
        sim.simulate(fw.Stand.empty(), heights=np.array([0.0, np.nan]))
    with pytest.raises(ValueError, match="non-empty"):
        sim.simulate(fw.Stand.empty(), heights=np.array([]))
    with pytest.raises(ValueError, match="measured pulse"):
        fw.MeasuredPulse(np.array([0.0, np.nan, 1.0]), 1.0)


def test_presets_follow_the_conventions():
    slicer, gedi = fw.instrument_preset("slicer"), fw.instrument_preset("gedi")
    assert slicer.bin_height == pytest.approx(0.112)
    assert gedi.bin_height == pytest.approx(0.1499, abs=1e-4)
    assert gedi.footprint_sigma_m == 5.5
    assert slicer.pulse.sigma_m == pytest.approx(4 * 0.299792458 / 2 / 2.35482, rel=1e-5)
    assert gedi.with_overrides(footprint_diameter_m=10.0).footprint_sigma_m == 2.5


def test_allometry_is_monotone_and_bounded():
    allometry = fw.SPECIES_ALLOMETRY["jack pine"]
    dbh = np.linspace(0, 60, 50)
    height = allometry.height(dbh)
    assert np.all(np.diff(height) > 0) and height[0] == pytest.approx(1.3)
    assert np.all(allometry.crown_length(height) <= height)
    with pytest.raises(ValueError, match="DBH"):
        allometry.height([-1.0])


def test_jack_pine_matches_the_paper_text():
    scene = example("jack-pine")
    stand = scene.stand
    assert stand.n_trees == 1900
    low, high = np.percentile(stand.height, [5, 95])
    assert 11.5 < low and high < 15.5
    # crown volume in a 10 m footprint: paper ≈ 180 m³ (cones) and 310 m³ (ellipsoids)
    volumes = {s: [] for s in ("cone", "ellipsoid")}
    for center in scene.centers:
        inside = np.hypot(stand.x - center[0], stand.y - center[1]) < 5.0
        for s in volumes:
            volumes[s].append(stand.with_shape(s).crown_volume[inside].sum())
    assert 120 < np.mean(volumes["cone"]) < 240
    assert 240 < np.mean(volumes["ellipsoid"]) < 420
