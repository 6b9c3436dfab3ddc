"""Readers and the shot analysis on the real GEDI and LVIS shots shipped with lidarinv.

Light checks only: the full comparison with the NASA products is
``studies/real_products.py``. Expectations come from the products read at test time.
"""

import numpy as np
import pytest

from lidarinv.io import (
    example_file,
    iter_observations,
    read_gedi_l2a,
    read_gedi_l2b,
    read_lvis_l2,
)
from lidarinv.observe import Observation, analyse, pulse_fwhm_m, shot_instrument
from lidarinv.observe.signal import smooth

C = 0.299792458  # m/ns


@pytest.fixture(scope="module")
def gedi():
    shots = list(iter_observations(example_file("gedi-l1b")))
    return shots, [analyse(s) for s in shots], read_gedi_l2a(example_file("gedi-l2a"))


@pytest.fixture(scope="module")
def lvis():
    shots = list(iter_observations(example_file("lvis-l1b")))
    return shots, [analyse(s) for s in shots], read_lvis_l2(example_file("lvis-l2"))


def test_gedi_reader_on_real_shots(gedi):
    shots, _, l2a = gedi
    assert all(isinstance(s, Observation) for s in shots)
    assert {s.shot_id for s in shots} == set(l2a)
    for obs in shots:
        assert isinstance(obs.shot_id, int) and obs.instrument == "gedi"
        assert obs.axis_kind == "elevation" and 600 < obs.n_bins < 1500
        assert obs.bin_size == pytest.approx(C / 2, rel=0.01)  # 1 ns bins
        assert obs.metadata["beam"].startswith("BEAM") and -90 < obs.metadata["latitude"] < 90
        assert obs.pulse.size == 128 and obs.pulse_ns == 1.0
        fwhm_ns = pulse_fwhm_m(shot_instrument(obs).pulse) * 2 / C
        assert 10.0 < fwhm_ns < 25.0  # GEDI's pulse: about 15 ns
        assert np.isfinite(obs.noise_mean) and obs.noise_sigma > 0  # the L1B noise fields


def test_lvis_reader_on_real_shots(lvis):
    shots, _, l2 = lvis
    assert all(isinstance(s, Observation) for s in shots)
    assert {s.shot_id for s in shots} >= set(l2)
    for obs in shots:
        assert isinstance(obs.shot_id, int) and isinstance(obs.metadata["lfid"], int)
        assert obs.instrument == "lvis" and obs.n_bins == 1024
        assert np.all(obs.samples == np.round(obs.samples))  # integer counts
        assert obs.pulse.size == 128
        fwhm_ns = pulse_fwhm_m(shot_instrument(obs).pulse) * 2 / C
        assert 6.0 < fwhm_ns < 16.0


def test_every_real_shot_gets_a_status_and_its_noise(gedi, lvis):
    for shots, results, _ in (gedi, lvis):
        for _obs, result in zip(shots, results):
            assert result.status == "ok" or result.reason
            assert result.noise is not None and result.noise.sigma > 0
            assert result.noise.source == "samples"
    # GEDI's digitiser noise is strongly correlated from bin to bin, LVIS's less
    gedi_r1 = np.median([r.noise.autocorrelation[1] for r in gedi[1]])
    lvis_r1 = np.median([r.noise.autocorrelation[1] for r in lvis[1]])
    assert gedi_r1 > 0.8 and 0.2 < lvis_r1 < 0.8


def test_real_grounds_agree_with_the_products(gedi, lvis):
    shots, results, l2a = gedi
    quality = [
        (r, l2a[s.shot_id]) for s, r in zip(shots, results) if l2a[s.shot_id]["quality_flag"]
    ]
    d = np.array([r.ground - p["elev_lowestmode"] for r, p in quality if r.ok])
    assert d.size >= 0.9 * len(quality) and np.mean(np.abs(d) < 1.0) >= 0.9
    shots, results, l2 = lvis
    d = np.array([r.ground - l2[s.shot_id]["zg"] for s, r in zip(shots, results)
                  if r.ok and s.shot_id in l2])  # fmt: skip
    assert np.mean(np.abs(d) < 1.0) >= 0.9


def test_a_lone_real_peak_is_ground_under_a_low_canopy(gedi):
    """A GEDI shot with a single mode: the ground is that peak, the canopy low."""
    shots, results, _ = gedi
    single = [(s, r) for s, r in zip(shots, results) if r.ok and r.n_modes == 1]
    assert single
    for obs, result in single:
        smoothed = smooth(obs.samples, result.smoothing_bins)
        peak = obs.axis[np.argmax(smoothed)]
        assert abs(result.ground - peak) < obs.bin_size
        assert result.rh[98] < 12.0


def test_a_two_layer_real_shot_has_its_ground_at_the_lowest_mode(lvis):
    shots, results, l2 = lvis
    layered = [
        (s, r) for s, r in zip(shots, results) if r.ok and r.n_modes >= 2 and s.shot_id in l2
    ]
    assert layered
    for obs, result in layered:
        assert abs(result.ground - l2[obs.shot_id]["zg"]) < 1.0
        assert result.rh[98] > 5.0


def test_product_readers():
    l2b = read_gedi_l2b(example_file("gedi-l2b"))
    record = next(iter(l2b.values()))
    assert 0 <= record["cover"] <= 1 and record["pavd_z"].shape == (30,)
    assert record["rhov"] / record["rhog"] == pytest.approx(1.5, rel=1e-3)
    lvis = read_lvis_l2(example_file("lvis-l2"))
    record = next(iter(lvis.values()))
    assert record["rh"].shape == (101,) and np.isnan(record["rh"][5])
    assert record["zt"] - record["zg"] == pytest.approx(record["rh"][100], abs=0.02)
    with pytest.raises(ValueError, match="unknown example"):
        example_file("icesat")


def test_metrics_and_the_inversion_read_a_shot_alike(gedi, lvis):
    """The inversion's shot uses the same analysis: same status, ground and extent."""
    from lidarinv.inference import InversionSettings
    from lidarinv.inference.shot import Shot

    settings = InversionSettings()
    for shots, results, _ in (gedi, lvis):
        for obs, result in list(zip(shots, results))[:6]:
            quick = analyse(obs, metrics=False)
            assert quick.rh is None and quick.status == result.status
            assert quick.ground == result.ground and quick.signal_start == result.signal_start
            if result.ok:
                shot = Shot.from_observation(obs, settings)
                assert shot.analysis.ground == result.ground
                assert shot.analysis.signal_end == result.signal_end
            else:
                with pytest.raises(ValueError, match=result.status):
                    Shot.from_observation(obs, settings)


def test_a_clipped_shot_is_inverted_with_its_plateau_censored(gedi):
    """A real shot clipped below its peak, in a file without a saturation level: the
    analysis flags it and the inversion's window treats the plateau as saturated."""
    from dataclasses import replace

    from lidarinv.inference import InversionSettings
    from lidarinv.inference.shot import Shot

    obs = gedi[0][0]
    level = obs.noise_mean + 0.6 * (obs.samples.max() - obs.noise_mean)
    clipped = replace(obs, samples=np.minimum(obs.samples, level))
    assert "clipped" in analyse(clipped).flags
    shot = Shot.from_observation(clipped, InversionSettings())
    assert shot.window.saturated.sum() >= 3 and shot.window.saturation == pytest.approx(level)
