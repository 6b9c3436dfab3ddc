"""The explicit engine: waveforms of a stem map, footprint by footprint.

:class:`WaveformSimulator` sums the gap profiles of vertical columns over the Gaussian
footprint, each column crossing every crown above it exactly, and convolves the layer
returns and the ground with the pulse (Sun & Ranson 2000, extended to overlapping crowns,
sloped ground and a uniform understory). It shares the process modules of :mod:`forward`
with the expected engine (:mod:`forward.expected`): the pulse and its ground return
(:mod:`forward.pulse`), the footprint weight (:mod:`forward.footprint`), the crown shapes
(:mod:`forward.crowns`), the instrument and the one backend switch (:mod:`forward.backends`).

Modules: :mod:`.engine` (the simulator and the per-stand work), :mod:`.accuracy` (a
tolerance and the resolution it buys), :mod:`.column_grid` (the footprint's columns and
the crowns near it), :mod:`.column_kernel` (the footprint sums, numpy reference and
backend switch) with its compiled twin :mod:`.column_kernel_numba`, :mod:`.gap` (gap
profiles exact at the layer edges), :mod:`.render` (profiles to samples), :mod:`.waveform`
(the result) and :mod:`.crown_quadrature` (the per-crown quadrature of earlier versions,
kept as a reference).

References
----------
Sun, G. & Ranson, K. J. (2000). Modeling lidar returns from forest canopies. *IEEE Trans.
Geosci. Remote Sens.* 38(6), 2617–2626.
"""

from .accuracy import AccuracySettings
from .engine import DEFAULT_CANOPY_REFLECTANCE, PreparedStand, WaveformSimulator
from .waveform import Waveform

__all__ = [
    "DEFAULT_CANOPY_REFLECTANCE",
    "AccuracySettings",
    "PreparedStand",
    "Waveform",
    "WaveformSimulator",
]
