"""The noise of a recorded waveform: mean, σ and autocorrelation from its signal-free bins.

Real digitisers add noise that is correlated from bin to bin (filtered detector noise) and
record integer or rounded samples. Everything here is measured on the shot's own
signal-free bins, never derived from a white-noise formula, and never from a median
absolute deviation (which quantisation can make zero): the mean and σ are those of the
samples kept by iterative σ-clipping, the autocorrelation is the sample autocorrelation
over pairs of signal-free bins, and the σ of the *smoothed* noise is the larger of its
value measured on the smoothed signal-free bins and its value computed from the measured
σ and autocorrelation.
"""

from dataclasses import dataclass, field, replace

import numpy as np

#: Samples beyond this many σ from the mean are dropped when estimating the noise.
CLIP_SIGMAS = 4.0
#: Fewest signal-free bins from which the noise is estimated.
MIN_NOISE_BINS = 16


@dataclass(frozen=True)
class NoiseModel:
    """The noise of one shot (digitiser units).

    Attributes
    ----------
    mean : float
        Noise mean (baseline) b.
    sigma : float
        Standard deviation σn of the recorded samples (quantisation included).
    autocorrelation : array
        R(0), R(1), …, R(K): correlation of the noise at lags of 0 to K bins (R(0) = 1).
    n_bins : int
        Number of signal-free bins the estimate used (0 for product values).
    source : str
        ``"samples"`` (measured here) or ``"product"`` (the file's own noise fields).
    quantum : float
        Spacing of the recorded values (1 for integer counts; 0 when continuous).
    smoothing_bins : float
        Gaussian smoothing σ (bins) that ``smoothed_sigma`` and ``slope_sigma`` refer to.
    smoothed_sigma : float
        σ of the noise after that smoothing, measured on the smoothed signal-free bins.
    slope_sigma : float
        σ of the smoothed noise's central difference (digitiser units per bin).
    product_mean, product_sigma : float
        The file's own noise fields, NaN when it has none (kept as a cross-check).
    """

    mean: float
    sigma: float
    autocorrelation: np.ndarray = field(default_factory=lambda: np.ones(1))
    n_bins: int = 0
    source: str = "samples"
    quantum: float = 0.0
    smoothing_bins: float = 0.0
    smoothed_sigma: float = np.nan
    slope_sigma: float = np.nan
    product_mean: float = np.nan
    product_sigma: float = np.nan

    def detection_floor(self, n_sigmas: float, units: str = "smoothed") -> float:
        """The floor ``mean + n_sigmas·σ`` for the smoothed waveform, σ being that of the
        smoothed noise (``units="smoothed"``) or of the recorded noise (``"raw"``)."""
        sigma = {"smoothed": self.smoothed_sigma, "raw": self.sigma}[units]
        return noise_floor(self.mean, sigma, n_sigmas)

    def describe(self) -> dict:
        """Scalars for tables and JSON (the autocorrelation's first three lags)."""
        lags = {f"noise_r{k}": float(r) for k, r in enumerate(self.autocorrelation[1:4], 1)}
        return {
            "noise_mean": self.mean,
            "noise_sigma": self.sigma,
            "noise_smoothed_sigma": self.smoothed_sigma,
            "noise_source": self.source,
            "noise_bins": self.n_bins,
            "product_noise_mean": self.product_mean,
            "product_noise_sigma": self.product_sigma,
            **lags,
        }


def noise_floor(mean: float, sigma: float, n_sigma: float) -> float:
    """The noise floor ``mean + n_sigma·sigma`` (digitiser units)."""
    if not (np.isfinite(mean) and np.isfinite(sigma) and sigma >= 0):
        raise ValueError(f"noise mean {mean} and σ {sigma} must be finite, σ ≥ 0")
    return float(mean + n_sigma * sigma)


