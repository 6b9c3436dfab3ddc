"""File formats: the lidarinv HDF5 waveform layout, the GEDI/LVIS L1B readers, the NASA
products to compare with, and the real example files shipped with lidarinv."""

from .examples import EXAMPLE_FILES, example_file
from .formats import FORMATS, detect_format, iter_observations
from .products import read_gedi_l2a, read_gedi_l2b, read_lvis_l2
from .waveforms import read_observations, read_stand_from, write_observations

__all__ = [
    "EXAMPLE_FILES",
    "FORMATS",
    "detect_format",
    "example_file",
    "iter_observations",
    "read_gedi_l2a",
    "read_gedi_l2b",
    "read_lvis_l2",
    "read_observations",
    "read_stand_from",
    "write_observations",
]
