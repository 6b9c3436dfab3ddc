"""Ground detection, signal extent and shot analysis statuses on simulated shots."""

import numpy as np
import pytest
from alignment import align_and_average

import forward as fw
from lidarinv.observe import (
    Observation,
    analyse,
    estimate_noise,
    find_ground,
    find_modes,
    observe,
    signal_extent,
    smooth,
)
from lidarinv.observe.noise import with_smoothed_noise

GROUND_Z = 231.7  # m, elevation of the ground in the simulated shots


@pytest.fixture(scope="module")
def setup():
    inst = fw.instrument_preset("gedi")
    stand = fw.Stand.from_arrays(x=[0.0, 5.0, -4.0], y=[0.0, 3.0, -2.0], height=[21.0, 16.0, 13.0],
                                 crown_length=[8.0, 6.0, 5.0], crown_radius=[4.0, 3.0, 3.0],
                                 favd=0.5, shape="ellipsoid")  # fmt: skip
    return inst, fw.WaveformSimulator(inst), stand


def _shot(setup, offset, rng, gain=1000.0, first=-80, last=250, stand=None, **kwargs):
    inst, sim, default = setup
    heights = (np.arange(first, last) + offset) * inst.bin_height
    wf = sim.simulate(stand or default, center=(0.0, 0.0), heights=heights)
    return observe(wf, gain=gain, baseline=40.0, noise_sigma=1.0, rng=rng,
                   ground_elevation=GROUND_Z, instrument=inst, **kwargs)  # fmt: skip


def _errors(setup, gain, n=25, **kwargs):
    rng = np.random.default_rng(11)
    dz = setup[0].bin_height
    out = []
    for offset in rng.uniform(0, 1, n):
        result = analyse(_shot(setup, offset, rng, gain=gain, **kwargs))
        out.append(((result.ground - GROUND_Z) / dz, result.ground_uncertainty / dz))
    return np.array(out).T


def test_ground_to_a_small_fraction_of_a_bin_at_good_snr(setup):
    # gain 7000: ground peak amplitude ≈ 100 σ
    error, sigma = _errors(setup, 7000.0)
    assert np.sqrt(np.mean(error**2)) < 0.05
    assert np.max(np.abs(error)) < 0.12
    # the uncertainty from the measured slope noise is the size of the errors
    assert 0.4 < np.std(error / sigma) < 2.5


def test_ground_error_grows_at_low_snr_but_stays_sub_bin(setup):
    error, sigma = _errors(setup, 700.0)  # peak ≈ 10 σ
    assert np.sqrt(np.mean(error**2)) < 0.5
    assert 0.4 < np.std(error / sigma) < 2.5


def test_saturated_ground_peak_is_located_at_its_plateau_centre(setup):
    rng = np.random.default_rng(5)
    obs = _shot(setup, 0.37, rng, gain=7000.0, saturation=40.0 + 60.0)  # peak ≈ 100: clipped
    assert obs.saturated_mask.sum() >= 3
    result = analyse(obs)
    assert result.ok and "saturated" in result.flags and not result.quality
    assert abs(result.ground - GROUND_Z) < 0.1 * setup[0].bin_height


def test_a_clipped_return_without_a_saturation_level_is_flagged(setup):
    rng = np.random.default_rng(5)
    obs = _shot(setup, 0.37, rng, gain=7000.0)
    clipped = Observation(np.minimum(obs.samples, 100.0), obs.axis, "elevation",
                          instrument="gedi")  # fmt: skip
    result = analyse(clipped)
    assert "clipped" in result.flags and not result.quality


