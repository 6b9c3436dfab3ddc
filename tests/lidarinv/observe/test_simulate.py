"""The observation model: read and shot noise, correlated noise, quantisation, censoring."""

import numpy as np
import pytest

from lidarinv.observe import observe


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


def test_correlated_read_noise_has_the_filter_autocorrelation(rng):
    w, h = _flat(40000)
    kernel = np.exp(-0.5 * (np.arange(-6, 7) / 2.0) ** 2)
    obs = observe(w, heights=h, gain=1.0, baseline=5.0, noise_sigma=2.0, rng=rng,
                  noise_filter=kernel)  # fmt: skip
    x = obs.samples - 5.0
    assert x.std() == pytest.approx(2.0, rel=0.03)
    expected = [np.sum(kernel[:-k] * kernel[k:]) / np.sum(kernel**2) for k in (1, 2, 3)]
    measured = [np.mean(x[:-k] * x[k:]) / x.var() for k in (1, 2, 3)]
    np.testing.assert_allclose(measured, expected, atol=0.03)
    with pytest.raises(ValueError, match="noise filter"):
        observe(w, heights=h, gain=1, baseline=0, noise_sigma=1, rng=rng, noise_filter=[0.0])


def test_the_observation_records_its_instrument(rng, gedi):
    w, h = _flat(100)
    assert observe(w, heights=h, gain=1, baseline=0, noise_sigma=1, rng=rng).instrument is None
    obs = observe(w, heights=h, gain=1, baseline=0, noise_sigma=1, rng=rng, instrument=gedi)
    assert obs.instrument == "gedi"
