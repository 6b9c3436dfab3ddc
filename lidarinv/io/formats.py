"""Waveform file formats: a registry with automatic detection, and shot streaming.

Every error of reading a file is a ``ValueError`` whose one line names the file: an empty
file, one that is not HDF5, a truncated one, or one whose layout lacks what its format
needs (not the HDF5 library's bare "file signature not found").
"""

import contextlib
import re
from dataclasses import dataclass
from pathlib import Path

import h5py

from . import gedi_l1b, lvis_l1b, waveforms
from .simulation import is_simulation

#: Format name → module with ``detect``, ``instrument``, ``beams``, ``count_shots`` and
#: ``iter_shots``.
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


@contextlib.contextmanager
def open_waveform_file(path):
    """An open ``h5py.File`` of ``path``; what cannot be read becomes a one-line
    ``ValueError`` naming the file, also while the file is being read."""
    path = Path(path)
    if not path.exists():
        raise ValueError(f"no such file: {path}")
    if path.is_dir():
        raise ValueError(f"{path} is a folder, not a waveform file")
    if path.stat().st_size == 0:
        raise ValueError(f"{path}: empty file (0 bytes), not an HDF5 waveform file")
    if not h5py.is_hdf5(path):
        raise ValueError(f"{path}: not an HDF5 file (no HDF5 signature; {_looks_like(path)})")
    try:
        handle = h5py.File(path, "r")
    except OSError as error:
        raise ValueError(f"{path}: cannot open this HDF5 file ({_hdf5_reason(error)})") from None
    try:
        with handle:
            yield handle
    except (OSError, KeyError) as error:
        raise ValueError(f"{path}: cannot read this file ({_hdf5_reason(error)})") from None
    except ValueError as error:
        if str(path) in str(error):
            raise
        raise ValueError(f"{path}: {error}") from None


def _looks_like(path) -> str:
    with open(path, "rb") as handle:
        head = handle.read(512)
    try:
        head.decode("utf-8")
    except UnicodeDecodeError:
        return "unknown binary content"
    return "it holds text"


def _hdf5_reason(error) -> str:
    """HDF5's message in plain words, on one line."""
    text = " ".join(str(error).split())
    sizes = re.search(r"truncated file: eof = (\d+).*stored_eof = (\d+)", text)
    if sizes:
        present, stored = sizes.groups()
        return f"truncated: {present} of its {stored} bytes present; is the copy complete?"
    return text.removeprefix("Unable to synchronously open file ").strip() or type(error).__name__


@dataclass(frozen=True)
class FileSummary:
    """What a waveform file is, known before any shot is read.

    Attributes
    ----------
    path : Path
    format : str
        Name in :data:`FORMATS`.
    instrument : str or None
        The preset the file's layout names (``None`` when it does not say): from the
        format (GEDI L1B, LVIS L1B) or ``/instrument`` (lidarinv files), never from the
        sample values.
    beams : list
        The beams to be read (``[None]`` for a format without beams).
    n_shots : int
        Shots in those beams.
    """

    path: Path
    format: str
    instrument: str | None
    beams: list
    n_shots: int

    @property
    def has_beams(self) -> bool:
        """Whether the format has beams (GEDI)."""
        return self.beams != [None]


def inspect_file(path, format="auto", beams=None) -> FileSummary:
    """Open ``path``, find its format, instrument, beams and shot count; every problem is
    a one-line ``ValueError`` naming the file (before any shot is read)."""
    name = _check_format_name(format)
    with open_waveform_file(path) as handle:
        name = _format_of(handle, path, format)
        module = FORMATS[name]
        chosen = module.beams(handle) if beams is None else list(beams)
        chosen = [_beam_name(module, handle, beam) for beam in chosen]
        count = sum(module.count_shots(handle, beam) for beam in chosen)
        return FileSummary(Path(path), name, module.instrument(handle), chosen, count)


def _beam_name(module, handle, beam):
    resolve = getattr(module, "resolve_beam", None)
    if beam is None or resolve is None:
        return beam
    return resolve(handle, beam)


def _check_format_name(format) -> str:
    if format != "auto" and format not in FORMATS:
        raise ValueError(f"unknown format {format!r}; choose auto or one of {list(FORMATS)}")
    return format


def _format_of(handle, path, format) -> str:
    name = detect_format(handle) if format == "auto" else format
    if format != "auto" and not FORMATS[name].detect(handle):
        raise ValueError(f"{path} does not have the {name} layout")
    return name


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
    _check_format_name(format)
    with open_waveform_file(path) as handle:
        module = FORMATS[_format_of(handle, path, format)]
        for beam in module.beams(handle) if beams is None else beams:
            yield from module.iter_shots(handle, beam, shots=shots)
