"""Ground-peak detection, signal extent, shot analysis statuses and alignment."""

import numpy as np
import pytest

import forward as fw
from lidarinv.observe import (
    Observation,
    align_and_average,
    analyse,
    find_ground,
    observe,
    signal_extent,
)

GROUND_Z = 231.7  # m, elevation of the ground in the simulated shots


@pytest.fixture(scope="module")
def setup():
    inst = fw.instrument_preset("gedi")
    stand = fw.Stand.from_arrays(x=[0.0, 5.0, -4.0], y=[0.0, 3.0, -2.0], height=[21.0, 16.0, 13.0],
                                 crown_length=[8.0, 6.0, 5.0], crown_radius=[4.0, 3.0, 3.0],
                                 favd=0.5, shape="ellipsoid")  # fmt: skip
    return inst, fw.WaveformSimulator(inst), stand


def _shot(setup, offset, rng, gain=1000.0, first=-80, last=250, **kwargs):
    inst, sim, stand = setup
    heights = (np.arange(first, last) + offset) * inst.bin_height
    wf = sim.simulate(stand, center=(0.0, 0.0), heights=heights)
    return observe(wf, gain=gain, baseline=40.0, noise_sigma=1.0, rng=rng,
                   ground_elevation=GROUND_Z, **kwargs)  # fmt: skip


def _errors(setup, gain, n=25, **kwargs):
    rng = np.random.default_rng(11)
    dz = setup[0].bin_height
    out = []
    for offset in rng.uniform(0, 1, n):
        obs = _shot(setup, offset, rng, gain=gain, **kwargs)
        peak = find_ground(obs.samples, obs.axis, 40.0, 1.0, valid=obs.valid_mask)
        out.append(((peak.position - GROUND_Z) / dz, peak.uncertainty / dz))
    return np.array(out).T


def test_ground_peak_to_a_small_fraction_of_a_bin_at_good_snr(setup):
    # gain 7000: ground peak amplitude ≈ 100 σ
    error, sigma = _errors(setup, 7000.0)
    assert np.sqrt(np.mean(error**2)) < 0.05
    assert np.max(np.abs(error)) < 0.12
    # the fit's uncertainty is a usable prior width: errors are of its size
    assert 0.4 < np.std(error / sigma) < 2.5


def test_ground_peak_error_grows_at_low_snr_but_stays_sub_bin(setup):
    error, _ = _errors(setup, 700.0)  # peak ≈ 10 σ
    assert np.sqrt(np.mean(error**2)) < 0.5


def test_saturated_ground_peak_is_fitted_from_its_flanks(setup):
    rng = np.random.default_rng(5)
    obs = _shot(setup, 0.37, rng, gain=7000.0, saturation=40.0 + 60.0)  # peak ≈ 100: clipped
    assert obs.saturated_mask.sum() >= 3
    peak = find_ground(obs.samples, obs.axis, 40.0, 1.0, valid=obs.valid_mask)
    assert abs(peak.position - GROUND_Z) < 0.1 * setup[0].bin_height
    result = analyse(obs)
    assert result.ok and "saturated" in result.flags


def test_analysis_of_a_simulated_shot(setup):
    rng = np.random.default_rng(8)
    obs = _shot(setup, 0.5, rng, gain=3000.0)
    result = analyse(obs)
    assert result.status == "ok" and result.flags == []
    assert result.noise_mean == pytest.approx(40.0, abs=0.55)  # 4 standard errors
    assert result.noise_sigma == pytest.approx(1.0, rel=0.25)
    assert result.ground == pytest.approx(GROUND_Z, abs=0.05)
    # the top of the tallest crown is 21 m; the pulse (σ ≈ 0.95 m) spreads the start up
    assert 20.5 < result.canopy_height < 24.0
    assert result.rh[100] == pytest.approx(result.canopy_height)
    assert result.rh[0] < 0 < result.rh[50] < result.rh[98] <= result.rh[100]
    assert 0 < result.cover < 1


def test_no_signal_gets_a_status_not_an_exception():
    rng = np.random.default_rng(2)
    axis = 100.0 + 0.15 * np.arange(400)
    obs = Observation(samples=30.0 + rng.standard_normal(400), axis=axis, axis_kind="elevation")
    assert signal_extent(obs.samples, axis, 30.0, 1.0) is None
    assert find_ground(obs.samples, axis, 30.0, 1.0) is None
    result = analyse(obs)
    assert result.status == "no signal" and result.rh is None and np.isnan(result.ground)