def end_bins(n_bins: int, fraction: float = 0.125, minimum: int = MIN_NOISE_BINS) -> np.ndarray:
    """Mask of the first and last ``fraction`` of a window: the first guess of where the
    noise is, before the signal has been found."""
    k = max(minimum, round(fraction * n_bins))
    if 2 * k > n_bins:
        raise ValueError(f"a window of {n_bins} bins is too short to hold noise at its ends")
    mask = np.zeros(n_bins, bool)
    mask[:k] = mask[-k:] = True
    return mask


def clipped_mean_sigma(values, clip: float = CLIP_SIGMAS, max_iterations: int = 10):
    """Mean and σ of the values within ±clip·σ of the mean, iterated to convergence.

    Starts from the plain mean and σ, so a sample spread below one quantisation step
    still gives its true (non-zero) σ.
    """
    values = np.asarray(values, float)
    keep = np.ones(values.size, bool)
    mean, sigma = float(values.mean()), float(values.std())
    for _ in range(max_iterations):
        if sigma == 0:
            break
        new_keep = np.abs(values - mean) <= clip * sigma
        if np.array_equal(new_keep, keep):
            break
        keep = new_keep
        mean, sigma = float(values[keep].mean()), float(values[keep].std())
    return mean, sigma


def autocorrelation(values, mask, mean: float, max_lag: int) -> np.ndarray:
    """Sample autocorrelation R(0…max_lag) over pairs of bins that are both in ``mask``.

    Bins outside the mask (signal, spikes, censored samples) break the series, so the
    signal-free stretches above and below the return are pooled without bridging it.
    """
    values = np.asarray(values, float) - mean
    mask = np.asarray(mask, bool)
    x = np.where(mask, values, 0.0)
    variance = float(np.sum(x * x) / max(mask.sum(), 1))
    out = np.ones(max_lag + 1)
    if variance <= 0:
        out[1:] = 0.0
        return out
    for lag in range(1, max_lag + 1):
        both = mask[:-lag] & mask[lag:]
        pairs = int(both.sum())
        out[lag] = np.sum(x[:-lag] * x[lag:]) / (pairs * variance) if pairs else 0.0
    return out


def sample_quantum(samples) -> float:
    """1 when every sample is an integer count, else 0 (continuous values)."""
    samples = np.asarray(samples, float)
    return 1.0 if np.all(samples == np.round(samples)) else 0.0


def estimate_noise(
    samples, signal_free=None, *, valid=None, max_lag: int = 32, clip: float = CLIP_SIGMAS
) -> NoiseModel:
    """Noise mean, σ and autocorrelation from the signal-free bins of one waveform.

    Parameters
    ----------
    samples : array of float
        Waveform samples (digitiser units).
    signal_free : array of bool, optional
        Bins known to hold no signal; default the first and last eighth of the window.
    valid : array of bool, optional
        Samples measured exactly (not censored or saturated); others are left out.
    max_lag : int
        Largest lag (bins) of the autocorrelation.
    clip : float
        σ-clipping limit that drops spikes from the estimate.

    Returns
    -------
    NoiseModel
        ``source="samples"``; the smoothed-noise fields are left for
        :func:`with_smoothed_noise`.
    """
    samples = np.asarray(samples, float)
    if samples.ndim != 1 or samples.size == 0:
        raise ValueError("noise estimation needs a non-empty 1-D waveform")
    if not np.all(np.isfinite(samples)):
        raise ValueError("noise estimation: the waveform has NaN or infinite samples")
    free = end_bins(samples.size) if signal_free is None else np.asarray(signal_free, bool)
    if valid is not None:
        free = free & np.asarray(valid, bool)
    if free.sum() < MIN_NOISE_BINS:
        raise ValueError(
            f"only {int(free.sum())} signal-free bins (need {MIN_NOISE_BINS}) to estimate noise"
        )
    mean, sigma = clipped_mean_sigma(samples[free], clip)
    kept = free & (np.abs(samples - mean) <= clip * sigma if sigma > 0 else free)
    return NoiseModel(
        mean=mean,
        sigma=sigma,
        autocorrelation=autocorrelation(samples, kept, mean, max_lag),
        n_bins=int(free.sum()),
        source="samples",
        quantum=sample_quantum(samples[free]),
    )


