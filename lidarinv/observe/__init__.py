"""Observations: the observation model, noise, signal extent, ground peak, quality flags
and direct metrics. Everything between a waveform file and the inversion."""

from .analyse import QUALITY_FLAGS, STATUSES, ShotAnalysis, analyse
from .ground import GroundPeak, Mode, find_ground, find_modes
from .instrument import pulse_fwhm_m, shot_instrument, transmit_pulse
from .metrics import ALL_PERCENTILES, GapProfile, gap_profile, rh_metrics
from .noise import NoiseModel, estimate_noise, noise_floor, product_noise
from .observation import AXIS_KINDS, Observation, ShotError
from .processing import PROCESSING_DEFAULTS, ProcessingSettings, processing_settings
from .quality import clipped_plateau, sensitivity
from .signal import SignalExtent, signal_extent, smooth
from .simulate import observe

__all__ = [
    "ALL_PERCENTILES",
    "AXIS_KINDS",
    "PROCESSING_DEFAULTS",
    "QUALITY_FLAGS",
    "STATUSES",
    "GapProfile",
    "GroundPeak",
    "Mode",
    "NoiseModel",
    "Observation",
    "ProcessingSettings",
    "ShotAnalysis",
    "ShotError",
    "SignalExtent",
    "analyse",
    "clipped_plateau",
    "estimate_noise",
    "find_ground",
    "find_modes",
    "gap_profile",
    "noise_floor",
    "observe",
    "processing_settings",
    "product_noise",
    "pulse_fwhm_m",
    "rh_metrics",
    "sensitivity",
    "shot_instrument",
    "signal_extent",
    "smooth",
    "transmit_pulse",
]
