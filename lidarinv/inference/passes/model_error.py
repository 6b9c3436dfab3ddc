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

The raise has a ceiling, :data:`MODEL_ERROR_CEILING`, fixed by what the instrument model is
known to lack, not by the shot: a shot whose residuals need more is a misfit (flagged,
never clean), and its likelihood keeps the ceiling, so that the posterior-predictive check
judges the fit against the noise plus that bounded error (:func:`bounded_floor`).
"""

import numpy as np
from scipy.optimize import brentq

#: How the result's flag begins where the error was raised.
MODEL_ERROR_FLAG = "model error raised"

#: How the result's flag begins where the residuals need more than the ceiling.
MISFIT_FLAG = "misfit"

#: The ceiling of η, the per-bin sd of the instrument model's error as a fraction of the
#: signal. What the model is known to lack (the receiver's tail after each return, a
#: width the transmitted waveform does not carry) moves a return's energy between
#: neighbouring bins; it neither creates a return nor removes one, and the gain fits the
#: total. At η = ½ the ±2 sd band of a bin reaches from no signal at all to twice the
#: signal recorded: any larger error would let the model leave out a return the shot
#: recorded (or add one it did not), which is a misfit of the stand, not a reshaping by
#: the receiver. The same for every instrument, since it is a statement about returns,
#: not about one receiver.
MODEL_ERROR_CEILING = 0.5

#: The largest η searched for the residuals' need (beyond it: "more than any error").
LARGEST_FLOOR = 1e3

#: Absolute tolerance on η.
_TOLERANCE = 1e-6


def floor_for_residuals(residuals, base_variance, unit_variance, floor) -> float:
    """The smallest η ≥ ``floor`` with Σ r²/(v₀ + η²·u) ≤ the number of bins: what the
    residuals need, with no ceiling (:func:`bounded_floor` applies it).

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
        η; inf where no η up to :data:`LARGEST_FLOOR` fits them (residuals where the
        model's error cannot reach: bins without signal).
    """
    r2 = np.asarray(residuals, float) ** 2
    v0, u = np.asarray(base_variance, float), np.asarray(unit_variance, float)

    def excess(eta):
        return float(np.sum(r2 / (v0 + eta * eta * u))) - r2.size

    if not r2.size or excess(floor) <= 0.0:
        return float(floor)
    if excess(LARGEST_FLOOR) > 0.0:
        return float("inf")
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
        What the residuals need (:func:`floor_for_residuals`), no ceiling applied.
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


def bounded_floor(needed, least, ceiling=MODEL_ERROR_CEILING) -> float:
    """The η the likelihood takes: what the residuals need, at most the ceiling (and at
    least η₀, where η₀ itself is set above the ceiling).

    Parameters
    ----------
    needed : float
        η the residuals need (:func:`shot_floor`), inf for more than any.
    least : float
        η₀.
    ceiling : float
        The ceiling, :data:`MODEL_ERROR_CEILING` by default.

    Returns
    -------
    float
    """
    return float(max(least, min(needed, ceiling)))


def exceeds_ceiling(needed, least, ceiling=MODEL_ERROR_CEILING) -> bool:
    """Whether the residuals need more model error than the likelihood may take."""
    return bool(needed > bounded_floor(needed, least, ceiling) * (1.0 + 1e-9))


def describe_misfit(needed, ceiling=MODEL_ERROR_CEILING) -> str:
    """The result's flag where the residuals need a model error above the ceiling."""
    need = (
        "more than any model error"
        if not np.isfinite(needed)
        else (f"a model error of {100 * needed:.0f} % of the signal per bin")
    )
    return (
        f"{MISFIT_FLAG}: the residuals at the MAP need {need}, above the instrument "
        f"model's ceiling of {100 * ceiling:.0f} % (a receiver's reshaping of the returns "
        "cannot explain them: the stand model leaves out or adds a return; see the "
        "residual panel)"
    )


def describe_floor(floor, least) -> str:
    """The result's flag where the instrument model's error was raised above η₀."""
    return (
        f"{MODEL_ERROR_FLAG}: the residuals at the MAP exceed the noise and the simulated "
        f"discrepancy, so the instrument model's error is taken as {100 * floor:.0f} % of "
        f"the signal per bin instead of {100 * least:.0f} % (the model does not explain "
        "part of the waveform; see the residual panel)"
    )