def filtered_sigma(sigma: float, autocorrelation, weights) -> float:
    """σ of noise of σ ``sigma`` and the given autocorrelation after a linear filter:
    σ·√(Σ_ij w_i w_j R(|i − j|)), with R set to zero beyond its first non-positive lag
    (the usual truncation of a sample autocorrelation, whose far lags are noise)."""
    r = np.asarray(autocorrelation, float)
    stop = np.flatnonzero(r <= 0)
    r = r[: stop[0]] if stop.size else r
    weights = np.asarray(weights, float)
    pairs = np.correlate(weights, weights, mode="full")  # Σ_i w_i w_(i+k), k = −K … K
    centre = weights.size - 1
    lags = min(r.size - 1, centre)
    total = pairs[centre] + 2.0 * np.sum(pairs[centre + 1 : centre + 1 + lags] * r[1 : lags + 1])
    return float(sigma * np.sqrt(max(total, 0.0)))


def gaussian_weights(sigma_bins: float):
    radius = max(int(np.ceil(4.0 * sigma_bins)), 1)
    x = np.arange(-radius, radius + 1)
    weights = np.exp(-0.5 * (x / sigma_bins) ** 2)
    weights /= weights.sum()
    return weights, np.convolve(weights, [0.5, 0.0, -0.5])  # the smoothed central difference


def with_smoothed_noise(noise: NoiseModel, smoothed, signal_free, smoothing_bins) -> NoiseModel:
    """The noise model with the σ of the smoothed noise and of its slope.

    Each is measured on the smoothed waveform's signal-free bins (the caller leaves out
    bins whose smoothing kernel reaches past the window's edge) and computed from the
    measured σ and autocorrelation; the larger is kept. The direct measurement holds any
    slow baseline wander, which the truncated autocorrelation misses; the computed one
    is steady where a short window leaves few independent smoothed values.
    """
    smoothed = np.asarray(smoothed, float)
    free = np.asarray(signal_free, bool)
    if free.sum() < MIN_NOISE_BINS:
        raise ValueError(f"only {int(free.sum())} signal-free bins to measure the smoothed noise")
    _, smoothed_sigma = clipped_mean_sigma(smoothed[free] - noise.mean)
    slope = np.gradient(smoothed)
    interior = free & np.roll(free, 1) & np.roll(free, -1)
    _, slope_sigma = clipped_mean_sigma(slope[interior] if interior.sum() > 2 else slope[free])
    if smoothing_bins:
        weights, slope_weights = gaussian_weights(float(smoothing_bins))
        r = noise.autocorrelation
        smoothed_sigma = max(smoothed_sigma, filtered_sigma(noise.sigma, r, weights))
        slope_sigma = max(slope_sigma, filtered_sigma(noise.sigma, r, slope_weights))
    return replace(
        noise,
        smoothing_bins=float(smoothing_bins or 0.0),
        smoothed_sigma=smoothed_sigma,
        slope_sigma=slope_sigma,
    )


def product_noise(mean: float, sigma: float, smoothing_bins: float = 0.0) -> NoiseModel:
    """A noise model from a product's own noise fields (white noise assumed: the product
    gives no autocorrelation). Used where the samples hold too few signal-free bins."""
    if not (np.isfinite(mean) and np.isfinite(sigma) and sigma > 0):
        raise ValueError("the file supplies no usable noise mean and σ for this shot")
    width = max(float(smoothing_bins or 0.0), 1.0)
    return NoiseModel(
        mean=float(mean),
        sigma=float(sigma),
        source="product",
        smoothing_bins=float(smoothing_bins or 0.0),
        # white noise through a Gaussian of σ w bins: Σk² = 1/(2√π w), Σk'² = 1/(4√π w³)
        smoothed_sigma=float(sigma) / np.sqrt(2.0 * np.sqrt(np.pi) * width),
        slope_sigma=float(sigma) / np.sqrt(4.0 * np.sqrt(np.pi) * width**3),
        product_mean=float(mean),
        product_sigma=float(sigma),
    )
