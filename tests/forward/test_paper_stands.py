"""The paper's stands as parameterised stands: calibration and qualitative findings."""

import numpy as np
import pytest

from forward import derived
from forward.examples import EXAMPLES
from forward.expected import ExpectedWaveformModel
from forward.paper_stands import (
    SUCCESSIONAL,
    jack_pine_instrument,
    jack_pine_params,
    successional_instrument,
    successional_params,
    successional_scene,
)

FOOTPRINT_10M = np.pi * 5.0**2


def test_jack_pine_matches_the_paper_numbers():
    p = jack_pine_params("cone")
    assert p.density == 1900 and p.favd == 0.8
    dist = p.cohorts()[0][1]
    assert dist.ppf(0.0) == pytest.approx(12.0) and dist.ppf(1.0) == pytest.approx(15.0)
    # crown volume per 10 m footprint: paper 180 m³ (cones) and 310 m³ (ellipsoids)
    cone = derived.crown_volume_per_ha(p) * FOOTPRINT_10M / 1e4
    ellipsoid = derived.crown_volume_per_ha(jack_pine_params("ellipsoid")) * FOOTPRINT_10M / 1e4
    assert cone == pytest.approx(180.0, rel=0.1)
    assert ellipsoid == pytest.approx(310.0, rel=0.2)
    # the measured LAI 2.17 lies between the cone and ellipsoid stands at FAVD 0.8
    assert (
        derived.leaf_area_index(p) < 2.17 < derived.leaf_area_index(jack_pine_params("ellipsoid"))
    )
    inst = jack_pine_instrument()
    assert inst.bin_height == pytest.approx(0.112) and inst.pulse.fwhm_ns == 4.0


def _expected(params, instrument, heights):
    return ExpectedWaveformModel(instrument, heights, params).evaluate(params)


def _rise(heights, canopy):
    peak = int(np.argmax(canopy))
    return heights[np.flatnonzero(canopy >= 0.1 * canopy[peak]).max()] - heights[peak]


def test_cones_rise_slower_and_waveform_peaks_sit_above_volume_peaks():
    inst = jack_pine_instrument()
    heights = np.arange(-20, 160) * inst.bin_height
    rise = {}
    for shape in ("cone", "ellipsoid", "hemi-ellipsoid"):
        params = jack_pine_params(shape)
        canopy = _expected(params, inst, heights).canopy[0]
        rise[shape] = _rise(heights, canopy)
        volume = derived.crown_volume_profile(params, heights)
        assert heights[np.argmax(canopy)] > heights[np.argmax(volume)], shape
    assert rise["cone"] > 1.3 * max(rise["ellipsoid"], rise["hemi-ellipsoid"])


def test_successional_stands_follow_the_text():
    inst = successional_instrument()
    assert inst.footprint_diameter_m == pytest.approx(25.0) and inst.pulse.fwhm_ns == 10.0
    heights = np.arange(-10, 200) * inst.bin_height
    peaks, ground_max = {}, {}
    for age in SUCCESSIONAL:
        p = successional_params(age)
        out = _expected(p, inst, heights)
        peaks[age] = derived.crown_volume_profile(p, heights).max()
        ground_max[age] = out.samples[0].max()
        assert 1.5 < derived.mean_height(p) < 25.0
        assert derived.expected_max_height(p, 25.0) < 27.0
    # 5 years: conifers (cones) below 3 m, deciduous (ellipsoids) above 3.5 m
    five = successional_params(5)
    upper, lower = (dist for _, dist, _ in five.cohorts())
    assert upper.ppf(0.0) > 3.0 and lower.ppf(1.0) < 3.5
    # the five-year ground return is the largest return of all stands
    assert ground_max[5] == max(ground_max.values())
    # the 200-year stand holds the largest crown-volume density
    assert peaks[200] == max(peaks.values())


def test_upper_tier_of_the_old_stand_occults_the_lower():
    inst = successional_instrument()
    heights = np.arange(-10, 200) * inst.bin_height
    transmission = {}
    for age in (20, 60, 200):
        p = successional_params(age)
        # beam fraction reaching the crown top of the lower tier's mean tree
        top_lower = p.cohort2_height_mean
        transmission[age] = ExpectedWaveformModel(inst, heights, p).gap(p, [top_lower])[0, 0]
    assert transmission[200] < 0.5
    assert min(transmission[20], transmission[60]) > 0.7


def test_successional_examples_are_explicit_scenes():
    successional = sorted(name for name in EXAMPLES if name.startswith("successional"))
    assert successional == [f"successional-{a}" for a in (20, 200, 5, 60)]
    scene = successional_scene(20)
    assert scene.stand.n_trees > 0
    assert set(np.unique(scene.stand.shape_names)) <= {"cone", "ellipsoid"}
    assert successional_params(200, "hemi-ellipsoid").shape_mix == (0.0, 0.0, 1.0, 0.0)
    with pytest.raises(ValueError, match="age"):
        successional_params(7)
