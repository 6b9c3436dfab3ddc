"""RH of posterior waveforms in the products' conventions, against the direct metrics."""

from types import SimpleNamespace

import numpy as np
import pytest

from lidarinv.inference.results.product_metrics import product_relative_heights
from lidarinv.observe import processing_settings, rh_metrics
from lidarinv.observe.signal import smooth

AXIS = np.arange(0.0, 40.0, 0.3)
GROUND = 5.0
EXTENT = SimpleNamespace(signal_start=26.0, signal_end=3.0, smoothing_bins=2.0)


def _waveform(baseline):
    """A ground pulse and a canopy layer over a baseline (DN)."""
    ground = 40.0 * np.exp(-0.5 * ((AXIS - GROUND) / 0.5) ** 2)
    canopy = 6.0 * np.exp(-0.5 * ((AXIS - 18.0) / 3.0) ** 2)
    return baseline + ground + canopy


@pytest.mark.parametrize("instrument", ["gedi", "lvis"])
def test_product_heights_match_the_direct_metrics_of_the_same_waveform(instrument):
    settings = processing_settings(instrument)
    baseline = 3.0
    mean = _waveform(baseline)
    energy = smooth(mean, EXTENT.smoothing_bins) if settings.rh_smoothed else mean
    noise_mean = baseline if settings.rh_energy == "above-noise" else 0.0
    direct = rh_metrics(energy, AXIS, GROUND, noise_mean=noise_mean,
                        start=EXTENT.signal_start, end=EXTENT.signal_end,
                        percentiles=[50, 98])  # fmt: skip
    heights = product_relative_heights(
        mean[None], AXIS, [GROUND], [baseline], EXTENT, settings, [0.5, 0.98]
    )
    np.testing.assert_allclose(heights[0], direct, atol=1e-9)


def test_the_recorded_noise_level_lifts_rh98_towards_the_signal_start():
    lvis, gedi = processing_settings("lvis"), processing_settings("gedi")
    rows = np.stack([_waveform(0.0), _waveform(3.0)])
    recorded = product_relative_heights(rows, AXIS, [GROUND] * 2, [0.0, 3.0], EXTENT, lvis, [0.98])
    above = product_relative_heights(rows, AXIS, [GROUND] * 2, [0.0, 3.0], EXTENT, gedi, [0.98])
    top = EXTENT.signal_start - GROUND
    assert recorded[0, 0] < recorded[1, 0] < top  # the noise level's energy counts in LVIS L2
    assert above[1, 0] == pytest.approx(above[0, 0], abs=1e-9)  # GEDI L2A takes it away


def test_an_extent_outside_the_axis_gives_nan_and_mismatched_axes_are_refused():
    settings = processing_settings("lvis")
    away = SimpleNamespace(signal_start=90.0, signal_end=80.0, smoothing_bins=0.0)
    heights = product_relative_heights(_waveform(1.0)[None], AXIS, [GROUND], [1.0], away,
                                       settings, [0.98])  # fmt: skip
    assert np.isnan(heights).all()
    with pytest.raises(ValueError, match="bins"):
        product_relative_heights(np.ones((1, 5)), AXIS, [GROUND], [1.0], EXTENT, settings, [0.98])
