"""Direct metrics: RH percentiles on closed forms, cover and PAI on slab stands."""

import numpy as np
import pytest
from scipy.optimize import brentq
from scipy.stats import norm

import forward as fw
from lidarinv.observe import analyse, gap_profile, observe, rh_metrics

DZ = 0.15


def _two_gaussians(ground=100.0, areas=(3.0, 5.0), centres=(0.0, 15.0), sigmas=(1.0, 2.0)):
    axis = ground + np.arange(-60, 200) * DZ
    density = sum(a * norm.pdf(axis, ground + c, s) for a, c, s in zip(areas, centres, sigmas))

    def cdf(z):
        total = sum(a * norm.cdf(z, c, s) for a, c, s in zip(areas, centres, sigmas))
        return total / sum(areas)

    return axis, density * DZ, cdf


def test_rh_metrics_of_two_gaussians_match_the_closed_form():
    axis, samples, cdf = _two_gaussians()
    percentiles = np.array([2, 10, 25, 37.5, 50, 75, 90, 98])
    rh = rh_metrics(samples, axis, 100.0, percentiles=percentiles)
    exact = [brentq(lambda z, p=p: cdf(z) - p / 100, -10, 30) for p in percentiles]
    np.testing.assert_allclose(rh, exact, atol=0.01)
    # 3/8 of the energy is in the ground Gaussian: RH37.5 falls between the two modes
    assert 2.5 < rh[3] < 10.0


def test_rh_does_not_depend_on_baseline_or_gain():
    axis, samples, _ = _two_gaussians()
    base = rh_metrics(samples, axis, 100.0)
    scaled = rh_metrics(25.0 + 400.0 * samples, axis, 100.0, noise_mean=25.0)
    np.testing.assert_allclose(base[1:], scaled[1:], atol=1e-9)  # RH0: first nonzero bin
    assert np.all(np.diff(base) >= 0)


def test_rh_window_limits_and_bad_input():
    axis, samples, _ = _two_gaussians()
    rh = rh_metrics(samples, axis, 100.0, start=120.0, end=97.0)
    assert rh[100] == pytest.approx(120.0 - 100.0, abs=DZ / 2)
    assert rh[0] == pytest.approx(97.0 - 100.0, abs=DZ / 2)
    with pytest.raises(ValueError, match="percentiles"):
        rh_metrics(samples, axis, 100.0, percentiles=[101])
    with pytest.raises(ValueError, match="no return energy"):
        rh_metrics(np.zeros_like(samples), axis, 100.0)
    with pytest.raises(ValueError, match="below"):
        rh_metrics(samples, axis, 100.0, start=90.0, end=110.0)


def _box_on_a_level(amplitude=10.0, level=2.0, top=20.0, step=0.1):
    """Bins 0.1 m wide with edges on whole tenths: a rectangular return over [0, top] on a
    flat level (the recorded noise mean), ground at 0."""
    axis = np.arange(-100, 400) * step + step / 2
    inside = (axis > 0.0) & (axis < top)
    return axis, level + amplitude * inside


@pytest.mark.parametrize("start_edge", [30.0, 25.0])
def test_rh98_of_recorded_counts_follows_the_signal_start(start_edge):
    # LVIS L2 counts the recorded level as energy: between the signal end (edge −5 m) and
    # the start edge S, a box of area 10·20 m over a level of 2 holds 200 + 2·(S + 5), and
    # RH98 lies in the level above the box where 200 + 2·(z + 5) = 0.98 · total
    axis, samples = _box_on_a_level()
    start, end = start_edge - 0.05, -5.0 + 0.05  # bin centres
    rh = rh_metrics(samples, axis, 0.0, start=start, end=end, percentiles=[98])
    total = 200.0 + 2.0 * (start_edge + 5.0)
    assert rh[0] == pytest.approx((0.98 * total - 200.0) / 2.0 - 5.0, abs=1e-9)
    # with the level subtracted (GEDI L2A) the same start leaves RH98 at 0.98 of the box
    above = rh_metrics(samples, axis, 0.0, noise_mean=2.0, start=start, end=end, percentiles=[98])
    assert above[0] == pytest.approx(0.98 * 20.0, abs=1e-9)


def test_rh98_of_recorded_counts_moves_with_the_start_nearly_metre_for_metre():
    # d RH98 / d S = 0.98 · level / level = 0.98 (closed form above): a signal start
    # 0.37 m higher than the product's lifts RH98 by 0.36 m under LVIS L2's convention
    axis, samples = _box_on_a_level()
    heights = [
        rh_metrics(samples, axis, 0.0, start=s - 0.05, end=-4.95, percentiles=[98])[0]
        for s in (27.0, 28.0)
    ]
    assert heights[1] - heights[0] == pytest.approx(0.98, abs=1e-9)


def _slab(favd, crown_length=8.0, top=20.0):
    inst = fw.instrument_preset("gedi")
    stand = fw.Stand.from_arrays(x=[0.0], y=[0.0], height=[top], crown_length=[crown_length],
                                 crown_radius=[200.0], favd=[favd], shape="cylinder")  # fmt: skip
    heights = np.arange(-60, 220) * inst.bin_height
    wf = fw.WaveformSimulator(inst).simulate(stand, center=(0.0, 0.0), heights=heights)
    return inst, wf


