"""The Gaussian likelihood's terms for rows of model waveforms: the predictive moments
and the log-likelihood of exactly recorded, censored and saturated bins, the exact bins
summed by a compiled kernel (:func:`gaussian_exact`): the sampler asks for a few rows at
a time, where numpy's per-call cost, not arithmetic, would set the price."""

import math

import numpy as np
from scipy.special import log_ndtr

from forward.backends import jit

from ..shot import WindowData
from .marginal import HALF_LOG_2PI, baseline_pattern


def row_log_likelihood(
    data: WindowData,
    signal,
    gain,
    baseline,
    noise_sigma,
    shot_factor=0.0,
    discrepancy_scale=0.0,
    fixed_variance=None,
    unit=None,
) -> np.ndarray:
    """Log-likelihood of model waveforms ``signal`` W (n, bins), the fast path.

    Parameters
    ----------
    data : WindowData
        The window's samples (DN) and which are censored or saturated.
    signal : array (n, bins)
        Model waveforms W (apparent reflectance per bin).
    gain, baseline, noise_sigma : array (n,) (DN per unit reflectance, DN, DN)
    shot_factor : float (DN)
        g, shot-noise variance per unit signal.
    discrepancy_scale : float
        η of a discrepancy proportional to each row's model.
    fixed_variance : array (bins,) (DN²), optional
        A variance fixed for the shot (e.g. a discrepancy's, :mod:`.discrepancy`).
    unit : array (bins,), optional
        The baseline's pattern in a rotated basis (:mod:`.covariance`, where every bin
        is exact); ones by default.

    Returns
    -------
    array (n,)

    Notes
    -----
    y_j ~ N(b·1_j + a·W_j, σn² + g·a·W_j + (η·a·W_j)² + v_j) over the exactly recorded
    bins (compiled, :func:`gaussian_exact`), censored bins log Φ((floor − μ)/s) and
    saturated ones log Φ((μ − max)/s) (numpy). :mod:`lidarinv.testing` holds the slow
    reference it is checked against.

    References
    ----------
    Tobin, J. (1958). Estimation of relationships for limited dependent variables.
    *Econometrica* 26(1), 24–36 (censored Gaussian observations).
    """
    fixed = np.zeros(data.axis.size) if fixed_variance is None else fixed_variance
    total = gaussian_exact(
        signal, gain, baseline, noise_sigma, shot_factor, discrepancy_scale, fixed, data, unit
    )
    limited = data.censored | data.saturated
    if limited.any():
        part = signal[:, limited]
        extra = fixed[limited] + (discrepancy_scale * np.asarray(gain)[:, None] * part) ** 2
        mean, variance = model_moments(part, gain, baseline, noise_sigma, shot_factor, extra)
        sd = np.sqrt(variance)
        c, s = data.censored[limited], data.saturated[limited]
        total += np.sum(log_ndtr((data.floor - mean[:, c]) / sd[:, c]), axis=1)
        total += np.sum(log_ndtr((mean[:, s] - data.saturation) / sd[:, s]), axis=1)
    return total


def model_moments(signal, gain, baseline, noise_sigma, shot_factor=0.0, extra_variance=0.0):
    """Mean and variance of the samples for model waveforms.

    Parameters
    ----------
    signal : array (n, bins)
        The noise-free waveform W (apparent reflectance per bin).
    gain, baseline, noise_sigma : array (n,) (DN per unit reflectance, DN, DN)
    shot_factor : float (DN)
        g.
    extra_variance : float or array (n, bins) (DN²)
        Added, e.g. a model discrepancy (:mod:`.discrepancy`).

    Returns
    -------
    mean, variance : arrays (n, bins) (DN, DN²)
        b + a·W and σn² + g·a·W + extra (physics conventions, "Observation model").
    """
    scaled = np.asarray(gain)[:, None] * signal
    variance = np.asarray(noise_sigma)[:, None] ** 2 + shot_factor * scaled + extra_variance
    return np.asarray(baseline)[:, None] + scaled, variance


@jit
def _gaussian_exact(signal, gain, baseline, noise_sigma, shot_factor, scale, fixed, y, exact, unit):
    n, bins = signal.shape
    out = np.zeros(n)
    for r in range(n):
        a, b, s2 = gain[r], baseline[r], noise_sigma[r] ** 2
        total = 0.0
        for j in range(bins):
            if not exact[j]:
                continue
            w = a * signal[r, j]
            variance = s2 + shot_factor * w + fixed[j] + (scale * w) ** 2
            resid = y[j] - b * unit[j] - w
            total -= 0.5 * (resid * resid / variance + math.log(variance)) + HALF_LOG_2PI
        out[r] = total
    return out


def gaussian_exact(signal, gain, baseline, noise_sigma, shot_factor, scale, fixed, data, unit=None):
    """Log-likelihood of the exactly recorded bins (compiled).

    Parameters
    ----------
    signal : array (n, bins)
    gain, baseline, noise_sigma : array (n,)
    shot_factor : float (DN)
    scale : float
        η of a discrepancy proportional to the model (0 for none).
    fixed : array (bins,) (DN²)
        A discrepancy variance fixed for the shot (zeros for none).
    data : WindowData
    unit : array (bins,), optional
        The baseline's pattern, ones by default; in a rotated basis (:mod:`.covariance`)
        the rotated ones.

    Returns
    -------
    array (n,)
        Σ_j over exact bins of log N(y_j; b·unit_j + a·W_j, σn² + g·a·W_j + v_j + (η·a·W_j)²).
    """
    return _gaussian_exact(
        np.ascontiguousarray(signal, dtype=np.float64),
        np.ascontiguousarray(gain, dtype=np.float64),
        np.ascontiguousarray(baseline, dtype=np.float64),
        np.ascontiguousarray(noise_sigma, dtype=np.float64),
        float(shot_factor),
        float(scale),
        np.ascontiguousarray(fixed, dtype=np.float64),
        np.ascontiguousarray(data.samples, dtype=np.float64),
        np.ascontiguousarray(data.exact),
        baseline_pattern(unit, data),
    )
