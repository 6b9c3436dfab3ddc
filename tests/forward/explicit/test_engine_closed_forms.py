"""The explicit engine against closed forms and a brute-force reference."""

import numpy as np
import pytest
from scipy import integrate
from scipy.special import i0e

import forward as fw
from lidarinv.testing.reference_model import reference_waveform


def test_bare_ground_is_the_pulse_times_ground_reflectance(gedi):
    sim = fw.WaveformSimulator(gedi)
    wf = sim.simulate(fw.Stand.empty(), ground=fw.Ground(reflectance=0.37))
    expected = 0.37 * gedi.bin_height * gedi.pulse.pdf(wf.heights)
    # the pulse is cut where each tail holds < 1e-9 of its area
    np.testing.assert_allclose(wf.samples, expected, rtol=1e-12, atol=1e-9)
    assert wf.samples.sum() == pytest.approx(0.37, rel=1e-8)
    assert wf.heights[np.argmax(wf.samples)] == pytest.approx(0.0, abs=1e-12)
    assert np.all(wf.canopy == 0)


def test_measured_pulse_peak_is_registered_at_the_ground():
    times = np.arange(40.0)
    tail = np.where(times >= 12, 0.3 * np.exp(-(times - 12) / 6.0), 0.0)
    tx = np.exp(-0.5 * ((times - 12) / 3.0) ** 2) + tail
    inst = fw.Instrument(fw.MeasuredPulse(tx, 1.0), 1.0, 5.5)
    wf = fw.WaveformSimulator(inst).simulate(fw.Stand.empty(), ground=fw.Ground(0.5))
    assert wf.heights[np.argmax(wf.samples)] == pytest.approx(0.0, abs=1e-9)
    assert wf.samples.sum() == pytest.approx(0.5, rel=1e-3)
    # the late-time tail of the transmit pulse lies below the ground in height
    below = wf.samples[wf.heights < -1].sum()
    above = wf.samples[wf.heights > 1].sum()
    assert below > 2 * above


@pytest.mark.parametrize("k", [1.0, 1.5, 2.0])
def test_slab_wider_than_footprint_follows_beer_lambert(gedi, k):
    inst = gedi.with_overrides(hotspot_k=k)
    u, top, length, rho_v = 0.4, 22.0, 9.0, 0.5
    slab = fw.Stand.from_arrays(
        x=[4.0],
        y=[-2.0],
        height=[top],
        crown_length=[length],
        crown_radius=[800.0],
        favd=u,
        shape="cylinder",
    )
    wf = fw.WaveformSimulator(inst).simulate(slab, canopy_reflectance=rho_v)
    alpha = inst.extinction_per_favd * u
    assert wf.ground_gap == pytest.approx(np.exp(-alpha * length), rel=1e-12)

    def sample(z):  # ρv α exp(−α(top − z')) on the slab, convolved with the pulse
        f = lambda zp: rho_v * alpha * np.exp(-alpha * (top - zp)) * inst.pulse.pdf(z - zp)
        return inst.bin_height * integrate.quad(f, top - length, top, epsabs=1e-13)[0]

    expected = np.array([sample(z) for z in wf.heights])
    scale = wf.canopy.max()
    np.testing.assert_allclose(wf.canopy, expected, atol=2e-3 * scale)
    # the gap profile is exact at layer edges and linear between them: compare away from
    # the slab's top and base, where P has a kink
    inside = (wf.heights > top - length + 0.2) & (wf.heights < top - 0.2)
    exact = np.exp(-alpha * np.clip(top - wf.heights[inside], 0, length))
    np.testing.assert_allclose(wf.gap[inside], exact, rtol=1e-3)


def weighted_crown_volume(shape, stem_offset, radius, length, sigma):
    """∫ w(x)·ℓ(x) dA for one crown: the angular integral of the Gaussian is a Bessel I0."""
    crown = fw.CROWN_SHAPES[shape]

    def integrand(r):
        s_low, s_high = crown.extent(np.array([r / radius]))
        path = length * (s_high - s_low)[0]
        d = stem_offset
        bessel = i0e(d * r / sigma**2) * np.exp(-((d - r) ** 2) / (2 * sigma**2))
        return path * bessel * r / sigma**2

    return integrate.quad(integrand, 0, radius, limit=200, epsabs=1e-14)[0]


