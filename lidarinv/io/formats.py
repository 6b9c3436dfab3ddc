"""Waveform file formats: a registry with automatic detection, and shot streaming."""

import h5py

from . import gedi_l1b, lvis_l1b, waveforms
from .simulation import is_simulation

#: Format name → module with ``detect``, ``beams``, ``count_shots`` and ``iter_shots``.
FORMATS = {
    waveforms.NAME: waveforms,
    gedi_l1b.NAME: gedi_l1b,
    lvis_l1b.NAME: lvis_l1b,
}


def detect_format(handle) -> str:
    """Name of the registered format of an open HDF5 file."""
    for name, module in FORMATS.items():
        if module.detect(handle):
            return name
    if is_simulation(handle):
        raise ValueError(
            f"{handle.filename} holds noise-free waveforms from 'lidarinv simulate' "
            "(apparent reflectance, no gain or noise), not observations: read them with "
            "lidarinv.io.simulation.read_simulation, observe them with "
            "lidarinv.observe.observe and write them with lidarinv.io.write_observations"
        )
    raise ValueError(
        f"{handle.filename}: not a recognised waveform file (formats: {list(FORMATS)})"
    )


def iter_observations(path, format="auto", beams=None, shots=None):
    """Stream the shots of a waveform file.

    Parameters
    ----------
    path : str or Path
        HDF5 file.
    format : str
        ``"auto"`` or a name in :data:`FORMATS`.
    beams : sequence of str, optional
        Beams to read (GEDI); default all.
    shots : slice or sequence of int, optional
        Shot indices within each beam; default all.

    Yields
    ------
    Observation or ShotError
        One per shot; a ShotError carries the reason a shot could not be read.
    """
    if format != "auto" and format not in FORMATS:
        raise ValueError(f"unknown format {format!r}; choose auto or one of {list(FORMATS)}")
    with h5py.File(path, "r") as handle:
        name = detect_format(handle) if format == "auto" else format
        module = FORMATS[name]
        if format != "auto" and not module.detect(handle):
            raise ValueError(f"{path} does not have the {name} layout")
        for beam in module.beams(handle) if beams is None else beams:
            yield from module.iter_shots(handle, beam, shots=shots)
