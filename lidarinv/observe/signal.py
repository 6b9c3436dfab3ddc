"""Signal start and end: where the (optionally smoothed) waveform rises above the floor."""

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import gaussian_filter1d


@dataclass(frozen=True)
class SignalExtent:
    """Where the return lies in the window.

    Attributes
    ----------
    start, end : float (m)
        Axis value of the signal start (top, first in time) and end (bottom).
    start_index, end_index : int
        Bins of the highest and lowest samples above the floor.
    touches_top, touches_bottom : bool
        The signal reaches the edge of the window: the return may be truncated there.
    """

    start: float
    end: float
    start_index: int
    end_index: int
    touches_top: bool
    touches_bottom: bool


def smooth(samples, sigma_bins: float | None):
    """Gaussian smoothing with σ in bins (``None`` or 0: unchanged copy)."""
    samples = np.asarray(samples, float)
    if not sigma_bins:
        return samples.copy()
    if sigma_bins < 0:
        raise ValueError(f"smoothing σ must be ≥ 0 bins, got {sigma_bins}")
    return gaussian_filter1d(samples, sigma_bins, mode="nearest")


def smoothed_noise_factor(sigma_bins: float | None) -> float:
    """Factor by which Gaussian smoothing reduces the σ of white noise: √Σk²."""
    if not sigma_bins:
        return 1.0
    radius = int(np.ceil(4 * sigma_bins))
    impulse = np.zeros(2 * radius + 1)
    impulse[radius] = 1.0
    kernel = gaussian_filter1d(impulse, sigma_bins, mode="constant")
    return float(np.sqrt(np.sum(kernel**2)))


def above_floor_runs(values, floor: float, min_run: int) -> np.ndarray:
    """Mask of samples in runs of at least ``min_run`` consecutive samples above ``floor``."""
    above = np.asarray(values) > floor
    if min_run <= 1:
        return above
    padded = np.concatenate([[False], above, [False]])
    edges = np.flatnonzero(np.diff(padded.astype(np.int8)))
    mask = np.zeros(above.shape, bool)
    for first, stop in zip(edges[::2], edges[1::2]):
        if stop - first >= min_run:
            mask[first:stop] = True
    return mask


def signal_extent(
    samples,
    axis,
    noise_mean: float,
    noise_sigma: float,
    *,
    n_sigma: float = 4.0,
    smooth_bins: float | None = None,
    min_run: int = 3,
    censored=None,
) -> SignalExtent | None:
    """Signal start and end of a waveform, or ``None`` when nothing rises above the floor.

    Parameters
    ----------
    samples : array of float
        Waveform (digitiser units), ordered like ``axis``.
    axis : array of float (m)
        Ascending bin-centre heights or elevations.
    noise_mean, noise_sigma : float
        Noise of the raw samples (digitiser units).
    n_sigma : float
        The floor is ``noise_mean + n_sigma·σ_s``, where σ_s is the noise σ after the
        smoothing (σ times :func:`smoothed_noise_factor`).
    smooth_bins : float, optional
        Gaussian smoothing σ in bins before thresholding.
    min_run : int
        Minimum number of consecutive bins above the floor to count as signal.
    censored : array of bool, optional
        Samples set to a product's floor; they never count as signal (smoothing would
        otherwise lift a run of floor values above a lower detection floor).
    """
    samples = np.asarray(samples, float)
    axis = np.asarray(axis, float)
    floor = noise_mean + n_sigma * noise_sigma * smoothed_noise_factor(smooth_bins)
    above = smooth(samples, smooth_bins)
    if censored is not None:
        above = np.where(np.asarray(censored, bool), -np.inf, above)
    mask = above_floor_runs(above, floor, min_run)
    hits = np.flatnonzero(mask)
    if hits.size == 0:
        return None
    low, high = int(hits[0]), int(hits[-1])
    return SignalExtent(
        start=float(axis[high]),
        end=float(axis[low]),
        start_index=high,
        end_index=low,
        touches_top=high == samples.size - 1,
        touches_bottom=low == 0,
    )
