"""Robust estimation of the noise mean and σ of a waveform, and the noise floor."""

from dataclasses import dataclass

import numpy as np
from scipy.optimize import curve_fit

#: σ of a normal variable per unit median absolute deviation.
MAD_TO_SIGMA = 1.482602218505602


@dataclass(frozen=True)
class NoiseEstimate:
    """Noise mean and standard deviation (digitiser units) and how they were obtained."""

    mean: float
    sigma: float
    method: str

    def floor(self, n_sigma: float) -> float:
        """Noise floor mean + n·σ (digitiser units)."""
        return noise_floor(self.mean, self.sigma, n_sigma)


def noise_floor(mean: float, sigma: float, n_sigma: float) -> float:
    """The noise floor ``mean + n_sigma·sigma`` (digitiser units)."""
    if not (np.isfinite(mean) and np.isfinite(sigma) and sigma >= 0):
        raise ValueError(f"noise mean {mean} and σ {sigma} must be finite, σ ≥ 0")
    return float(mean + n_sigma * sigma)


def _robust(values, clip=3.0):
    """Median/MAD, then the mean and σ of the samples within ±clip·σ (more efficient)."""
    centre = float(np.median(values))
    sigma = MAD_TO_SIGMA * float(np.median(np.abs(values - centre)))
    if sigma <= 0:
        return centre, sigma
    kept = values[np.abs(values - centre) <= clip * sigma]
    # σ of a normal truncated at ±3σ is 0.9865σ
    return float(kept.mean()), float(kept.std()) / 0.98654


def _from_ends(samples, valid, end_fraction, min_bins):
    n = samples.size
    k = max(min_bins, round(end_fraction * n))
    if 2 * k > n:
        raise ValueError(f"waveform of {n} bins is too short for {k}-bin noise ends")
    ends = []
    for part, ok in ((samples[:k], valid[:k]), (samples[-k:], valid[-k:])):
        part = part[ok]
        if part.size >= min_bins:
            ends.append((part, *_robust(part)))
    if not ends:
        raise ValueError("too few uncensored samples at the waveform ends to estimate noise")
    if len(ends) == 2:
        (a, ma, sa), (b, mb, sb) = ends
        spread = max(sa, sb, 1e-12) * np.sqrt(2.0 / min(a.size, b.size))
        if abs(ma - mb) <= 4.0 * spread + 1e-12:  # both ends are noise: pool them
            return _robust(np.concatenate([a, b]))
        # one end holds signal (or a baseline step): keep the quieter end
        return min(((ma, sa), (mb, sb)), key=lambda ms: ms[0] + ms[1])
    return ends[0][1:]


def half_sample_mode(values) -> float:
    """Mode of a sample by the half-sample method (Bickel & Frühwirth 2006)."""
    x = np.sort(np.asarray(values, float))
    while x.size > 3:
        h = (x.size + 1) // 2
        widths = x[h - 1 :] - x[: x.size - h + 1]
        start = int(np.argmin(widths))
        x = x[start : start + h]
    if x.size == 3:
        x = x[:2] if x[1] - x[0] <= x[2] - x[1] else x[1:]
    return float(x.mean())


def _gaussian(x, count, mean, sigma):
    return count * np.exp(-0.5 * ((x - mean) / sigma) ** 2)


def _from_histogram(samples, valid):
    x = samples[valid]
    if x.size < 10:
        raise ValueError("too few uncensored samples to estimate noise from the histogram")
    mode = half_sample_mode(x)
    # the noise peak's lower half is free of signal (returns only add energy)
    below = mode - x[x <= mode]
    if below.size < 5:
        raise ValueError("the sample histogram has no lower half to estimate the noise σ")
    mean, sigma = mode, MAD_TO_SIGMA * float(np.median(below))
    if sigma <= 0:
        return mean, 0.0
    # refine with a Gaussian fitted to the histogram from 3σ below the mode to 0.5σ above
    # it, the side of the noise peak that the returns do not reach
    for _ in range(2):
        edges = np.arange(mean - 3.0 * sigma, mean + 0.5 * sigma + 1e-9, 0.25 * sigma)
        counts, edges = np.histogram(x, bins=edges)
        centres = 0.5 * (edges[1:] + edges[:-1])
        try:
            (_, fit_mean, fit_sigma), _ = curve_fit(
                _gaussian, centres, counts, p0=(counts.max(), mean, sigma), maxfev=2000
            )
        except (RuntimeError, ValueError):
            break
        if not (np.isfinite(fit_mean) and 0 < abs(fit_sigma) < 3 * sigma):
            break
        mean, sigma = float(fit_mean), float(abs(fit_sigma))
    return float(mean), sigma


def estimate_noise(
    samples,
    *,
    method: str = "ends",
    valid=None,
    end_fraction: float = 0.1,
    min_bins: int = 8,
) -> NoiseEstimate:
    """Robust noise mean and σ of one waveform.

    Parameters
    ----------
    samples : array of float
        Waveform samples (digitiser units).
    method : {"ends", "histogram"}
        ``"ends"``: median and MAD of the signal-free first and last ``end_fraction`` of
        the window (the end holding signal is dropped if the two disagree).
        ``"histogram"``: as Sun & Ranson did for SLICER, the noise is the dominant mode of
        the sample histogram; its centre is the half-sample mode and σ comes from the
        lower half of that mode, which returns cannot reach.
    valid : array of bool, optional
        Samples to use (e.g. exclude censored or saturated ones).
    end_fraction : float
        Fraction of the window taken at each end for ``"ends"``.
    min_bins : int
        Minimum number of samples per end.

    Returns
    -------
    NoiseEstimate
        Mean and σ in digitiser units.
    """
    samples = np.asarray(samples, float)
    if samples.ndim != 1 or samples.size == 0:
        raise ValueError("noise estimation needs a non-empty 1-D waveform")
    if not np.all(np.isfinite(samples)):
        raise ValueError("noise estimation: the waveform has NaN or infinite samples")
    valid = np.ones(samples.shape, bool) if valid is None else np.asarray(valid, bool)
    estimators = {
        "ends": lambda: _from_ends(samples, valid, end_fraction, min_bins),
        "histogram": lambda: _from_histogram(samples, valid),
    }
    if method not in estimators:
        raise ValueError(f"unknown noise method {method!r}; choose from {list(estimators)}")
    mean, sigma = estimators[method]()
    return NoiseEstimate(float(mean), float(sigma), method)
