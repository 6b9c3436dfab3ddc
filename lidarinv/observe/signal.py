"""Signal start and end: where the smoothed waveform rises above the noise floors.

As in the GEDI L2A and LVIS processing (Hofton & Blair 2019, GEDI L2A ATBD), the waveform
is smoothed, the signal start is the highest bin above a *front* floor and the signal end
the lowest bin above a higher *back* floor: the trailing edge below the ground return
carries detector tails and slow baseline wander that a front-floor search would take for
signal. Both floors are in units of the σ of the smoothed noise, measured on the shot's
signal-free bins (:mod:`lidarinv.observe.noise`).
"""

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import gaussian_filter1d

#: Half-width of the smoothing kernel, in kernel σ, beyond which the window edge is
#: considered not to affect a smoothed sample.
EDGE_KERNEL_SIGMAS = 3.0


@dataclass(frozen=True)
class SignalExtent:
    """Where the return lies in the window.

    Attributes
    ----------
    start, end : float (m)
        Axis value of the signal start (top, first in time) and end (bottom).
    start_index, end_index : int
        Bins of the highest and lowest samples above the floors.
    touches_top, touches_bottom : bool
        The signal (above the front floor) reaches the edge of the window: the return may
        be truncated there.
    """

    start: float
    end: float
    start_index: int
    end_index: int
    touches_top: bool
    touches_bottom: bool


def smooth(samples, sigma_bins: float | None):
    """Gaussian smoothing with σ in bins (``None`` or 0: unchanged copy).

    The window is extended by reflection; samples within :func:`edge_bins` of an edge
    still feel that extension and are left out of detection by the callers.

    References
    ----------
    Hofton, M. & Blair, J. B. (2019). *Algorithm Theoretical Basis Document (ATBD) for GEDI
    Transmit and Receive Waveform Processing for L1 and L2 Products*, version 1.0. NASA
    Goddard Space Flight Center, Greenbelt, MD (the waveform smoothed by a Gaussian before
    its signal and modes are sought).
    """
    samples = np.asarray(samples, float)
    if not sigma_bins:
        return samples.copy()
    if sigma_bins < 0:
        raise ValueError(f"smoothing σ must be ≥ 0 bins, got {sigma_bins}")
    return gaussian_filter1d(samples, sigma_bins, mode="reflect")


def edge_bins(sigma_bins: float | None) -> int:
    """Number of bins at each window edge whose smoothed value depends on the padding."""
    return int(np.ceil(EDGE_KERNEL_SIGMAS * sigma_bins)) if sigma_bins else 0


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
    smoothed,
    axis,
    start_floor: float,
    end_floor: float | None = None,
    *,
    min_run: int = 3,
    edge: int = 0,
    edge_floor: float | None = None,
    censored=None,
) -> SignalExtent | None:
    """Signal start and end of a smoothed waveform, or ``None`` when nothing is above the
    front floor.

    Parameters
    ----------
    smoothed : array of float
        Smoothed waveform (digitiser units), ordered like ``axis``.
    axis : array of float (m)
        Ascending bin-centre heights or elevations.
    start_floor : float
        Front floor (digitiser units): the signal start is the highest bin of a run of at
        least ``min_run`` bins above it.
    end_floor : float, optional
        Back floor: the signal end is the lowest bin of a run above it; default
        ``start_floor``. When nothing reaches the back floor, the front floor is used.
    min_run : int
        Minimum number of consecutive bins above a floor to count as signal.
    edge : int
        Bins at each window edge left out of the search (see :func:`edge_bins`).
    edge_floor : float, optional
        Floor for those edge bins (higher than the front floor: the padding makes their
        smoothed noise up to √2 larger); a return above it there, or one whose run above
        the front floor reaches them, touches the edge. Default ``start_floor``.
    censored : array of bool, optional
        Samples set to a product's floor; they never count as signal.

    References
    ----------
    Hofton, M. & Blair, J. B. (2019). *Algorithm Theoretical Basis Document (ATBD) for GEDI
    Transmit and Receive Waveform Processing for L1 and L2 Products*, version 1.0. NASA
    Goddard Space Flight Center, Greenbelt, MD (signal start and end above front and back
    noise thresholds).
    Blair, J. B., Rabine, D. L. & Hofton, M. A. (1999). The Laser Vegetation Imaging Sensor:
    a medium-altitude, digitisation-only, airborne laser altimeter for mapping vegetation
    and topography. *ISPRS J. Photogramm. Remote Sens.* 54(2–3), 115–122.
    """
    values = np.asarray(smoothed, float).copy()
    axis = np.asarray(axis, float)
    if values.shape != axis.shape:
        raise ValueError(f"{values.size} samples but {axis.size} axis values")
    if censored is not None:
        values[np.asarray(censored, bool)] = -np.inf
    edge_floor = start_floor if edge_floor is None else edge_floor
    bottom_edge = bool(edge) and bool(np.any(values[: edge + 1] > edge_floor))
    top_edge = bool(edge) and bool(np.any(values[-edge - 1 :] > edge_floor))
    if edge:
        values[:edge] = values[-edge:] = -np.inf
    front = np.flatnonzero(above_floor_runs(values, start_floor, min_run))
    if front.size == 0:
        return None
    back = np.flatnonzero(
        above_floor_runs(values, start_floor if end_floor is None else end_floor, min_run)
    )
    high = int(front[-1])
    low = int(back[0]) if back.size else int(front[0])
    return SignalExtent(
        start=float(axis[high]),
        end=float(axis[low]),
        start_index=high,
        end_index=low,
        touches_top=top_edge or high >= values.size - 1 - edge,
        touches_bottom=bottom_edge or int(front[0]) <= edge,
    )