def test_analysis_of_a_simulated_shot(setup):
    rng = np.random.default_rng(8)
    obs = _shot(setup, 0.5, rng, gain=3000.0)
    result = analyse(obs)
    assert result.status == "ok" and result.flags == [] and result.quality
    assert result.instrument == "gedi" and result.noise.source == "samples"
    assert result.noise_mean == pytest.approx(40.0, abs=0.3)
    assert result.noise_sigma == pytest.approx(1.0, rel=0.15)
    assert result.ground == pytest.approx(GROUND_Z, abs=0.05)
    # the top of the tallest crown is 21 m; the pulse (σ ≈ 0.95 m) spreads the start up
    assert 19.5 < result.canopy_height < 24.0
    assert result.rh[100] == pytest.approx(result.canopy_height)
    assert result.rh[0] < 0 < result.rh[50] < result.rh[98] <= result.rh[100]
    assert 0 < result.cover < 1 and result.n_modes >= 2
    assert 0.9 < result.sensitivity < 1.0
    # PAVD in 5 m layers integrates to the PAI
    assert np.sum(result.pavd) * result.pavd_layer_m == pytest.approx(result.pai, rel=1e-6)


def test_a_lone_peak_is_ground_with_no_canopy(setup):
    rng = np.random.default_rng(3)
    bare = fw.Stand.from_arrays(x=[], y=[], height=[], crown_length=[], crown_radius=[],
                                favd=[], shape=[])  # fmt: skip
    obs = _shot(setup, 0.3, rng, gain=3000.0, stand=bare)
    result = analyse(obs)
    assert result.ok and result.n_modes == 1
    assert result.ground == pytest.approx(GROUND_Z, abs=0.05)
    assert result.cover == pytest.approx(0.0, abs=0.02)
    # the signal is the smoothed pulse (σ 1.35 m): bare ground has an RH100 of a few σ
    assert result.canopy_height < 4 * 1.35


def test_a_two_layer_return_has_its_ground_at_the_lower_mode():
    axis = 100.0 + 0.15 * np.arange(800)
    rng = np.random.default_rng(4)
    layers = (120.0 * np.exp(-0.5 * ((axis - 140.0) / 1.0) ** 2)  # the ground
              + 60.0 * np.exp(-0.5 * ((axis - 150.0) / 1.5) ** 2)  # an understorey
              + 90.0 * np.exp(-0.5 * ((axis - 165.0) / 2.0) ** 2))  # a canopy  # fmt: skip
    obs = Observation(30.0 + layers + rng.standard_normal(axis.size), axis, "elevation",
                      instrument="gedi")  # fmt: skip
    result = analyse(obs)
    assert result.ok and result.n_modes == 3
    assert result.ground == pytest.approx(140.0, abs=0.05)


def test_no_signal_gets_a_status_not_an_exception():
    rng = np.random.default_rng(2)
    axis = 100.0 + 0.15 * np.arange(400)
    obs = Observation(samples=30.0 + rng.standard_normal(400), axis=axis, axis_kind="elevation",
                      instrument="gedi")  # fmt: skip
    result = analyse(obs)
    assert result.status == "no signal" and result.rh is None and np.isnan(result.ground)
    assert not result.quality and result.noise.mean == pytest.approx(30.0, abs=0.2)


def test_a_noise_spike_below_the_signal_is_not_the_ground(setup):
    """A narrow spike far below the return stays under the back floor: the ground is the
    true one."""
    rng = np.random.default_rng(8)
    obs = _shot(setup, 0.5, rng, gain=3000.0, first=-160)
    spike = 20  # 140 bins (21 m) below the ground
    obs.samples[spike - 1 : spike + 2] += [3.0, 7.0, 3.0]
    result = analyse(obs)
    assert result.status == "ok"
    assert result.ground == pytest.approx(GROUND_Z, abs=0.05)


def test_correlated_noise_at_the_window_edges_does_not_pass_for_signal(setup):
    """Shots whose window reaches 22 m below the ground, with correlated noise: none is
    refused as 'ground outside window' and none finds its ground away from the truth."""
    _inst, _sim, _stand = setup
    kernel = np.exp(-0.5 * (np.arange(-8, 9) / 2.5) ** 2)  # R(1) ≈ 0.92, like GEDI's
    rng = np.random.default_rng(17)
    for k in range(40):
        obs = _shot(setup, rng.uniform(), rng, gain=1500.0, first=-150, noise_filter=kernel)
        result = analyse(obs)
        assert result.ok, (k, result.status, result.reason)
        assert abs(result.ground - GROUND_Z) < 0.3


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
    assert result.ok and "truncated top" in result.flags and not result.quality
    assert result.ground == pytest.approx(GROUND_Z, abs=0.05)


