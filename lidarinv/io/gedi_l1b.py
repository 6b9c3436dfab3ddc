"""Reader for GEDI L1B geolocated waveforms (HDF5).

Layout used: groups ``BEAMxxxx``, each holding ``rxwaveform`` (all shots' samples
concatenated, in time order) sliced by ``rx_sample_start_index`` (1-based) and
``rx_sample_count``; ``txwaveform`` with ``tx_sample_start_index``/``tx_sample_count``;
``shot_number``, ``noise_mean_corrected``, ``noise_stddev_corrected``,
``stale_return_flag``; and ``geolocation/elevation_bin0``, ``elevation_lastbin``,
``latitude_bin0``, ``longitude_bin0``, ``latitude_lastbin``, ``longitude_lastbin``. The
elevation axis runs linearly from bin 0 to the last bin. Shots carry the instrument name
``"gedi"`` and their ``txwaveform`` as the pulse.
"""

import re

import numpy as np

from ._common import build, chunks, read_rows, select_shots

NAME = "gedi-l1b"
INSTRUMENT = "gedi"
BIN_NS = 1.0
_BEAM = re.compile(r"BEAM\d{4}")
_REQUIRED = (
    "rxwaveform",
    "rx_sample_start_index",
    "rx_sample_count",
    "shot_number",
    "geolocation/elevation_bin0",
    "geolocation/elevation_lastbin",
)


def detect(handle) -> bool:
    """True for a file with at least one ``BEAMxxxx/rxwaveform``."""
    return any(_BEAM.fullmatch(k) and "rxwaveform" in handle[k] for k in handle)


def instrument(handle) -> str:
    """GEDI L1B files hold GEDI shots."""
    return INSTRUMENT


def beams(handle) -> list:
    """Beam group names, sorted."""
    return sorted(k for k in handle if _BEAM.fullmatch(k))


def resolve_beam(handle, beam) -> str:
    """Beam name from ``BEAM0101``, ``0101`` or ``101``."""
    names = beams(handle)
    text = str(beam).upper()
    candidates = [text, f"BEAM{text.removeprefix('BEAM').zfill(4)}"]
    for name in candidates:
        if name in names:
            return name
    raise ValueError(f"no beam {beam!r} in this GEDI file; beams are {names}")


def count_shots(handle, beam) -> int:
    return int(handle[resolve_beam(handle, beam)]["shot_number"].shape[0])


def _optional(group, name, lo, hi, part, fill=np.nan):
    if name in group:
        return read_rows(group[name], lo, hi, part)
    return np.full(part.size, fill)


def iter_shots(handle, beam, shots=None):
    """Observations of one beam, streamed in chunks.

    Yields :class:`~lidarinv.observe.Observation` (elevation axis, ascending) or
    :class:`~lidarinv.observe.ShotError` for a shot whose window cannot be read.
    """
    name = resolve_beam(handle, beam)
    group = handle[name]
    missing = [k for k in _REQUIRED if k not in group]
    if missing:
        raise ValueError(f"GEDI beam {name} lacks dataset(s) {missing}")
    n = group["shot_number"].shape[0]
    rx = group["rxwaveform"]
    has_tx = all(k in group for k in ("txwaveform", "tx_sample_start_index", "tx_sample_count"))
    for part, lo, hi in chunks(select_shots(n, shots)):
        shot_number = read_rows(group["shot_number"], lo, hi, part)
        start = read_rows(group["rx_sample_start_index"], lo, hi, part).astype(np.int64) - 1
        count = read_rows(group["rx_sample_count"], lo, hi, part).astype(np.int64)
        top = read_rows(group["geolocation/elevation_bin0"], lo, hi, part)
        bottom = read_rows(group["geolocation/elevation_lastbin"], lo, hi, part)
        position = {
            f"{name}_{end}": _optional(group, f"geolocation/{name}_{field}", lo, hi, part)
            for name in ("latitude", "longitude")
            for end, field in (("top", "bin0"), ("bottom", "lastbin"))
        }
        stale = _optional(group, "stale_return_flag", lo, hi, part, fill=0)
        noise_mean = _optional(group, "noise_mean_corrected", lo, hi, part)
        noise_sd = _optional(group, "noise_stddev_corrected", lo, hi, part)
        block_lo = max(int(start.min()), 0)
        block_hi = min(int((start + count).max()), rx.shape[0])
        block = rx[block_lo:block_hi] if block_hi > block_lo else np.empty(0)
        if has_tx:
            tx_start = read_rows(group["tx_sample_start_index"], lo, hi, part).astype(int) - 1
            tx_count = read_rows(group["tx_sample_count"], lo, hi, part).astype(int)
        for i in range(part.size):
            metadata = {
                "beam": name,
                "index": int(part[i]),
                "latitude": float(position["latitude_top"][i]),
                "longitude": float(position["longitude_top"][i]),
                **{key: float(values[i]) for key, values in position.items()},
                "stale_return": bool(stale[i]),
            }
            shot_id = int(shot_number[i])
            first, size = int(start[i]), int(count[i])
            if first < 0 or size < 0 or first + size > rx.shape[0]:
                yield _error(shot_id, metadata, first, size, rx.shape[0])
                continue
            samples = block[first - block_lo : first - block_lo + size]
            pulse = None
            if has_tx:
                a, m = int(tx_start[i]), int(tx_count[i])
                if a >= 0 and m >= 2 and a + m <= group["txwaveform"].shape[0]:
                    pulse = group["txwaveform"][a : a + m]
            yield build(
                shot_id,
                metadata,
                samples=samples,
                axis=np.linspace(float(top[i]), float(bottom[i]), size),
                axis_kind="elevation",
                noise_mean=float(noise_mean[i]),
                noise_sigma=float(noise_sd[i]),
                pulse=pulse,
                pulse_ns=BIN_NS,
                instrument=INSTRUMENT,
            )


def _error(shot_id, metadata, first, size, total):
    from lidarinv.observe.observation import ShotError

    return ShotError(
        shot_id,
        f"truncated rxwaveform: samples {first + 1}…{first + size} (1-based) requested, "
        f"{total} stored",
        metadata,
    )
