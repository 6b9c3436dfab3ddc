"""The observation model and robust noise estimation."""

import numpy as np
import pytest

import forward as fw
from lidarinv.observe import estimate_noise, noise_floor, observe


def _flat(n=20000, level=0.0):
    return np.full(n, level), np.arange(n) * 0.15


def test_read_noise_statistics(rng):
    w, h = _flat()
    obs = observe(w, heights=h, gain=500.0, baseline=30.0, noise_sigma=2.0, rng=rng)
    # mean and σ of 20 000 draws: standard errors 0.014 and 0.01
    assert obs.samples.mean() == pytest.approx(30.0, abs=0.06)
    assert obs.samples.std() == pytest.approx(2.0, rel=0.02)


def test_shot_noise_adds_variance_in_proportion_to_signal(rng):
    w, h = _flat(level=0.2)
    a, s, g = 400.0, 1.5, 0.3
    obs = observe(w, heights=h, gain=a, baseline=10.0, noise_sigma=s, shot_factor=g, rng=rng)
    assert obs.samples.mean() == pytest.approx(10.0 + a * 0.2, abs=0.1)
    assert obs.samples.var() == pytest.approx(s**2 + g * a * 0.2, rel=0.05)


def test_quantise_saturate_and_censor(rng):
    w = np.concatenate([np.zeros(500), np.linspace(0, 1, 500)])
    h = np.arange(w.size) * 0.15
    obs = observe(w, heights=h, gain=100.0, baseline=5.0, noise_sigma=1.0, rng=rng,
                  quantise=True, saturation=80.0, floor_sigmas=3.0)  # fmt: skip
    assert np.all(obs.samples == np.round(obs.samples))
    assert obs.samples.max() == 80.0 and obs.saturated_mask.sum() > 50
    # censored samples sit at the floor and are flagged; no sample lies below it
    assert obs.floor == pytest.approx(8.0)
    assert obs.samples.min() >= obs.floor
    assert np.all(obs.samples[obs.censored] == obs.floor)
    # nearly all of the 500 noise-only samples fall under b + 3σ (99.87 %)
    assert obs.censored[:500].mean() > 0.97
    assert not obs.valid_mask[obs.censored].any()


def test_same_seed_same_observation():
    w, h = _flat(200, 0.1)
    kwargs = {"heights": h, "gain": 10.0, "baseline": 1.0, "noise_sigma": 0.5}
    a = observe(w, rng=np.random.default_rng(3), **kwargs)
    b = observe(w, rng=np.random.default_rng(3), **kwargs)
    np.testing.assert_array_equal(a.samples, b.samples)


def test_observe_rejects_bad_input(rng):
    w, h = _flat(100)
    with pytest.raises(ValueError, match="NaN"):
        observe(np.where(h > 3, np.nan, w), heights=h, gain=1, baseline=0, noise_sigma=1, rng=rng)
    with pytest.raises(ValueError, match="gain"):
        observe(w, heights=h, gain=0, baseline=0, noise_sigma=1, rng=rng)
    with pytest.raises(ValueError, match="Generator"):
        observe(w, heights=h, gain=1, baseline=0, noise_sigma=1, rng=np.random.RandomState(1))


@pytest.fixture(scope="module")
def forest_waveform():
    inst = fw.instrument_preset("gedi")
    stand = fw.Stand.from_arrays(x=[0.0, 4.0, -3.0], y=[0.0, -2.0, 3.0], height=[22.0, 17.0, 12.0],
                                 crown_length=[9.0, 7.0, 5.0], crown_radius=[4.0, 3.5, 3.0],
                                 favd=0.6, shape="ellipsoid")  # fmt: skip
    heights = np.arange(-100, 500) * inst.bin_height  # signal in ~1/3 of the window
    return fw.WaveformSimulator(inst).simulate(stand, center=(0.0, 0.0), heights=heights)


@pytest.mark.parametrize("method", ["ends", "histogram"])
def test_noise_estimates_are_unbiased_on_forest_waveforms(forest_waveform, method):
    rng = np.random.default_rng(7)
    means, sigmas = [], []
    for _ in range(200):
        obs = observe(forest_waveform, gain=300.0, baseline=20.0, noise_sigma=1.0, rng=rng)
        est = estimate_noise(obs.samples, method=method)
        means.append(est.mean)
        sigmas.append(est.sigma)
    # the returns must not pull the estimates up (ends: ≤ 0.05σ; histogram: ≤ 0.1σ)
    assert np.mean(means) == pytest.approx(20.0, abs=0.05 if method == "ends" else 0.1)
    assert np.mean(sigmas) == pytest.approx(1.0, rel=0.05)
    assert np.std(means) < 0.3


def test_noise_floor_and_bad_noise_input():
    assert noise_floor(10.0, 2.0, 3.0) == 16.0
    with pytest.raises(ValueError):
        noise_floor(np.nan, 1.0, 3.0)
    with pytest.raises(ValueError, match="NaN"):
        estimate_noise([1.0, np.nan, 2.0])
    with pytest.raises(ValueError, match="unknown noise method"):
        estimate_noise(np.zeros(50), method="magic")
    with pytest.raises(ValueError, match="too short"):
        estimate_noise(np.zeros(10))
