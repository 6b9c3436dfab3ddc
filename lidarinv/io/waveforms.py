"""The lidarinv HDF5 layout for observed waveforms (write, read, stream).

Layout (format version 1)::

    /                        attrs: content = "lidarinv observed waveforms",
                                    layout_version = 1, lidarinv_version
    /instrument              attrs: the instrument description; ``instrument`` names the
                             preset that recorded the shots (optional)
    /waveforms               attrs: axis_kind ("height" | "elevation"), n_shots
        samples       [n, B]  float64  digitiser units, lowest bin first, NaN padding
        sample_count  [n]     int32    bins used in each row
        axis_bin0     [n]     float64  m, axis value of the centre of bin 0 (lowest)
        bin_size      [n]     float64  m, axis step (> 0)
        shot_id       [n]     int64 or UTF-8 string
        noise_mean, noise_sigma, floor, saturation  [n] float64 (NaN: none/unknown)
        censored      [n, B]  uint8    1 where a sample was set to the floor (optional)
        pulse         [n, P]  float64  transmit pulse in time order (optional), with
        pulse_count   [n]     int32    and pulse_ns [n] float64 (ns)
        metadata/<key>   [n]  per-shot metadata (numbers or strings)
        truth/<key>      [n] or [n, B]  known truth of simulated shots (optional)
    /stand                   the stand / stem map (forward.stand_io layout, optional)
"""

import h5py
import numpy as np

from forward.stand_io import read_stand, write_stand
from lidarinv.observe.observation import Observation

from ._common import build, chunks, read_rows, scalar, select_shots

NAME = "lidarinv"
CONTENT = "lidarinv observed waveforms"
LAYOUT_VERSION = 1
_SCALARS = ("noise_mean", "noise_sigma", "floor", "saturation")


def _padded(rows, width, fill, dtype=float):
    out = np.full((len(rows), width), fill, dtype=dtype)
    for i, row in enumerate(rows):
        if row is not None:
            out[i, : len(row)] = row
    return out


def _column(values):
    values = [scalar(v) for v in values]
    if all(isinstance(v, str) for v in values):
        return np.asarray(values, dtype=object), h5py.string_dtype()
    if all(isinstance(v, (int, np.integer)) and not isinstance(v, bool) for v in values):
        return np.asarray(values, dtype=np.int64), None  # 64-bit shot numbers stay exact
    try:
        return np.asarray(values, dtype=float), None
    except (TypeError, ValueError):
        return np.asarray([str(v) for v in values], dtype=object), h5py.string_dtype()


def write_observations(path, observations, *, stand=None, instrument=None, attrs=None):
    """Write observations (and optionally their stand and instrument) to a new HDF5 file.

    Parameters
    ----------
    path : str or Path
        File to create (overwritten).
    observations : sequence of Observation
        All on the same ``axis_kind``; windows may differ in length.
    stand : forward.Stand, optional
        Stored under ``/stand`` (the stem map of simulated shots).
    instrument : forward.Instrument or dict, optional
        Stored as attributes of ``/instrument``. Default: the instrument named by the
        observations (they must agree).
    attrs : dict, optional
        Extra root attributes.
    """
    observations = list(observations)
    if not observations:
        raise ValueError("no observations to write")
    kinds = {o.axis_kind for o in observations}
    if len(kinds) > 1:
        raise ValueError(f"observations mix axis kinds {sorted(kinds)}; write them separately")
    names = {o.instrument for o in observations}
    if len(names) > 1:
        raise ValueError(f"observations mix instruments {sorted(map(str, names))}")
    if instrument is None and names != {None}:
        instrument = {"instrument": names.pop()}
    from lidarinv import __version__

    n = len(observations)
    width = max(o.n_bins for o in observations)
    with h5py.File(path, "w") as handle:
        handle.attrs.update({"content": CONTENT, "layout_version": LAYOUT_VERSION})
        handle.attrs["lidarinv_version"] = __version__
        for key, value in (attrs or {}).items():
            handle.attrs[key] = value
        if instrument is not None:
            description = instrument if isinstance(instrument, dict) else instrument.describe()
            handle.create_group("instrument").attrs.update(description)
        group = handle.create_group("waveforms")
        group.attrs["axis_kind"] = kinds.pop()
        group.attrs["n_shots"] = n
        group.create_dataset(
            "samples", data=_padded([o.samples for o in observations], width, np.nan), chunks=True
        )
        group.create_dataset(
            "sample_count", data=np.array([o.n_bins for o in observations], np.int32)
        )
        group.create_dataset("axis_bin0", data=[o.axis[0] for o in observations]).attrs["units"] = (
            "m"
        )
        group.create_dataset("bin_size", data=[o.bin_size for o in observations]).attrs["units"] = (
            "m"
        )
        ids, dtype = _column([o.shot_id for o in observations])
        group.create_dataset("shot_id", data=ids, dtype=dtype)
        for name in _SCALARS:
            group.create_dataset(name, data=[float(getattr(o, name)) for o in observations])
        if any(o.censored is not None for o in observations):
            rows = [o.censored_mask.astype(np.uint8) for o in observations]
            group.create_dataset("censored", data=_padded(rows, width, 0, np.uint8))
        if any(o.pulse is not None for o in observations):
            pulses = [o.pulse for o in observations]
            size = max(len(p) for p in pulses if p is not None)
            group.create_dataset("pulse", data=_padded(pulses, size, np.nan))
            counts = [0 if p is None else len(p) for p in pulses]
            group.create_dataset("pulse_count", data=np.array(counts, np.int32))
            group.create_dataset("pulse_ns", data=[float(o.pulse_ns) for o in observations])
        _write_dicts(group, "metadata", [o.metadata for o in observations], width)
        _write_dicts(group, "truth", [o.truth for o in observations], width)
        if stand is not None:
            write_stand(handle.create_group("stand"), stand)


