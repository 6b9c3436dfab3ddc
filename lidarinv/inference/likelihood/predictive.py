"""Replicated observations of a Gaussian likelihood: draws of the samples a shot could
have recorded, for the posterior-predictive bands and check."""

import numpy as np


def covariance_root(covariance) -> np.ndarray:
    """R with R·Rᵀ = ``covariance`` (symmetric, positive semi-definite; tiny negative
    eigenvalues of rounding taken as 0).

    Parameters
    ----------
    covariance : array (bins, bins)

    Returns
    -------
    array (bins, k)
        The eigenvectors of the positive eigenvalues, each scaled by its square root.
    """
    values, vectors = np.linalg.eigh(0.5 * (covariance + covariance.T))
    keep = values > 0.0
    return vectors[:, keep] * np.sqrt(values[keep])


def recorded(draws, data) -> np.ndarray:
    """Draws as the digitiser records them: at the floor or the maximum where the product
    would have set them.

    Parameters
    ----------
    draws : array (n, bins) (DN)
    data : WindowData
        Its floor (where bins are censored) and saturation level.

    Returns
    -------
    array (n, bins) (DN)
    """
    if data.censored.any() and np.isfinite(data.floor):
        draws = np.maximum(draws, data.floor)
    if np.isfinite(data.saturation):
        draws = np.minimum(draws, data.saturation)
    return draws


def gaussian_replicates(mean, variance, noise_sigma, rng, *, noise_covariance=None,
                        discrepancy_covariance=None) -> np.ndarray:  # fmt: skip
    """Draws of N(mean, V) whose correlated parts are drawn with their correlations.

    Parameters
    ----------
    mean, variance : array (n, bins) (DN, DN²)
        Predictive mean and total per-bin variance of each row.
    noise_sigma : array (n,) (DN)
        The read noise σn of each row.
    rng : numpy.random.Generator
    noise_covariance : array (bins, bins), optional
        Σ, the read noise's correlation (its covariance is σn²·Σ); white if omitted.
    discrepancy_covariance : array (bins, bins) (DN²), optional
        A discrepancy covariance between bins, drawn as such.

    Returns
    -------
    array (n, bins) (DN)
        The mean plus the correlated parts plus white noise of the remaining variance.
    """
    noise = np.asarray(noise_sigma, float)[:, None] * np.ones_like(mean)
    correlated = np.zeros(mean.shape[1])  # the variance drawn with its correlations
    draws = mean.copy()
    if noise_covariance is not None:
        root = np.linalg.cholesky(noise_covariance)
        draws += noise * (rng.standard_normal(mean.shape) @ root.T)
        correlated = correlated + noise**2
    if discrepancy_covariance is not None:
        root = covariance_root(discrepancy_covariance)  # bin to bin, as simulated
        draws += rng.standard_normal((mean.shape[0], root.shape[1])) @ root.T
        correlated = correlated + np.diag(discrepancy_covariance)
    rest = np.clip(variance - correlated, 0.0, None)  # white: the remaining variance
    draws += np.sqrt(rest) * rng.standard_normal(mean.shape)
    return draws
