"""Reader for LVIS L1B waveforms (HDF5).

Layout used: root datasets ``RXWAVE`` and ``TXWAVE`` [shots × bins] in time order,
``Z0`` (elevation of the first bin) and ``Z{N-1}`` (the last; N is 1024, 1216, 528 … by
release), ``LFID``, ``SHOTNUMBER``, ``LON0`` and ``LAT0``. The elevation axis is linear
from ``Z0`` to ``Z{N-1}``.
"""

import re

import numpy as np

from forward.constants import SPEED_OF_LIGHT_M_PER_NS

from ._common import build, chunks, read_rows, scalar, select_shots

NAME = "lvis-l1b"
_Z = re.compile(r"Z(\d+)")


def detect(handle) -> bool:
    return "RXWAVE" in handle and "Z0" in handle


def beams(handle) -> list:
    """LVIS files have a single beam, named ``None``."""
    return [None]


def last_bin_name(handle) -> str:
    """Name of the last-bin elevation dataset, checked against the RXWAVE width."""
    if "RXWAVE" not in handle or handle["RXWAVE"].ndim != 2:
        raise ValueError("LVIS file lacks a 2-D RXWAVE dataset")
    n_bins = handle["RXWAVE"].shape[1]
    indices = sorted(int(m.group(1)) for k in handle if (m := _Z.fullmatch(k)))
    last = [i for i in indices if i > 0]
    if not last:
        raise ValueError("LVIS file has Z0 but no last-bin elevation Z{N-1}")
    if last[-1] != n_bins - 1:
        raise ValueError(
            f"LVIS file has Z{last[-1]} but RXWAVE has {n_bins} bins (expected Z{n_bins - 1})"
        )
    return f"Z{last[-1]}"


def count_shots(handle, beam=None) -> int:
    return int(handle["RXWAVE"].shape[0])


def _column(handle, name, lo, hi, part):
    if name in handle:
        return read_rows(handle[name], lo, hi, part)
    return np.full(part.size, np.nan)


def iter_shots(handle, beam=None, shots=None):
    """Observations (elevation axis, ascending), streamed in chunks of shots."""
    if beam is not None:
        raise ValueError("LVIS files have no beams; leave --beam out")
    z_last = last_bin_name(handle)
    rx = handle["RXWAVE"]
    n_shots, n_bins = rx.shape
    for part, lo, hi in chunks(select_shots(n_shots, shots)):
        waves = read_rows(rx, lo, hi, part)
        pulses = read_rows(handle["TXWAVE"], lo, hi, part) if "TXWAVE" in handle else None
        top = read_rows(handle["Z0"], lo, hi, part)
        bottom = read_rows(handle[z_last], lo, hi, part)
        shot_number = _column(handle, "SHOTNUMBER", lo, hi, part)
        lfid = _column(handle, "LFID", lo, hi, part)
        lon, lat = _column(handle, "LON0", lo, hi, part), _column(handle, "LAT0", lo, hi, part)
        for i in range(part.size):
            step = abs(float(top[i]) - float(bottom[i])) / (n_bins - 1)
            metadata = {
                "index": int(part[i]),
                "lfid": scalar(lfid[i]),
                "latitude": float(lat[i]),
                "longitude": float(lon[i]),
            }
            yield build(
                scalar(shot_number[i]),
                metadata,
                samples=waves[i],
                axis=np.linspace(float(top[i]), float(bottom[i]), n_bins),
                axis_kind="elevation",
                pulse=None if pulses is None else pulses[i],
                pulse_ns=2 * step / SPEED_OF_LIGHT_M_PER_NS,
            )