def _write_dicts(group, name, dicts, width):
    keys = sorted({k for d in dicts for k in d})
    if not keys:
        return
    sub = group.create_group(name)
    for key in keys:
        values = [d.get(key) for d in dicts]
        if any(np.ndim(v) == 1 for v in values):  # per-bin arrays, e.g. the noise-free signal
            sub.create_dataset(key, data=_padded(values, width, np.nan))
            continue
        values = [np.nan if v is None else v for v in values]
        data, dtype = _column(values)
        sub.create_dataset(key, data=data, dtype=dtype)


def detect(handle) -> bool:
    return handle.attrs.get("content") == CONTENT and "waveforms" in handle


def beams(handle) -> list:
    return [None]


def instrument(handle) -> str | None:
    """The preset named by ``/instrument`` (None when the file names none)."""
    if "instrument" in handle and "instrument" in handle["instrument"].attrs:
        return str(scalar(handle["instrument"].attrs["instrument"]))
    return None


def count_shots(handle, beam=None) -> int:
    return int(handle["waveforms/sample_count"].shape[0])


def _rows(sub, lo, hi, part):
    if sub is None:
        return {}
    return {key: read_rows(sub[key], lo, hi, part) for key in sub}


def iter_shots(handle, beam=None, shots=None):
    """Observations from a lidarinv waveform file, streamed in chunks of shots."""
    if beam is not None:
        raise ValueError("lidarinv waveform files have no beams; leave --beam out")
    if handle.attrs.get("layout_version", 0) > LAYOUT_VERSION:
        raise ValueError("this file was written by a newer lidarinv layout version")
    group = handle["waveforms"]
    kind = str(scalar(group.attrs["axis_kind"]))
    recorded_by = instrument(handle)
    n = group["sample_count"].shape[0]
    for part, lo, hi in chunks(select_shots(n, shots)):
        get = {
            k: read_rows(group[k], lo, hi, part)
            for k in group
            if isinstance(group[k], h5py.Dataset)
        }
        meta = _rows(group.get("metadata"), lo, hi, part)
        truth = _rows(group.get("truth"), lo, hi, part)
        for i in range(part.size):
            size = int(get["sample_count"][i])
            pulse = None
            if "pulse" in get and get["pulse_count"][i] > 0:
                pulse = get["pulse"][i, : get["pulse_count"][i]]
            censored = get["censored"][i, :size].astype(bool) if "censored" in get else None
            truths = {k: (v[i, :size] if v.ndim == 2 else scalar(v[i])) for k, v in truth.items()}
            yield build(
                scalar(get["shot_id"][i]),
                {k: scalar(v[i]) for k, v in meta.items()},
                samples=get["samples"][i, :size],
                axis=get["axis_bin0"][i] + get["bin_size"][i] * np.arange(size),
                axis_kind=kind,
                censored=censored,
                pulse=pulse,
                pulse_ns=float(get["pulse_ns"][i]) if "pulse_ns" in get else np.nan,
                truth=truths,
                instrument=recorded_by,
                **{k: float(get[k][i]) for k in _SCALARS},
            )


def read_observations(path, shots=None) -> list:
    """All (or the selected) shots of a lidarinv waveform file as a list.

    Raises ValueError naming the first shot that cannot be read.
    """
    with h5py.File(path, "r") as handle:
        if not detect(handle):
            raise ValueError(f"{path} is not a lidarinv waveform file")
        out = list(iter_shots(handle, shots=shots))
    bad = [o for o in out if not isinstance(o, Observation)]
    if bad:
        raise ValueError(f"shot {bad[0].shot_id}: {bad[0].reason}")
    return out


def read_stand_from(path):
    """The stand stored with a waveform file, or ``None``."""
    with h5py.File(path, "r") as handle:
        return read_stand(handle["stand"]) if "stand" in handle else None
