"""The warning for a lowest return that may be the base of a closed canopy, not the ground."""

import numpy as np
import pytest

from forward import instrument_preset
from forward.pulse import GaussianPulse
from lidarinv.inference import InversionSettings
from lidarinv.inference.passes.hidden_ground import hidden_ground_note, widest_ground_flank_m
from lidarinv.inference.shot import Shot
from lidarinv.observe import Observation


def _gedi_like(layers, rng):
    """A GEDI-preset shot (Gaussian pulse, 0.15 m bins, 2 DN white noise on 100 DN) whose
    returns are Gaussians ``(centre m, σ m, amplitude DN)``."""
    axis = np.arange(-20.0, 60.0, instrument_preset("gedi").bin_height)
    samples = 100.0 + rng.normal(0.0, 2.0, axis.size)
    for centre, sigma, amplitude in layers:
        samples += amplitude * np.exp(-0.5 * ((axis - centre) / sigma) ** 2)
    return Observation(samples, axis, shot_id=1, instrument="gedi")


@pytest.mark.parametrize("broadening, smoothing", [(0.0, 0.3), (1.2, 0.5)])
def test_the_widest_ground_flank_of_a_gaussian_pulse_adds_in_quadrature(broadening, smoothing):
    pulse = GaussianPulse(15.0)
    expected = np.sqrt(pulse.sigma_m**2 + broadening**2 + smoothing**2)
    assert widest_ground_flank_m(pulse, broadening, smoothing) == pytest.approx(expected, rel=0.02)


def test_a_lone_ground_peak_raises_no_warning():
    rng = np.random.default_rng(3)
    sigma = instrument_preset("gedi").pulse.sigma_m
    shot = Shot.from_observation(_gedi_like([(0.0, sigma, 60.0)], rng), InversionSettings())
    # its lower flank: the pulse smoothed as the analysis smooths, give or take a bin
    smoothing = shot.analysis.smoothing_bins * shot.observation.bin_size
    expected = np.hypot(sigma, smoothing)
    assert shot.analysis.ground_width == pytest.approx(expected, abs=shot.observation.bin_size)
    assert hidden_ground_note(shot) is None


def test_a_closed_canopy_without_a_ground_return_is_flagged():
    # the crowns' base 3 m deep below its mode at 10 m, their tops at 18 m; no ground return
    rng = np.random.default_rng(3)
    shot = Shot.from_observation(
        _gedi_like([(10.0, 3.0, 40.0), (18.0, 2.0, 60.0)], rng), InversionSettings()
    )
    assert shot.analysis.ground == pytest.approx(10.0, abs=1.0)
    note = hidden_ground_note(shot)
    assert note is not None and note.startswith("ground may be hidden")
