"""Reader for LVIS L1B waveforms (HDF5).

Layout used: root datasets ``RXWAVE`` and ``TXWAVE`` [shots × bins] in time order,
``Z0`` (elevation of the first bin) and ``Z{N-1}`` (the last; N is 1024, 1216, 528 … by
release), ``LFID``, ``SHOTNUMBER``, ``LON0``, ``LAT0``, ``LON{N-1}``, ``LAT{N-1}`` and
``SIGMEAN`` (the noise mean computed in flight). The elevation axis is linear from ``Z0``
to ``Z{N-1}``. Shot numbers and LFIDs are integers even where the file stores them as
floats; shots carry the instrument name ``"lvis"`` and their ``TXWAVE`` as the pulse.
"""

import re

import numpy as np

from forward.constants import SPEED_OF_LIGHT_M_PER_NS

from ._common import build, chunks, read_rows, scalar, select_shots

NAME = "lvis-l1b"
INSTRUMENT = "lvis"
_Z = re.compile(r"Z(\d+)")


def detect(handle) -> bool:
    return "RXWAVE" in handle and "Z0" in handle


def instrument(handle) -> str:
    """LVIS L1B files hold LVIS shots."""
    return INSTRUMENT


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


def integer_id(value):
    """A shot number or LFID as an int (files may store them as floats)."""
    value = scalar(value)
    if isinstance(value, float) and np.isfinite(value) and value == int(value):
        return int(value)
    return value


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
        last = z_last.removeprefix("Z")
        position = {
            f"{name}_{end}": _column(handle, f"{key}{index}", lo, hi, part)
            for name, key in (("latitude", "LAT"), ("longitude", "LON"))
            for end, index in (("top", "0"), ("bottom", last))
        }
        noise_mean = _column(handle, "SIGMEAN", lo, hi, part)
        for i in range(part.size):
            step = abs(float(top[i]) - float(bottom[i])) / (n_bins - 1)
            metadata = {
                "index": int(part[i]),
                "lfid": integer_id(lfid[i]),
                "latitude": float(position["latitude_top"][i]),
                "longitude": float(position["longitude_top"][i]),
                **{key: float(values[i]) for key, values in position.items()},
            }
            yield build(
                integer_id(shot_number[i]),
                metadata,
                samples=waves[i],
                axis=np.linspace(float(top[i]), float(bottom[i]), n_bins),
                axis_kind="elevation",
                pulse=None if pulses is None else pulses[i],
                pulse_ns=2 * step / SPEED_OF_LIGHT_M_PER_NS,
                noise_mean=float(noise_mean[i]),
                instrument=INSTRUMENT,
            )
