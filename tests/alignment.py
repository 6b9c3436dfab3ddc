"""Registration of waveforms on their ground peaks and averaging (Sun & Ranson Fig. 7)."""

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class AlignedAverage:
    """Waveforms on a common height-above-ground grid.

    Attributes
    ----------
    height : array (m)
        Grid of heights above each waveform's ground peak.
    stack : array [n_waveforms, n_heights]
        Each waveform on the grid (NaN outside its window).
    mean : array
        Mean over the waveforms covering each height.
    count : array of int
        Number of waveforms covering each height.
    """

    height: np.ndarray
    stack: np.ndarray
    mean: np.ndarray
    count: np.ndarray


def align_and_average(
    waveforms,
    axes,
    grounds,
    *,
    noise_means=None,
    bin_size: float | None = None,
    normalise: bool = True,
) -> AlignedAverage:
    """Register waveforms on their ground peaks and average them.

    Each waveform, minus its noise mean, is linearly interpolated onto a grid of heights
    above its ground peak (a multiple of ``bin_size`` with 0 on the grid, so a waveform
    whose ground sits on a bin centre is not resampled). With ``normalise`` each is first
    divided by its maximum, as in the paper.

    Parameters
    ----------
    waveforms : sequence of arrays
        Samples (digitiser units), each ascending with its axis.
    axes : sequence of arrays (m)
        Ascending bin-centre heights or elevations.
    grounds : sequence of float (m)
        Ground-peak position of each waveform in its axis units.
    noise_means : sequence of float, optional
        Subtracted before averaging (default 0).
    bin_size : float (m), optional
        Grid step; default the first waveform's bin size.
    normalise : bool
        Divide each waveform by its maximum.
    """
    waveforms = [np.asarray(w, float) for w in waveforms]
    axes = [np.asarray(a, float) for a in axes]
    grounds = np.asarray(grounds, float)
    if not waveforms:
        raise ValueError("align_and_average: no waveforms")
    if len(axes) != len(waveforms) or grounds.size != len(waveforms):
        raise ValueError("align_and_average: waveforms, axes and grounds differ in number")
    if not np.all(np.isfinite(grounds)):
        raise ValueError("align_and_average: every waveform needs a finite ground position")
    means = np.zeros(len(waveforms)) if noise_means is None else np.asarray(noise_means, float)
    for w, a in zip(waveforms, axes):
        if w.shape != a.shape or w.size < 2:
            raise ValueError("align_and_average: each waveform needs an axis of equal length")
    step = float(bin_size or (axes[0][-1] - axes[0][0]) / (axes[0].size - 1))
    low = min(a[0] - g for a, g in zip(axes, grounds))
    high = max(a[-1] - g for a, g in zip(axes, grounds))
    height = np.arange(np.floor(low / step), np.ceil(high / step) + 1) * step
    stack = np.full((len(waveforms), height.size), np.nan)
    for i, (w, a, g, m) in enumerate(zip(waveforms, axes, grounds, means)):
        values = w - m
        if normalise:
            peak = values.max()
            if peak <= 0:
                raise ValueError(f"align_and_average: waveform {i} has no positive signal")
            values = values / peak
        stack[i] = np.interp(height, a - g, values, left=np.nan, right=np.nan)
    count = np.sum(np.isfinite(stack), axis=0)
    with np.errstate(invalid="ignore"):
        mean = np.where(count > 0, np.nansum(stack, axis=0) / np.maximum(count, 1), np.nan)
    return AlignedAverage(height=height, stack=stack, mean=mean, count=count)
