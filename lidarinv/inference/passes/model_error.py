"""The instrument model's own error, sized by the shot's residuals at its MAP.

The simulated discrepancy (:mod:`.realisations`) holds what a random arrangement of trees
does to the waveform; it cannot hold the error of the instrument model itself: the shape
of the measured pulse, a receiver's response after the ground, what widens a real ground
return. That error enters the likelihood as a per-bin sd η times the shot's own signal
(``RealisationSettings.instrument_floor``, η₀ by default). Where the residuals at the MAP
are larger than the noise, the simulated discrepancy and η₀ allow, η is raised until their
mean square matches: E[Σ r²/v] equals the number of bins for any correlation between
bins, so the sum of the squared residuals over the per-bin variances sizes η without the
covariance's inverse. The raise is reported, as a misfit the model did not explain.
"""

import numpy as np
from scipy.optimize import brentq

#: How the result's flag begins where the error was raised.
MODEL_ERROR_FLAG = "model error raised"

#: The largest per-bin sd of the instrument model's error, as a fraction of the signal.
LARGEST_FLOOR = 2.0

#: Absolute tolerance on η.
_TOLERANCE = 1e-6


def floor_for_residuals(residuals, base_variance, unit_variance, floor) -> float:
    """The smallest η ≥ ``floor`` with Σ r²/(v₀ + η²·u) ≤ the number of bins.

    Parameters
    ----------
    residuals : array (bins,) (DN)
        Observed minus the MAP's predictive mean, on the exactly recorded bins.
    base_variance : array (bins,) (DN²)
        Per-bin variance without the instrument model's error: the noise and the
        simulated discrepancy.
    unit_variance : array (bins,) (DN²)
        The instrument model's error variance per bin at η = 1.
    floor : float
        η₀, the least η.

    Returns
    -------
    float
        η, at most :data:`LARGEST_FLOOR`.
    """
    r2 = np.asarray(residuals, float) ** 2
    v0, u = np.asarray(base_variance, float), np.asarray(unit_variance, float)

    def excess(eta):
        return float(np.sum(r2 / (v0 + eta * eta * u))) - r2.size

    if not r2.size or excess(floor) <= 0.0:
        return float(floor)
    if excess(LARGEST_FLOOR) > 0.0:
        return LARGEST_FLOOR
    return float(brentq(excess, floor, LARGEST_FLOOR, xtol=_TOLERANCE))


def shot_floor(pilot, likelihood, estimate, unit_variance, floor) -> float:
    """η for a shot: :func:`floor_for_residuals` at the pilot posterior's MAP.

    Parameters
    ----------
    pilot : LogPosterior
        The posterior the MAP search maximised.
    likelihood : Likelihood
        The shot's likelihood under the simulated discrepancy, without the instrument
        model's error: its predictive moments give the residuals and their variance.
    estimate : MapEstimate or None
        The pilot's MAP (unbounded coordinates); η₀ where there is none.
    unit_variance : array (bins,) (DN²)
        The instrument model's error variance per bin at η = 1.
    floor : float
        η₀.

    Returns
    -------
    float
    """
    if estimate is None:
        return float(floor)
    space = pilot.space
    x, _ = space.from_unbounded(np.asarray(estimate.u, float)[None, :])
    terms = pilot.evaluate(x, keep_signal=True)
    if not np.isfinite(terms.log_posterior[0]):
        return float(floor)
    values = space.values(x)
    if "gain" not in values:
        values["gain"] = terms.gain_fit[:, 1]
    mean, variance = likelihood.predictive_moments(terms.signal, values)
    exact = likelihood.data.exact
    residuals = (likelihood.data.samples - mean[0])[exact]
    return floor_for_residuals(residuals, variance[0][exact], unit_variance[exact], floor)


def describe_floor(floor, least) -> str:
    """The result's flag where the instrument model's error was raised above η₀."""
    return (
        f"{MODEL_ERROR_FLAG}: the residuals at the MAP exceed the noise and the simulated "
        f"discrepancy, so the instrument model's error is taken as {100 * floor:.0f} % of "
        f"the signal per bin instead of {100 * least:.0f} % (the model does not explain "
        "part of the waveform; see the residual panel)"
    )