def test_a_noise_spike_below_the_signal_is_not_the_ground(setup):
    """A narrow spike far below the return clears the ground finder's floor (2-bin
    smoothing) but not the signal extent's (6 bins, as the recovery study uses; the
    inversion smooths over the pulse σ, about 6 bins for GEDI): alone, find_ground takes it for the lowest mode; searching
    within the signal extent, as analyse does, finds the true ground."""
    rng = np.random.default_rng(8)
    obs = _shot(setup, 0.5, rng, gain=3000.0, first=-160)
    spike = 20  # 140 bins (21 m) below the ground
    obs.samples[spike - 1 : spike + 2] += [3.0, 7.0, 3.0]
    assert abs(find_ground(obs.samples, obs.axis, 40.0, 1.0).position - obs.axis[spike]) < 0.3
    result = analyse(obs, smooth_bins=6.0)
    assert result.status == "ok"
    assert result.ground == pytest.approx(GROUND_Z, abs=0.05)


def test_ground_below_the_window(setup):
    rng = np.random.default_rng(4)
    obs = _shot(setup, 0.0, rng, gain=3000.0, first=7)  # window starts 1 m above ground
    result = analyse(obs)
    assert result.status == "ground outside window"
    assert "truncated bottom" in result.flags


def test_window_truncated_at_the_top_is_flagged(setup):
    rng = np.random.default_rng(4)
    obs = _shot(setup, 0.0, rng, gain=3000.0, last=110)  # window ends 16.5 m above ground
    result = analyse(obs)
    assert result.ok and "truncated top" in result.flags
    assert result.ground == pytest.approx(GROUND_Z, abs=0.05)


def test_censored_product_uses_the_product_noise(setup):
    rng = np.random.default_rng(9)
    obs = _shot(setup, 0.2, rng, gain=3000.0, floor_sigmas=3.0)
    result = analyse(obs)
    assert result.noise_source == "product" and "censored" in result.flags
    assert result.ground == pytest.approx(GROUND_Z, abs=0.05)


def test_smoothing_lowers_the_floor_for_weak_signals():
    # a weak broad return at 3σ per bin: invisible raw, found after smoothing
    axis = 0.15 * np.arange(600)
    bump = 3.0 * np.exp(-0.5 * ((axis - 45.0) / 1.5) ** 2)
    rng = np.random.default_rng(1)
    samples = bump + rng.standard_normal(axis.size)
    assert signal_extent(samples, axis, 0.0, 1.0, n_sigma=4.0) is None
    extent = signal_extent(samples, axis, 0.0, 1.0, n_sigma=4.0, smooth_bins=4.0)
    assert extent is not None and 41.0 < extent.end < extent.start < 49.0


def test_alignment_registers_ground_peaks_and_averages(setup):
    inst, sim, stand = setup
    rng = np.random.default_rng(6)
    waves, axes, grounds, noises = [], [], [], []
    reference = None
    for k, offset in enumerate(rng.uniform(0, 1, 6)):
        heights = (np.arange(-80, 250) + offset) * inst.bin_height
        wf = sim.simulate(stand, center=(0.0, 0.0), heights=heights)
        obs = observe(wf, gain=4000.0, baseline=40.0, noise_sigma=0.5, rng=rng,
                      ground_elevation=100.0 + 7.3 * k)  # fmt: skip
        result = analyse(obs)
        waves.append(obs.samples)
        axes.append(obs.axis)
        grounds.append(result.ground)
        noises.append(result.noise_mean)
        reference = wf
    avg = align_and_average(waves, axes, grounds, noise_means=noises)
    assert np.all(avg.count[(avg.height > -5) & (avg.height < 30)] == 6)
    # the average peaks at the ground (0 m) and follows the noise-free shape
    assert abs(avg.height[np.nanargmax(avg.mean)]) <= inst.bin_height
    truth = np.interp(avg.height, reference.heights, reference.samples / reference.samples.max())
    inside = avg.count == 6
    assert np.max(np.abs(avg.mean[inside] - truth[inside])) < 0.03
    with pytest.raises(ValueError, match="ground"):
        align_and_average(waves[:2], axes[:2], [np.nan, 1.0])
