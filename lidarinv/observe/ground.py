"""Ground-peak detection: the lowest significant mode above the floor, to sub-bin precision."""

from dataclasses import dataclass

import numpy as np
from scipy.optimize import curve_fit
from scipy.signal import find_peaks

from .signal import smooth, smoothed_noise_factor


@dataclass(frozen=True)
class GroundPeak:
    """The ground return of one waveform.

    Attributes
    ----------
    position : float (m)
        Axis value of the peak centre (height or elevation), sub-bin.
    index : float
        Fractional bin index of ``position``.
    uncertainty : float (m)
        1-σ uncertainty of ``position`` from the fit (usable as a prior width).
    amplitude : float
        Peak amplitude above the noise mean (digitiser units).
    width : float (m)
        Gaussian σ of the peak.
    method : str
        ``"gaussian-fit"`` or ``"parabola"`` (fallback when the fit fails).
    """

    position: float
    index: float
    uncertainty: float
    amplitude: float
    width: float
    method: str


def _gauss(x, amplitude, centre, sigma):
    return amplitude * np.exp(-0.5 * ((x - centre) / sigma) ** 2)


def _lower_half_width(values, peak, level):
    """Bins from the peak down (towards index 0) to where ``values`` fall below ``level``."""
    below = np.flatnonzero(values[:peak] < level)
    return peak - below[-1] if below.size else peak


def find_ground(
    samples,
    axis,
    noise_mean: float,
    noise_sigma: float,
    *,
    n_sigma: float = 4.0,
    smooth_bins: float | None = 2.0,
    prominence_sigmas: float = 4.0,
    valid=None,
    within=None,
) -> GroundPeak | None:
    """Locate the ground peak: the lowest significant mode above the noise floor.

    The waveform is smoothed for detection; peaks must exceed the smoothed floor
    ``noise_mean + n_sigma·σ_s`` and stand out by ``prominence_sigmas·σ_s``. The lowest
    such peak is then located by a least-squares Gaussian fit to the raw samples over
    its lower flank and top (the side the canopy cannot reach), excluding invalid
    (censored or saturated) samples, so a clipped peak is fitted from its flanks.

    Parameters
    ----------
    samples, axis : arrays
        Waveform (digitiser units) and ascending axis (m).
    noise_mean, noise_sigma : float
        Noise of the raw samples (digitiser units).
    n_sigma, prominence_sigmas : float
        Detection thresholds in units of the smoothed noise σ.
    smooth_bins : float, optional
        Gaussian smoothing σ (bins) for detection only.
    valid : array of bool, optional
        Samples usable in the fit.
    within : (int, int), optional
        First and last sample index a peak may lie at, e.g. the signal extent's: a noise
        spike outside it is not taken for the ground.

    Returns
    -------
    GroundPeak or None
        ``None`` when no peak rises above the floor.
    """
    samples = np.asarray(samples, float)
    axis = np.asarray(axis, float)
    valid = np.ones(samples.shape, bool) if valid is None else np.asarray(valid, bool)
    sigma_s = max(noise_sigma * smoothed_noise_factor(smooth_bins), 1e-12)
    smoothed = smooth(samples, smooth_bins) - noise_mean
    peaks, _ = find_peaks(
        smoothed, height=n_sigma * sigma_s, prominence=prominence_sigmas * sigma_s
    )
    if within is not None:
        peaks = peaks[(peaks >= within[0]) & (peaks <= within[1])]
    if peaks.size == 0:
        return None
    peak = int(peaks[0])  # lowest on the ascending axis
    step = float(axis[1] - axis[0])
    height = smoothed[peak]
    half = max(_lower_half_width(smoothed, peak, 0.5 * height), 1)
    sigma0 = max(half / np.sqrt(2 * np.log(2)), 0.7)  # bins
    first = max(peak - int(np.ceil(2.5 * sigma0)), 0)
    stop = min(peak + max(int(np.ceil(1.0 * sigma0)), 2) + 1, samples.size)
    window = np.arange(first, stop)
    window = window[valid[window]]
    y = samples[window] - noise_mean
    if window.size >= 4:
        try:
            params, cov = curve_fit(
                _gauss,
                window.astype(float),
                y,
                p0=(max(height, y.max()), float(peak), sigma0),
                maxfev=2000,
            )
            amplitude, centre, width = params
            err = float(np.sqrt(cov[1, 1])) if np.all(np.isfinite(cov)) else np.nan
            if amplitude > 0 and first - 1 <= centre <= stop and 0.2 < abs(width) < 10 * sigma0:
                return GroundPeak(
                    position=float(axis[0] + centre * step),
                    index=float(centre),
                    uncertainty=err * step,
                    amplitude=float(amplitude),
                    width=float(abs(width)) * step,
                    method="gaussian-fit",
                )
        except (RuntimeError, ValueError):
            pass
    return _parabola(smoothed, axis, peak, sigma0, noise_sigma)


def _parabola(values, axis, peak, sigma0, noise_sigma):
    """Three-point log-parabola vertex on the smoothed waveform (fallback)."""
    step = float(axis[1] - axis[0])
    offset = 0.0
    if 0 < peak < values.size - 1 and np.all(values[peak - 1 : peak + 2] > 0):
        a, b, c = np.log(values[peak - 1 : peak + 2])
        denominator = a - 2 * b + c
        if denominator < 0:
            offset = float(np.clip(0.5 * (a - c) / denominator, -0.5, 0.5))
    index = peak + offset
    return GroundPeak(
        position=float(axis[0] + index * step),
        index=float(index),
        uncertainty=step / np.sqrt(12.0),
        amplitude=float(values[peak]),
        width=float(sigma0 * step),
        method="parabola",
    )