@pytest.mark.parametrize("favd", [0.05, 0.3, 0.8])
def test_direct_cover_and_pai_of_a_slab_are_exact(favd):
    inst, wf = _slab(favd)
    k = inst.extinction_per_favd
    exact_gap = np.exp(-k * favd * 8.0)
    profile = gap_profile(wf.samples, wf.heights, 0.0, rho_ratio=0.45 / 0.3, extinction=k)
    assert profile.cover == pytest.approx(1 - exact_gap, abs=1e-4)
    assert profile.pai == pytest.approx(favd * 8.0, rel=1e-3)
    # PAVD equals the slab's FAVD well inside the slab, and vanishes below it
    inside = (profile.height[:-1] > 14.0) & (profile.height[:-1] < 17.0)
    np.testing.assert_allclose(profile.pavd[inside], favd, rtol=0.03)
    assert np.all(np.abs(profile.pavd[profile.height[:-1] < 8.0]) < 1e-3 * favd)


def test_wrong_reflectance_ratio_biases_cover_as_expected():
    inst, wf = _slab(0.3)
    k = inst.extinction_per_favd
    exact = 1 - np.exp(-k * 0.3 * 8.0)
    low = gap_profile(wf.samples, wf.heights, 0.0, rho_ratio=1.0, extinction=k).cover
    high = gap_profile(wf.samples, wf.heights, 0.0, rho_ratio=2.5, extinction=k).cover
    # under-stating ρv/ρg credits the canopy with more gap-blocking: cover is too high
    assert low > exact > high


def test_cover_of_a_noisy_slab_observation():
    inst, wf = _slab(0.3)
    exact = 1 - np.exp(-inst.extinction_per_favd * 0.3 * 8.0)
    rng = np.random.default_rng(21)
    covers = []
    for _ in range(10):
        obs = observe(wf, gain=3000.0, baseline=50.0, noise_sigma=1.0, rng=rng,
                      ground_elevation=812.0, instrument=inst)  # fmt: skip
        result = analyse(obs)
        assert result.ok
        # the signal start lies a couple of smoothed-pulse σ (1.35 m) above the slab's top
        assert 20.0 < result.canopy_height < 23.5
        covers.append(result.cover)
    assert np.mean(covers) == pytest.approx(exact, abs=0.01)


def test_asymmetric_ground_return_needs_its_pulse_cdf():
    """A ground return with a tail below its peak (GEDI's pulse) over a slab: mirroring
    the energy below the peak overstates the ground; the pulse's own CDF does not."""
    from forward.pulse import MeasuredPulse
    from lidarinv.observe.instrument import ground_return_cdf

    times = np.arange(60.0)
    tailed = np.where(times < 20, np.exp(-0.5 * ((times - 20) / 3.0) ** 2),
                      np.exp(-(times - 20) / 8.0))  # fmt: skip
    inst = fw.instrument_preset("gedi").with_overrides(pulse=MeasuredPulse(tailed, 1.0))
    stand = fw.Stand.from_arrays(x=[0.0], y=[0.0], height=[20.0], crown_length=[8.0],
                                 crown_radius=[200.0], favd=[0.3], shape="cylinder")  # fmt: skip
    heights = np.arange(-80, 220) * inst.bin_height
    wf = fw.WaveformSimulator(inst).simulate(stand, center=(0.0, 0.0), heights=heights)
    exact = 1 - np.exp(-inst.extinction_per_favd * 0.3 * 8.0)
    kwargs = {"rho_ratio": 0.45 / 0.3, "extinction": inst.extinction_per_favd}
    mirrored = gap_profile(wf.samples, wf.heights, 0.0, **kwargs).cover
    with_cdf = gap_profile(wf.samples, wf.heights, 0.0, ground_cdf=ground_return_cdf(inst.pulse),
                           **kwargs).cover  # fmt: skip
    assert with_cdf == pytest.approx(exact, abs=2e-3)
    assert mirrored < exact - 0.05


def test_pavd_layers_integrate_to_the_pai():
    inst, wf = _slab(0.3)
    profile = gap_profile(wf.samples, wf.heights, 0.0, extinction=inst.extinction_per_favd)
    layers = profile.layer_pavd(5.0)
    assert layers.size == int(np.ceil(profile.height[-1] / 5.0))
    assert np.sum(layers) * 5.0 == pytest.approx(profile.pai, rel=1e-9)
    # the slab's top 5 m (15–20 m) hold 1.5 m² m⁻²; the pulse spreads some above 20 m
    assert (layers[3] + layers[4]) * 5.0 == pytest.approx(0.3 * 5.0, rel=0.02)
    assert np.all(np.abs(layers[:2]) < 1e-3)


def test_gap_profile_rejects_a_ground_outside_the_window():
    _, wf = _slab(0.3)
    with pytest.raises(ValueError, match="outside"):
        gap_profile(wf.samples, wf.heights, -50.0)
    with pytest.raises(ValueError, match="positive"):
        gap_profile(wf.samples, wf.heights, 0.0, rho_ratio=0.0)
