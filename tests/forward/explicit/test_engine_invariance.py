"""Symmetries, truncation, convergence and multi-footprint behaviour of the engine."""

import numpy as np
import pytest

import forward as fw
from tests.conftest import random_stand


def test_tree_beyond_truncation_radius_changes_nothing(gedi, rng):
    sim = fw.WaveformSimulator(gedi)
    stand = random_stand(rng, n=40, half_width=10.0)
    far = sim.footprint_radius + 3.0 + 1e-6  # crown radius 3 m
    extra = fw.Stand.from_arrays(
        x=[far],
        y=[0.0],
        height=[25.0],
        crown_length=[10.0],
        crown_radius=[3.0],
        favd=2.0,
        shape="cylinder",
    )
    merged = fw.Stand(
        **{
            c: np.concatenate([getattr(stand, c), getattr(extra, c)])
            for c in ("x", "y", "height", "crown_length", "crown_radius", "shape", "favd")
        }
    )
    a, b = sim.simulate(stand), sim.simulate(merged, heights=sim.simulate(stand).heights)
    np.testing.assert_allclose(b.samples, a.samples, rtol=1e-13, atol=1e-18)


def test_translating_stand_and_footprint_together_changes_nothing(gedi, rng):
    sim = fw.WaveformSimulator(gedi)
    stand = random_stand(rng, n=80)
    a = sim.simulate(stand, center=(1.5, -2.0))
    b = sim.simulate(stand.translated(250.0, -75.0), center=(251.5, -77.0), heights=a.heights)
    np.testing.assert_allclose(b.samples, a.samples, rtol=1e-9, atol=1e-14)


def test_refining_accuracy_settings_converges(gedi, rng):
    stand = random_stand(rng, n=120)

    def run(radial, angular, m=None):
        settings = fw.AccuracySettings(
            radial_nodes=radial, angular_nodes=angular, vertical_oversampling=m
        )
        return fw.WaveformSimulator(gedi, settings).simulate(stand, heights=heights)

    heights = fw.WaveformSimulator(gedi).simulate(stand).heights
    reference = run(16, 64, 3)
    errors = [
        np.abs(run(r, a).samples - reference.samples).sum() / reference.samples.sum()
        for r, a in ((2, 4), (4, 8), (8, 24))
    ]
    assert errors[0] > errors[1] > errors[2]
    assert errors[2] < 3e-3


def test_many_footprints_equal_single_calls(rng):
    scene_instrument = fw.instrument_preset("slicer")
    sim = fw.WaveformSimulator(scene_instrument)
    stand = random_stand(rng, n=150, half_width=30.0)
    centers = [(0.0, 0.0), (10.0, 0.0), (-5.0, 12.0)]
    many = sim.simulate_many(stand, centers)
    for center, wf in zip(centers, many):
        single = sim.simulate(stand, center=center)
        np.testing.assert_array_equal(wf.samples, single.samples)
        assert wf.center == center


def test_window_length_does_not_change_samples(gedi, rng):
    sim = fw.WaveformSimulator(gedi)
    stand = random_stand(rng, n=60)
    short = sim.simulate(stand)
    dz = gedi.bin_height
    long_heights = np.concatenate(
        [
            short.heights[0] - dz * np.arange(300, 0, -1),
            short.heights,
            short.heights[-1] + dz * np.arange(1, 301),
        ]
    )
    long = sim.simulate(stand, heights=long_heights)
    np.testing.assert_allclose(long.samples[300:-300], short.samples, rtol=1e-12, atol=1e-16)
    assert np.all(long.samples[:200] == 0) and np.all(long.samples[-200:] == 0)


def test_ground_shift_by_moving_heights(gedi):
    sim = fw.WaveformSimulator(gedi)
    offset = 0.37 * gedi.bin_height
    base = sim.simulate(fw.Stand.empty())
    shifted = sim.simulate(fw.Stand.empty(), heights=base.heights + offset)
    expected = 0.3 * gedi.bin_height * gedi.pulse.pdf(base.heights + offset)
    np.testing.assert_allclose(shifted.samples, expected, atol=1e-9)


def test_sloped_bare_ground_widens_the_ground_return(gedi):
    sim = fw.WaveformSimulator(gedi)
    flat = sim.simulate(fw.Stand.empty())
    slope = sim.simulate(fw.Stand.empty(), ground=fw.Ground(slope_deg=20.0))
    assert slope.samples.sum() == pytest.approx(flat.samples.sum(), rel=1e-6)

    def spread(wf):
        mean = (wf.heights * wf.samples).sum() / wf.samples.sum()
        return np.sqrt(((wf.heights - mean) ** 2 * wf.samples).sum() / wf.samples.sum())

    expected = np.hypot(gedi.pulse.sigma_m, np.tan(np.radians(20.0)) * gedi.footprint_sigma_m)
    assert spread(slope) == pytest.approx(expected, rel=0.02)
