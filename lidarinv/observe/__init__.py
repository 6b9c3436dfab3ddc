"""Observations: the observation model, noise, signal extent, ground peak, alignment and
direct metrics. Everything between a waveform file and the inversion."""

from .align import AlignedAverage, align_and_average
from .analyse import STATUSES, ShotAnalysis, analyse, resolve_noise
from .ground import GroundPeak, find_ground
from .metrics import ALL_PERCENTILES, GapProfile, gap_profile, rh_metrics
from .noise import NoiseEstimate, estimate_noise, half_sample_mode, noise_floor
from .observation import AXIS_KINDS, Observation, ShotError
from .signal import SignalExtent, signal_extent, smooth, smoothed_noise_factor
from .simulate import observe

__all__ = [
    "ALL_PERCENTILES",
    "AXIS_KINDS",
    "STATUSES",
    "AlignedAverage",
    "GapProfile",
    "GroundPeak",
    "NoiseEstimate",
    "Observation",
    "ShotAnalysis",
    "ShotError",
    "SignalExtent",
    "align_and_average",
    "analyse",
    "estimate_noise",
    "find_ground",
    "gap_profile",
    "half_sample_mode",
    "noise_floor",
    "observe",
    "resolve_noise",
    "rh_metrics",
    "signal_extent",
    "smooth",
    "smoothed_noise_factor",
]
