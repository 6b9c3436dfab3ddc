"""Ground-peak detection: the lowest significant mode of the smoothed waveform.

The modes of a waveform are the local maxima of its smoothed form (the zero crossings of
the smoothed first derivative, as in the GEDI L2A and LVIS L2 processing). A mode counts
when it reaches the back floor and stands out from the trough that separates it from its
higher neighbour by a few σ of the smoothed noise. The lowest such mode within the
signal extent is the ground; a single peak with no canopy above it is therefore ground.
Its centre is the vertex of the parabola through the three smoothed samples at the
maximum, and its 1-σ uncertainty follows from the measured σ of the smoothed noise's
slope: a slope error ε moves the vertex by ε / |curvature|.
"""

from dataclasses import dataclass

import numpy as np
from scipy.signal import find_peaks


@dataclass(frozen=True)
class Mode:
    """A local maximum of the smoothed waveform.

    Attributes
    ----------
    index : int
        Bin of the maximum.
    amplitude : float
        Smoothed value above the noise mean (digitiser units).
    prominence : float
        Height above the higher of the troughs that separate it from higher modes
        (digitiser units).
    """

    index: int
    amplitude: float
    prominence: float


@dataclass(frozen=True)
class GroundPeak:
    """The ground return of one waveform.

    Attributes
    ----------
    position : float (m)
        Axis value of the mode's centre (height or elevation), sub-bin.
    index : float
        Fractional bin index of ``position``.
    uncertainty : float (m)
        1-σ uncertainty of ``position`` from the noise (usable as a prior width).
    amplitude : float
        Smoothed amplitude above the noise mean (digitiser units).
    width : float (m)
        Half width at half maximum of the mode's lower flank, as a Gaussian σ.
    n_modes : int
        Number of significant modes in the signal extent (1: a lone peak).
    """

    position: float
    index: float
    uncertainty: float
    amplitude: float
    width: float
    n_modes: int


def find_modes(smoothed, noise_mean: float, *, floor: float, prominence: float, within=None):
    """Significant modes of a smoothed waveform, lowest bin first.

    Parameters
    ----------
    smoothed : array of float
        Smoothed waveform (digitiser units), lowest bin first.
    noise_mean : float
        Noise mean (digitiser units).
    floor : float
        Smallest smoothed value (digitiser units) a mode may have.
    prominence : float
        Smallest prominence (digitiser units).
    within : (int, int), optional
        First and last bin a mode may lie at (e.g. the signal extent's).

    References
    ----------
    Hofton, M. & Blair, J. B. (2019). *Algorithm Theoretical Basis Document (ATBD) for GEDI
    Transmit and Receive Waveform Processing for L1 and L2 Products*, version 1.0. NASA
    Goddard Space Flight Center, Greenbelt, MD (modes as zero crossings of the smoothed
    waveform's first derivative).
    Hofton, M. A., Minster, J. B. & Blair, J. B. (2000). Decomposition of laser altimeter
    waveforms. *IEEE Trans. Geosci. Remote Sens.* 38(4), 1989–1996 (components of a smoothed
    waveform).
    """
    values = np.asarray(smoothed, float)
    peaks, props = find_peaks(values, height=floor, prominence=prominence)
    if within is not None:
        keep = (peaks >= within[0]) & (peaks <= within[1])
        peaks, prominences = peaks[keep], props["prominences"][keep]
    else:
        prominences = props["prominences"]
    return [
        Mode(int(p), float(values[p] - noise_mean), float(q)) for p, q in zip(peaks, prominences)
    ]


def peak_vertex(values, index: int):
    """Fractional index of the parabola vertex through ``values[index-1:index+2]`` and the
    curvature there (per bin²); the vertex is clamped to ±½ bin of ``index``."""
    if not 0 < index < len(values) - 1:
        return float(index), np.nan
    a, b, c = values[index - 1 : index + 2]
    curvature = float(a - 2.0 * b + c)
    offset = 0.5 * (a - c) / curvature if curvature < 0 else 0.0
    return index + float(np.clip(offset, -0.5, 0.5)), curvature


def find_ground(
    smoothed,
    axis,
    noise,
    *,
    floor: float,
    prominence_sigmas: float = 3.0,
    within=None,
) -> GroundPeak | None:
    """Locate the ground: the lowest significant mode of the smoothed waveform.

    Parameters
    ----------
    smoothed : array of float
        Smoothed waveform (digitiser units) on the ascending ``axis`` (m).
    axis : array of float (m)
        Ascending bin-centre heights or elevations.
    noise : NoiseModel
        The shot's noise, with ``smoothed_sigma`` and ``slope_sigma`` measured at the
        smoothing of ``smoothed``.
    floor : float
        Smallest smoothed value (digitiser units) the ground mode may have (the back
        floor of the signal extent).
    prominence_sigmas : float
        Smallest prominence, in σ of the smoothed noise.
    within : (int, int), optional
        First and last bin the ground may lie at (the signal extent's).

    Returns
    -------
    GroundPeak or None
        ``None`` when no mode qualifies.

    References
    ----------
    Hofton, M. & Blair, J. B. (2019). *Algorithm Theoretical Basis Document (ATBD) for GEDI
    Transmit and Receive Waveform Processing for L1 and L2 Products*, version 1.0. NASA
    Goddard Space Flight Center, Greenbelt, MD (the ground as the lowest mode).
    Hofton, M. A., Minster, J. B. & Blair, J. B. (2000). Decomposition of laser altimeter
    waveforms. *IEEE Trans. Geosci. Remote Sens.* 38(4), 1989–1996 (the ground as the lowest
    component of a decomposition).
    Blair, J. B., Rabine, D. L. & Hofton, M. A. (1999). The Laser Vegetation Imaging Sensor:
    a medium-altitude, digitisation-only, airborne laser altimeter for mapping vegetation
    and topography. *ISPRS J. Photogramm. Remote Sens.* 54(2–3), 115–122.
    """
    values = np.asarray(smoothed, float)
    axis = np.asarray(axis, float)
    modes = find_modes(
        values,
        noise.mean,
        floor=floor,
        prominence=prominence_sigmas * noise.smoothed_sigma,
        within=within,
    )
    if not modes:
        return None
    lowest = modes[0]
    step = float(axis[1] - axis[0])
    index, curvature = peak_vertex(values, lowest.index)
    if np.isfinite(curvature) and curvature < 0 and np.isfinite(noise.slope_sigma):
        uncertainty = noise.slope_sigma / -curvature * step
    else:
        uncertainty = step / np.sqrt(12.0)
    return GroundPeak(
        position=float(axis[0] + index * step),
        index=index,
        uncertainty=float(uncertainty),
        amplitude=lowest.amplitude,
        width=lower_flank_width(values - noise.mean, lowest.index) * step,
        n_modes=len(modes),
    )


#: Half width at half maximum over σ for a Gaussian: lower flanks are reported as σ.
HALF_MAXIMUM_PER_SIGMA = np.sqrt(2.0 * np.log(2.0))


def lower_flank_width(values, peak: int) -> float:
    """Half width at half maximum of the flank below ``peak``, as a Gaussian σ (samples).

    Parameters
    ----------
    values : array
        A waveform above its noise mean (or any density), lowest bin first.
    peak : int
        Index of the mode.

    Returns
    -------
    float
        The samples from ``peak`` down to the last one under half its value (at least
        one), over √(2 ln 2).
    """
    below = np.flatnonzero(values[:peak] < 0.5 * values[peak])
    half = peak - below[-1] if below.size else peak
    return max(half, 1) / HALF_MAXIMUM_PER_SIGMA
