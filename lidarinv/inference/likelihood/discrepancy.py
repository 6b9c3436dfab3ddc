"""Model-discrepancy variance: one random arrangement of trees against the expected stand.

The expected-waveform model predicts the mean over arrangements of trees; a footprint
holds one. The difference enters the likelihood as an extra variance per bin, a fraction
η of the signal squared. Which signal is chosen through :data:`DISCREPANCY_MODELS`:

``model``
    (η·a·W_j)², the model waveform of each row. The −½·ln(variance) terms then reward
    rows that predict less signal.
``observed``
    (η·ŝ_j)², ŝ the observed signal above the noise mean (lightly smoothed: the noise
    adds only η²σn² to the variance): the same for every row, so the variance cannot
    pull the parameters.
``realisations``
    A covariance between bins simulated from explicit realisations around a pilot MAP
    (:mod:`.realisations`); the pilot uses ``observed``.

The helpers :func:`footprint_area` and :func:`gap_cv2` describe the spread of a Poisson
stand seen through a Gaussian footprint (``studies/discrepancy.py``).
"""

import numpy as np
from scipy.ndimage import gaussian_filter1d


def model_variance(scale, gain, signal) -> np.ndarray:
    """(η·a·W)² (DN²) for rows of ``signal`` W (n, bins) and ``gain`` a (n,)."""
    return (scale * np.asarray(gain)[:, None] * signal) ** 2


def observed_variance(samples, baseline, smooth_bins, scale) -> np.ndarray:
    """(η·ŝ)² (DN², one per bin) from the observed ``samples`` (DN).

    ŝ is the observation less its noise mean ``baseline``, smoothed by a Gaussian of
    ``smooth_bins`` and clipped at zero.
    """
    signal = gaussian_filter1d(np.asarray(samples, float) - baseline, max(smooth_bins, 0.5))
    return (scale * np.clip(signal, 0.0, None)) ** 2


#: Discrepancy models by name: None where the variance is computed per row from the model
#: waveform, else the function of the observation that gives a fixed per-bin variance
#: (for ``realisations``, that of the pilot MAP search).
DISCREPANCY_MODELS = {
    "model": None,
    "observed": observed_variance,
    "realisations": observed_variance,
}

#: The discrepancy model that replaces the per-bin variance by a simulated covariance.
SIMULATED = "realisations"


def footprint_area(footprint_sigma_m) -> float:
    """Effective area (m²) (∫w)²/∫w² of a Gaussian footprint of σ ``footprint_sigma_m``."""
    return 4.0 * np.pi * float(footprint_sigma_m) ** 2


def gap_cv2(gap0, crown_area, area) -> np.ndarray:
    """Squared relative spread of the gap fraction seen by a footprint of ``area`` (m²)
    over crowns of mean area ``crown_area`` (m²), at expected gap ``gap0``."""
    gap0 = np.clip(gap0, 1e-12, 1.0)
    return (1.0 - gap0) / gap0 * crown_area / area