@pytest.mark.parametrize("shape", fw.SHAPE_NAMES)
def test_thin_crowns_return_the_weighted_crown_volume(gedi, shape):
    u, rho_v = 1e-7, 0.5
    offset, radius, length = 3.0, 2.5, 6.0
    stand = fw.Stand.from_arrays(
        x=[offset],
        y=[0.0],
        height=[15.0],
        crown_length=[length],
        crown_radius=[radius],
        favd=u,
        shape=shape,
    )
    accurate = fw.AccuracySettings(radial_nodes=24, angular_nodes=64, truncation_tolerance=1e-12)
    volume = weighted_crown_volume(shape, offset, radius, length, gedi.footprint_sigma_m)
    expected = rho_v * gedi.extinction_per_favd * u * volume
    wf = fw.WaveformSimulator(gedi, accurate).simulate(stand, canopy_reflectance=rho_v)
    assert wf.canopy_energy == pytest.approx(expected, rel=1e-4)
    assert wf.crown_volume.sum() == pytest.approx(volume, rel=1e-4)
    # default settings are within half a percent
    default = fw.WaveformSimulator(gedi).simulate(stand, canopy_reflectance=rho_v)
    assert default.canopy_energy == pytest.approx(expected, rel=5e-3)


def test_engine_matches_brute_force_reference(rng):
    inst = fw.instrument_preset("gedi", footprint_sigma_m=1.5, pulse_fwhm_ns=6.0)
    stand = fw.Stand.from_arrays(
        x=[0.5, -1.8, 2.2, -0.4, 3.5],
        y=[0.2, 1.1, -1.6, -2.7, 2.0],
        height=[14.0, 11.0, 16.0, 9.0, 13.0],
        crown_length=[6.0, 5.0, 8.0, 4.0, 7.0],
        crown_radius=[1.6, 1.4, 2.2, 1.2, 1.8],
        favd=[0.6, 1.0, 0.4, 0.8, 0.5],
        shape=["cone", "ellipsoid", "hemi-ellipsoid", "cylinder", "ellipsoid"],
    )
    sim = fw.WaveformSimulator(inst, fw.AccuracySettings(radial_nodes=16, angular_nodes=48))
    wf = sim.simulate(stand)
    expected, ground_gap = reference_waveform(stand, inst, wf.heights, spacing=0.03, fine=0.01)
    assert wf.ground_gap == pytest.approx(ground_gap, abs=2e-3)
    error = np.abs(wf.samples - expected).sum() / expected.sum()
    assert error < 5e-3


def test_energy_is_conserved_and_gap_is_monotone(gedi, rng):
    from tests.conftest import random_stand

    stand = random_stand(rng, n=120)
    wf = fw.WaveformSimulator(gedi).simulate(stand, canopy_reflectance=0.6, ground=fw.Ground(0.25))
    assert wf.canopy_energy == pytest.approx(0.6 * (1 - wf.ground_gap), rel=1e-12)
    assert wf.canopy.sum() == pytest.approx(0.6 * (1 - wf.ground_gap), rel=1e-8)
    assert wf.ground.sum() == pytest.approx(0.25 * wf.ground_gap, rel=1e-8)
    assert np.all((wf.gap >= 0) & (wf.gap <= 1))
    assert np.all(np.diff(wf.gap) >= -1e-15)
    assert np.all(wf.samples >= 0)


def test_understory_layer_factorises_the_gap(gedi):
    layer = fw.UniformUnderstory(height=2.0, lai=0.8)
    wf = fw.WaveformSimulator(gedi).simulate(fw.Stand.empty(), understory=layer)
    assert wf.ground_gap == pytest.approx(np.exp(-gedi.extinction_per_favd * 0.8), rel=1e-12)
    assert wf.foliage_area.sum() == pytest.approx(0.8, rel=1e-9)
    assert wf.canopy.sum() == pytest.approx(0.45 * (1 - wf.ground_gap), rel=1e-8)


def test_footprint_crown_cover_is_nought_one_or_the_weighted_disc_of_a_centred_crown():
    """No crown: 0. A crown over the whole 3σf disc: 1. One crown of radius r at the beam
    centre: the Gaussian weight inside r over the weight inside 3σf."""
    from forward.footprint import footprint_crown_cover
    from forward.stand import Stand

    sigma = 6.0

    def one(radius, x=0.0):
        return Stand.from_arrays(x=[x], y=[0.0], height=[10.0], crown_length=[5.0],
                                 crown_radius=[radius], favd=0.5)  # fmt: skip

    assert footprint_crown_cover(one(2.0, x=30.0), (0.0, 0.0), sigma) == 0.0
    assert footprint_crown_cover(one(3.0 * sigma + 0.5), (0.0, 0.0), sigma) == 1.0
    r = 5.0
    expected = (1 - np.exp(-(r**2) / (2 * sigma**2))) / (1 - np.exp(-4.5))
    assert footprint_crown_cover(one(r), (0.0, 0.0), sigma) == pytest.approx(expected, rel=0.01)