def test_censored_product_uses_the_product_noise(setup):
    rng = np.random.default_rng(9)
    obs = _shot(setup, 0.2, rng, gain=3000.0, floor_sigmas=3.0)
    result = analyse(obs)
    assert result.noise_source == "product" and "noise from product" in result.flags
    assert "censored" in result.flags
    assert result.ground == pytest.approx(GROUND_Z, abs=0.05)


def test_weak_canopy_under_the_front_floor_is_low_sensitivity(setup):
    """A dense stand over a weak ground: the shot's sensitivity is low and flagged."""
    rng = np.random.default_rng(12)
    dense = fw.Stand.from_arrays(x=[0.0], y=[0.0], height=[20.0], crown_length=[10.0],
                                 crown_radius=[300.0], favd=[1.2], shape="cylinder")  # fmt: skip
    obs = _shot(setup, 0.4, rng, gain=200.0, stand=dense)
    result = analyse(obs)
    assert result.sensitivity < 0.9
    assert "low sensitivity" in result.flags and not result.quality


def test_stale_return_flag_from_the_file(setup):
    rng = np.random.default_rng(6)
    obs = _shot(setup, 0.1, rng, gain=3000.0, metadata={"stale_return": True})
    result = analyse(obs)
    assert result.ok and "stale return" in result.flags and not result.quality


def test_an_observation_without_an_instrument_needs_one():
    axis = 0.15 * np.arange(300)
    obs = Observation(10.0 + np.exp(-0.5 * ((axis - 9.0) / 0.9) ** 2), axis)
    with pytest.raises(ValueError, match="which instrument"):
        analyse(obs)
    assert analyse(obs, instrument="gedi").instrument == "gedi"


def test_smoothing_reveals_a_weak_broad_return():
    # a weak broad return at 1.5σ a bin: under any floor raw, clear after smoothing
    axis = 0.15 * np.arange(600)
    bump = 1.5 * np.exp(-0.5 * ((axis - 45.0) / 1.5) ** 2)
    rng = np.random.default_rng(1)
    samples = bump + rng.standard_normal(axis.size)
    free = np.abs(axis - 45.0) > 8.0
    noise = estimate_noise(samples, free)
    assert signal_extent(samples, axis, noise.mean + 4.0 * noise.sigma) is None
    smoothed = smooth(samples, 4.0)
    noise = with_smoothed_noise(noise, smoothed, free, 4.0)
    extent = signal_extent(smoothed, axis, noise.detection_floor(4.0), edge=12)
    assert extent is not None and 41.0 < extent.end < extent.start < 49.0
    modes = find_modes(smoothed, noise.mean, floor=noise.detection_floor(4.0),
                       prominence=3 * noise.smoothed_sigma)  # fmt: skip
    assert len(modes) == 1 and abs(axis[modes[0].index] - 45.0) < 0.5
    peak = find_ground(smoothed, axis, noise, floor=noise.detection_floor(4.0))
    assert abs(peak.position - 45.0) < 3 * peak.uncertainty + 0.05


def test_alignment_registers_ground_peaks_and_averages(setup):
    inst, sim, stand = setup
    rng = np.random.default_rng(6)
    waves, axes, grounds, noises = [], [], [], []
    reference = None
    for k, offset in enumerate(rng.uniform(0, 1, 6)):
        heights = (np.arange(-80, 250) + offset) * inst.bin_height
        wf = sim.simulate(stand, center=(0.0, 0.0), heights=heights)
        obs = observe(wf, gain=4000.0, baseline=40.0, noise_sigma=0.5, rng=rng,
                      ground_elevation=100.0 + 7.3 * k, instrument=inst)  # fmt: skip
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
