"""forward: the lidar waveform physics of lidarinv (Sun & Ranson 2000, extended).

It follows the project's physics conventions: heights in m above the ground, times in ns,
single scattering through turbid crowns with the hot-spot gap probability
P(z) = exp(−k·G·Ω·L(z)), a Gaussian footprint and a unit-area pulse.
This package never imports ``lidarinv``.
"""

from .allometry import SPECIES_ALLOMETRY, Allometry
from .constants import SPEED_OF_LIGHT_M_PER_NS, height_to_ns, ns_to_height
from .crowns import CROWN_SHAPES, SHAPE_NAMES
from .engine import AccuracySettings, PreparedStand, WaveformSimulator
from .instrument import INSTRUMENT_PRESETS, Instrument, instrument_preset
from .pulse import PULSE_TYPES, GaussianPulse, MeasuredPulse
from .scene import Ground, UniformUnderstory
from .stand import Stand
from .stand_io import load_stand, save_stand
from .waveform import Waveform

__all__ = [
    "CROWN_SHAPES",
    "INSTRUMENT_PRESETS",
    "PULSE_TYPES",
    "SHAPE_NAMES",
    "SPECIES_ALLOMETRY",
    "SPEED_OF_LIGHT_M_PER_NS",
    "AccuracySettings",
    "Allometry",
    "GaussianPulse",
    "Ground",
    "Instrument",
    "MeasuredPulse",
    "PreparedStand",
    "Stand",
    "UniformUnderstory",
    "Waveform",
    "WaveformSimulator",
    "height_to_ns",
    "instrument_preset",
    "load_stand",
    "ns_to_height",
    "save_stand",
]
