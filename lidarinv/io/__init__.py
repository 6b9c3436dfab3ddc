"""File formats: the lidarinv HDF5 waveform layout and the GEDI/LVIS L1B readers."""

from .formats import FORMATS, detect_format, iter_observations
from .waveforms import read_observations, read_stand_from, write_observations

__all__ = [
    "FORMATS",
    "detect_format",
    "iter_observations",
    "read_observations",
    "read_stand_from",
    "write_observations",
]
