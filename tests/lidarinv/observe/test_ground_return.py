"""The pulse's broadening: the Gaussian convolution of waveforms, and its fit to a ground
return's lower flank that recovers a known broadening and the registered ground."""

import numpy as np
import pytest

from forward.pulse import GaussianPulse, MeasuredPulse, broaden, point_returns
from lidarinv.observe.ground_return import (
    fit_ground_return,
    mode_offset,
    registered_ground,
)
from lidarinv.observe.signal import smooth

DZ = 0.15


def test_broadening_a_gaussian_adds_its_width_in_quadrature():
    axis = np.arange(600) * DZ
    pulse = GaussianPulse(15.0)
    rows = point_returns(pulse, axis, np.array([40.0, 45.0]), np.array([1.0, 2.0]) * DZ,
                         pulse.support(1e-9))  # fmt: skip
    out = broaden(rows, DZ, np.array([0.0, 1.2]))
    np.testing.assert_allclose(out[0], rows[0], atol=1e-12 * rows.max())  # σ = 0: as it was
    np.testing.assert_allclose(out.sum(axis=1), rows.sum(axis=1), rtol=1e-9)
    wider = GaussianPulse(np.hypot(15.0, 2.354820045 * 1.2 * 2 / 0.299792458))
    expected = point_returns(wider, axis, np.array([45.0]), np.array([2.0]) * DZ,
                             wider.support(1e-9))  # fmt: skip
    np.testing.assert_allclose(out[1], expected[0], atol=1e-6 * expected.max())
    with pytest.raises(ValueError, match="≥ 0"):
        broaden(rows, DZ, -1.0)


def test_with_a_reach_a_rows_broadening_does_not_depend_on_the_rows_beside_it():
    # a return near the window's top and a σ under a bin (the transfer function cut at
    # Nyquist rings), where the padding's length shows: the batch's widest row sets the
    # transform's length unless the reach fixes it
    axis = np.arange(400) * DZ
    pulse = GaussianPulse(15.0)
    row = point_returns(pulse, axis, np.array([axis[-8]]), np.array([1.0]) * DZ,
                        pulse.support(1e-9))  # fmt: skip
    alone = broaden(row, DZ, 0.05, reach_m=4.0)[0]
    beside = broaden(np.vstack([row, row]), DZ, np.array([0.05, 3.5]), reach_m=4.0)[0]
    np.testing.assert_allclose(beside, alone, rtol=0, atol=1e-14 * alone.max())
    unfixed = broaden(np.vstack([row, row]), DZ, np.array([0.05, 3.5]))[0]
    assert np.max(np.abs(unfixed - broaden(row, DZ, 0.05)[0])) > 1e-6 * alone.max()


@pytest.mark.parametrize("bins", [337, 512, 1021])
def test_broadening_matches_a_direct_convolution_at_any_window_length(bins):
    # a band-limited waveform (smooth peaks well inside the window), convolved bin by bin
    # with the sampled Gaussian: the slow reference of the FFT path
    axis = np.arange(bins) * DZ
    pulse = GaussianPulse(15.0)
    centres = axis[bins // 2] + np.array([-6.0, 0.0, 4.5])
    rows = point_returns(pulse, axis, centres, np.array([1.0, 3.0, 0.5]) * DZ,
                         pulse.support(1e-12)).sum(axis=0, keepdims=True)  # fmt: skip
    sigma = 0.8
    offsets = np.arange(-int(8 * sigma / DZ), int(8 * sigma / DZ) + 1) * DZ
    kernel = np.exp(-0.5 * (offsets / sigma) ** 2)
    direct = np.convolve(rows[0], kernel / kernel.sum(), mode="same")
    np.testing.assert_allclose(broaden(rows, DZ, sigma)[0], direct, atol=1e-6 * direct.max())


def _tailed_pulse():
    t = np.arange(128.0)
    rise = np.exp(-0.5 * ((t - 50) / 4.0) ** 2)
    tail = np.exp(-0.5 * ((t - 50) / 4.0) ** 2) + 0.4 * np.exp(-(t - 50) / 12.0) * (t > 50)
    return MeasuredPulse(np.where(t < 50, rise, tail), 1.0)


@pytest.mark.parametrize("width", [0.0, 0.8, 1.8])
def test_the_lower_flank_fit_recovers_a_known_broadening_and_ground(width):
    pulse = _tailed_pulse()
    axis = 700.0 + np.arange(500) * DZ
    ground = 745.37
    bare = point_returns(pulse, axis, np.array([ground]), np.array([400.0]), pulse.support(1e-9))
    # shrubs above the ground: the upper flank holds more than the pulse (the lower flank
    # does not, which is why it measures the broadening)
    shrubs = 40.0 * np.exp(-0.5 * ((axis - ground - 2.5) / 0.8) ** 2)
    signal = broaden(bare, DZ, width)[0] + shrubs
    rng = np.random.default_rng(1)
    samples = 230.0 + signal + 1.5 * rng.standard_normal(axis.size)
    smoothing = 6.5
    detected = axis[np.argmax(smooth(samples, smoothing)[axis < ground + 0.5])]
    fit = fit_ground_return(samples, axis, 230.0, 1.5, pulse, detected)
    assert fit.broadening == pytest.approx(width, abs=0.2)
    assert fit.broadening_range[0] <= fit.broadening <= fit.broadening_range[1]
    # without the shrubs, the detected (smoothed) mode lies below the ground of a tailed
    # pulse; registered, it is back on the ground
    assert mode_offset(pulse, np.hypot(width, smoothing * DZ)) < 0
    bare_samples = 230.0 + broaden(bare, DZ, width)[0] + 1.5 * rng.standard_normal(axis.size)
    smoothed = smooth(bare_samples, smoothing)
    peak = int(np.argmax(smoothed))
    a, b, c = smoothed[peak - 1 : peak + 2]
    detected = axis[peak] + 0.5 * (a - c) / (a - 2 * b + c) * DZ
    registered = registered_ground(detected, pulse, width, smoothing * DZ)
    assert detected < ground - 0.02
    assert registered == pytest.approx(ground, abs=0.03)


def test_a_symmetric_pulse_peaks_where_it_is_registered():
    assert mode_offset(GaussianPulse(10.0), 1.5) == 0.0
    assert registered_ground(12.3, GaussianPulse(10.0), 0.5, 1.0) == 12.3


@pytest.mark.parametrize("smoothing_m", [0.0, 0.4, 2.0])
def test_a_gaussian_grounds_return_cdf_is_the_normal_cdf_of_the_widths_in_quadrature(
    smoothing_m,
):
    from scipy.stats import norm

    from lidarinv.observe.instrument import ground_return_cdf

    pulse = GaussianPulse(15.0)
    width = np.hypot(pulse.sigma_m, smoothing_m)
    offsets = np.linspace(-4.0, 4.0, 81) * width
    cdf = ground_return_cdf(pulse, smoothing_m)(offsets)
    np.testing.assert_allclose(cdf, norm.cdf(offsets / width), atol=2e-3)
