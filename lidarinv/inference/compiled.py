"""Compiled per-row terms of the log-posterior: the Gaussian likelihood and RH metrics.

The sampler calls the log-posterior with a few rows at a time, so numpy's per-call cost,
not arithmetic, sets the price of these terms. The kernels here compute, row by row, what
:func:`.likelihood.log_likelihood` (exactly recorded bins) with
:func:`.likelihood.model_moments`, and :func:`.posterior.rh_from_waveform`, compute with
numpy; those stay as the references they are tested against.
"""

import math

import numpy as np
from numba import njit

_HALF_LOG_2PI = 0.5 * math.log(2.0 * math.pi)


@njit(cache=True)
def _gaussian_exact(signal, gain, baseline, noise_sigma, shot_factor, scale, fixed, y, exact):
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
            resid = y[j] - b - w
            total -= 0.5 * (resid * resid / variance + math.log(variance)) + _HALF_LOG_2PI
        out[r] = total
    return out


def gaussian_exact(signal, gain, baseline, noise_sigma, shot_factor, scale, fixed, data):
    """Log-likelihood (n,) of the exactly recorded bins of ``data`` (a WindowData).

    The mean is b + a·W and the variance σn² + g·a·W + ``fixed`` + (``scale``·a·W)²: the
    model of :func:`.likelihood.model_moments` with either discrepancy of
    :mod:`.discrepancy` (``fixed`` (bins,) DN², or η = ``scale``; pass zeros or 0 for
    the one not used).
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
    )


@njit(cache=True)
def _relative_heights(signal, start, dz, ground, levels):
    n, bins = signal.shape
    out = np.full((n, levels.size), np.nan)
    cum = np.empty(bins)
    for r in range(n):
        acc = 0.0
        for j in range(bins):
            acc += max(signal[r, j], 0.0)
            cum[j] = acc
        if not acc > 0.0:
            continue
        for i in range(levels.size):
            target = levels[i] * acc
            k = 0
            while k < bins - 1 and cum[k] < target:
                k += 1
            below = cum[k - 1] if k > 0 else 0.0
            step = cum[k] - below
            frac = (target - below) / step if step > 0.0 else 0.0
            frac = min(max(frac, 0.0), 1.0)
            out[r, i] = start + (k + frac) * dz - ground[r]
    return out


def relative_heights(signal, axis, ground, levels=(0.5, 0.98)) -> np.ndarray:
    """Compiled :func:`.posterior.rh_from_waveform`: heights above ``ground`` (m) below
    which each fraction of the energy lies, (n, levels); NaN for rows without energy."""
    dz = float(axis[1] - axis[0])
    return _relative_heights(
        np.ascontiguousarray(signal, dtype=np.float64),
        float(axis[0]) - 0.5 * dz,
        dz,
        np.ascontiguousarray(ground, dtype=np.float64),
        np.asarray(levels, dtype=np.float64),
    )
