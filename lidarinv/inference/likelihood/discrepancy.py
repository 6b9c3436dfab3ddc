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
    (:mod:`lidarinv.inference.passes.realisations`); the pilot uses ``observed``.
``following``
    The same simulated covariance, scaled bin by bin by each row's own model signal
    against the pilot's (:mod:`.following`), so that a row without crowns where the pilot
    had them finds no spread there.

The spread of a Poisson stand seen through a Gaussian footprint is
:func:`forward.poisson_stand.footprint_gap_cv2` (``studies/discrepancy.py``).
"""

import numpy as np
from scipy.ndimage import gaussian_filter1d


def model_variance(scale, gain, signal) -> np.ndarray:
    """The discrepancy variance of each row's own model.

    Parameters
    ----------
    scale : float
        η.
    gain : array (n,)
    signal : array (n, bins)

    Returns
    -------
    array (n, bins) (DN²)
        (η·a·W)².
    """
    return (scale * np.asarray(gain)[:, None] * signal) ** 2


def observed_variance(samples, baseline, smooth_bins, scale) -> np.ndarray:
    """The discrepancy variance fixed by the observed signal.

    Parameters
    ----------
    samples : array (DN)
        The observation.
    baseline : float (DN)
        Its noise mean.
    smooth_bins : float
        Sd (bins) of the Gaussian smoothing.
    scale : float
        η.

    Returns
    -------
    array (bins,) (DN²)
        (η·ŝ)², ŝ the samples less the noise mean, smoothed and clipped at zero.
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
    "following": observed_variance,
}

#: The discrepancy model that replaces the per-bin variance by a simulated covariance.
SIMULATED = "realisations"
#: The discrepancy model whose simulated covariance follows each row's stand.
FOLLOWING = "following"
#: The discrepancy models that simulate a covariance for the shot.
SIMULATED_MODELS = (SIMULATED, FOLLOWING)
