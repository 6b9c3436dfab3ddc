"""Helpers shared by the waveform readers: shot selection and chunked iteration."""

import numpy as np

from lidarinv.observe.observation import Observation, ShotError

#: Shots read per h5py slice when streaming.
CHUNK = 512

#: Largest magnitude (digitiser units) a recorded sample can have: waveform digitisers
#: record at most 16 bits (GEDI and LVIS fewer), so a count beyond 2²⁴, 256 times a 16-bit
#: full scale, is no measurement (a fill value, a corrupt record) and its shot is refused
#: before any analysis or sampling.
ABSURD_SAMPLE = float(2**24)


def select_shots(n_shots: int, shots=None) -> np.ndarray:
    """Sorted shot indices from ``None`` (all), a slice, or a sequence of indices."""
    if shots is None:
        return np.arange(n_shots)
    if isinstance(shots, slice):
        return np.arange(n_shots)[shots]
    index = np.asarray(shots)
    if index.dtype == bool:
        if index.shape != (n_shots,):
            raise ValueError(f"a boolean shot mask needs {n_shots} entries")
        return np.flatnonzero(index)
    index = np.unique(index.astype(np.int64))
    if index.size and (index[0] < 0 or index[-1] >= n_shots):
        raise ValueError(f"shot indices must lie in [0, {n_shots}); got {index[0]}…{index[-1]}")
    return index


def chunks(index: np.ndarray, size: int | None = None):
    """Split sorted indices into chunks, each read with one contiguous h5py slice.

    A chunk holds at most ``size`` shots (default :data:`CHUNK`) and spans at most
    ``4·size`` rows, so a sparse selection never reads a large block.
    """
    size = size or CHUNK
    first = 0
    while first < index.size:
        stop = min(first + size, index.size)
        limit = index[first] + 4 * size
        stop = first + max(int(np.searchsorted(index[first:stop], limit)), 1)
        part = index[first:stop]
        yield part, int(part[0]), int(part[-1]) + 1
        first = stop


def read_rows(dataset, lo: int, hi: int, part: np.ndarray):
    """Rows ``part`` of ``dataset`` via one contiguous slice ``[lo:hi]``."""
    return dataset[lo:hi][part - lo]


def build(shot_id, metadata, **fields):
    """An :class:`Observation`, or a :class:`ShotError` giving why it could not be built
    (NaN or absurd samples, beyond :data:`ABSURD_SAMPLE`, among others).

    A descending axis (mission files are in time order, top first) is reversed together
    with the samples and the censored mask.
    """
    try:
        axis = np.asarray(fields["axis"], float)
        if axis.size > 1 and axis[0] > axis[-1]:
            fields["axis"] = axis[::-1]
            fields["samples"] = np.asarray(fields["samples"])[::-1]
            if fields.get("censored") is not None:
                fields["censored"] = np.asarray(fields["censored"])[::-1]
        observation = Observation(shot_id=shot_id, metadata=metadata, **fields)
        absurd = np.abs(observation.samples) >= ABSURD_SAMPLE
        if absurd.any():
            largest = observation.samples[absurd][np.argmax(np.abs(observation.samples[absurd]))]
            return ShotError(
                shot_id,
                f"{int(absurd.sum())} absurd sample(s) (up to {largest:.3g}; a digitiser "
                f"records less than {ABSURD_SAMPLE:.3g}): a fill value or a corrupt record",
                metadata,
            )
        return observation
    except ValueError as error:
        return ShotError(shot_id, str(error), metadata)


def scalar(value):
    """A numpy scalar as a plain Python value; bytes decoded."""
    if isinstance(value, bytes):
        return value.decode()
    return value.item() if isinstance(value, np.generic) else value
