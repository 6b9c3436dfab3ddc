"""The observation likelihood: heteroscedastic Gaussian with censored and saturated bins.

Per the physics conventions, y_j = b + a·W_j + ε_j with ε_j ~ N(0, σn² + g·a·W_j). A
model-discrepancy term (:mod:`.discrepancy`) adds to the variance, for the difference
between the one random arrangement of trees in a footprint and the expected stand.
Samples set to the floor are censored, log Φ((floor − μ)/s); samples at the digitiser
maximum are censored from above, log Φ((μ − max)/s).
"""

from dataclasses import dataclass

import numpy as np
from scipy.special import log_ndtr

from lidarinv.observe.observation import Observation

from . import compiled

_LOG_2PI = np.log(2.0 * np.pi)


@dataclass(frozen=True)
class WindowData:
    """The part of an observation that enters the likelihood.

    Attributes
    ----------
    axis : array (m)
        Bin centres on the observation's axis (ascending).
    samples : array (DN)
    censored : array of bool
        Samples at the noise floor (true value ≤ ``floor``).
    saturated : array of bool
        Samples at the digitiser maximum (true value ≥ ``saturation``).
    floor, saturation : float (DN)
    """

    axis: np.ndarray
    samples: np.ndarray
    censored: np.ndarray
    saturated: np.ndarray
    floor: float = np.nan
    saturation: float = np.nan

    @classmethod
    def from_observation(cls, obs: Observation, lo: int, hi: int) -> "WindowData":
        """Bins ``lo:hi`` of an observation."""
        if hi - lo < 3:
            raise ValueError(f"shot {obs.shot_id}: the inversion window holds {hi - lo} bins")
        part = slice(lo, hi)
        return cls(
            axis=obs.axis[part].copy(),
            samples=obs.samples[part].copy(),
            censored=obs.censored_mask[part].copy(),
            saturated=obs.saturated_mask[part].copy(),
            floor=float(obs.floor),
            saturation=float(obs.saturation),
        )

    @property
    def exact(self) -> np.ndarray:
        return ~(self.censored | self.saturated)


def log_likelihood(data: WindowData, mean, variance) -> np.ndarray:
    """Log-likelihood of each row of model ``mean`` and ``variance`` (n, n_bins) (DN, DN²)."""
    sd = np.sqrt(variance)
    total = np.zeros(mean.shape[0])
    exact = data.exact
    if exact.any():
        r = (data.samples[exact] - mean[:, exact]) / sd[:, exact]
        total -= 0.5 * np.sum(r * r + _LOG_2PI, axis=1) + np.sum(np.log(sd[:, exact]), axis=1)
    if data.censored.any():
        c = data.censored
        total += np.sum(log_ndtr((data.floor - mean[:, c]) / sd[:, c]), axis=1)
    if data.saturated.any():
        s = data.saturated
        total += np.sum(log_ndtr((mean[:, s] - data.saturation) / sd[:, s]), axis=1)
    return total


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

    The same value as :func:`log_likelihood` of :func:`model_moments`, with the extra
    variance (η·a·W)² (η = ``discrepancy_scale``) plus ``fixed_variance`` (bins,) (DN²):
    compiled over the exactly recorded bins (:mod:`.compiled`), numpy over the censored
    and saturated ones. ``unit`` is the baseline's pattern in a rotated basis
    (:mod:`.correlated`, where every bin is exact).
    """
    fixed = np.zeros(data.axis.size) if fixed_variance is None else fixed_variance
    total = compiled.gaussian_exact(
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
    """Mean and variance (DN, DN²) of the samples for model waveforms ``signal`` (n, bins).

    ``signal`` is the noise-free waveform W (apparent reflectance per bin); ``gain``,
    ``baseline`` and ``noise_sigma`` are (n,) arrays; ``extra_variance`` (DN², scalar or
    (n, bins)) is added, e.g. a model discrepancy (:mod:`.discrepancy`).
    """
    scaled = np.asarray(gain)[:, None] * signal
    variance = np.asarray(noise_sigma)[:, None] ** 2 + shot_factor * scaled + extra_variance
    return np.asarray(baseline)[:, None] + scaled, variance
