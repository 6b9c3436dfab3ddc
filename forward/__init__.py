"""forward: the lidar waveform physics of lidarinv (Sun & Ranson 2000, extended).

It follows the project's physics conventions: heights in m above the ground, times in ns,
single scattering through turbid crowns with the hot-spot gap probability
P(z) = exp(−k·G·Ω·L(z)), a Gaussian footprint and a unit-area pulse.
This package never imports ``lidarinv``.

Two engines share the process modules at the top of the package: :mod:`forward.explicit`
(waveforms of a stem map, :class:`WaveformSimulator`) and :mod:`forward.expected` (the
expected waveform of a Poisson stand, :class:`ExpectedWaveformModel`). The process
modules are written once and called by both: the pulse and its ground return
(:mod:`.pulse`), the footprint weight (:mod:`.footprint`), the crown shapes and the
crown radius (:mod:`.crowns`), the instrument (:mod:`.instrument`) and the one switch
between numpy references and compiled kernels (:mod:`.backends`). The stand descriptions
(:mod:`.stand`, :mod:`.stand_params`, :mod:`.scene`, :mod:`.realise`, ...) feed both.
"""

from .allometry import SPECIES_ALLOMETRY, Allometry
from .constants import SPEED_OF_LIGHT_M_PER_NS, height_to_ns, ns_to_height
from .crowns import CROWN_SHAPES, SHAPE_NAMES
from .derived import (
    canopy_cover,
    crown_volume_per_ha,
    crown_volume_profile,
    dominant_height,
    expected_max_height,
    leaf_area_index,
    mean_height,
)
from .expected import (
    CONVERGED,
    DEFAULT_FREE,
    MIX_FIELDS,
    VECTOR_FIELDS,
    ExpectedWaveformModel,
    ExpectedWaveforms,
    ModelSettings,
)
from .explicit import AccuracySettings, PreparedStand, Waveform, WaveformSimulator
from .instrument import INSTRUMENT_PRESETS, Instrument, instrument_preset
from .paper_stands import SUCCESSIONAL, jack_pine_params, successional_params
from .pulse import PULSE_TYPES, GaussianPulse, MeasuredPulse
from .realise import POINT_PATTERNS, realise, scene_extras
from .scene import Ground, UniformUnderstory
from .stand import Stand
from .stand_io import load_stand, save_stand
from .stand_params import HEIGHT_DISTRIBUTIONS, StandParams, height_distribution

__all__ = [
    "CONVERGED",
    "CROWN_SHAPES",
    "DEFAULT_FREE",
    "HEIGHT_DISTRIBUTIONS",
    "INSTRUMENT_PRESETS",
    "MIX_FIELDS",
    "POINT_PATTERNS",
    "PULSE_TYPES",
    "SHAPE_NAMES",
    "SPECIES_ALLOMETRY",
    "SPEED_OF_LIGHT_M_PER_NS",
    "SUCCESSIONAL",
    "VECTOR_FIELDS",
    "AccuracySettings",
    "Allometry",
    "ExpectedWaveformModel",
    "ExpectedWaveforms",
    "GaussianPulse",
    "Ground",
    "Instrument",
    "MeasuredPulse",
    "ModelSettings",
    "PreparedStand",
    "Stand",
    "StandParams",
    "UniformUnderstory",
    "Waveform",
    "WaveformSimulator",
    "canopy_cover",
    "crown_volume_per_ha",
    "crown_volume_profile",
    "dominant_height",
    "expected_max_height",
    "height_distribution",
    "height_to_ns",
    "instrument_preset",
    "jack_pine_params",
    "leaf_area_index",
    "load_stand",
    "mean_height",
    "ns_to_height",
    "realise",
    "save_stand",
    "scene_extras",
    "successional_params",
]
