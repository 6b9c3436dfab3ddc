"""How many explicit realisations a shot's discrepancy needs (:class:`EnoughRealisations`).

The simulated covariance (:mod:`.realisations`) is an estimate from K random stands, and
the answer moves with them by a spread that falls as 1/√K. Where the shot's own noise and
the instrument model's error outweigh the simulated discrepancy, a few stands already
leave that spread far below the sampler's Monte Carlo error, and the rest cost time for
nothing (a GEDI shot's 256 stands took about a second, a third of its preparation).
The first share of the realisations (``RealisationSettings.first_fraction``) is
simulated, and the spread they leave is measured before sampling as it is after it
(:func:`..results.realisation_spread.realisation_spread`): :data:`RESAMPLES` bootstrap
resamples of the realisations reweight draws of the posterior, here the Laplace ball
about the pilot MAP that the realisations were drawn from, under the instrument model's
least error. Where that spread exceeds ``RealisationSettings.spread_target``, the rest
are simulated.
"""

import numpy as np

from ..results.realisation_spread import DiscrepancyDraws, realisation_spread
from ..results.reported import reported_monitor

#: Bootstrap resamples of the first realisations (the default of the spread measured after
#: sampling, ``RealisationSettings.resamples``, on which this does not depend).
RESAMPLES = 16


class EnoughRealisations:
    """Whether the first realisations of a shot suffice (the ``enough`` of
    :func:`.realisations.realisation_covariance`).

    Parameters
    ----------
    pilot : LogPosterior
        The posterior the realisations are simulated for.
    settings : RealisationSettings
    diagonal : array (bins,) (DN²)
        The instrument model's least error, added to the simulated covariance (its sized
        error is at least this: a larger one weighs the realisations less, and their
        spread with them).
    rng : numpy.random.Generator
        For the bootstrap resamples.

    Attributes
    ----------
    spread : float or None
        The largest spread measured (posterior sd of the Laplace ball), once asked.
    """

    def __init__(self, pilot, settings, diagonal, rng):
        self.pilot, self.settings, self.diagonal, self.rng = pilot, settings, diagonal, rng
        self.spread = None

    def __call__(self, draws, residuals) -> bool:
        """Whether ``residuals`` (k, bins) (DN) suffice, judged on ``draws`` (n, ndim), the
        Laplace ball in the sampler's unbounded coordinates."""
        self.spread = laplace_spread(
            self.pilot, draws, residuals, self.settings, self.diagonal, self.rng
        )
        return bool(self.spread <= self.settings.spread_target)

    def describe(self, simulated: int) -> dict:
        """The count asked, the count simulated and the spread that decided it."""
        count = self.settings.count
        return {"asked": count, "simulated": int(simulated), "first_spread": self.spread}


def laplace_spread(pilot, draws, residuals, settings, diagonal, rng) -> float:
    """The largest spread of the reported quantities' 5/50/95 % quantiles over bootstrap
    resamples of ``residuals``, in posterior sd, with the Laplace ball ``draws`` standing
    for the posterior.

    Parameters
    ----------
    pilot : LogPosterior
    draws : array (n, ndim)
        Unbounded coordinates.
    residuals : array (k, bins) (DN)
    settings : RealisationSettings
        Its ``shrinkage``.
    diagonal : array (bins,) (DN²)
    rng : numpy.random.Generator

    Returns
    -------
    float
        inf where no quantity's spread could be measured (the rest are then simulated).
    """
    simulated = DiscrepancyDraws(residuals, settings.shrinkage, diagonal)
    likelihood = pilot.likelihood.with_fixed_discrepancy(simulated.covariance())
    posterior = pilot.with_likelihood(likelihood)
    rows = posterior(draws)
    monitor = reported_monitor(posterior.space, posterior.blob_names)
    columns = {name: v[0] for name, v in monitor(draws[None], rows[None, :, 1:]).items()}
    x, _ = posterior.space.from_unbounded(draws)
    found = realisation_spread(posterior, simulated, x, columns, rng, RESAMPLES, x.shape[0])
    spreads = [v for v in found.spread.values() if np.isfinite(v)]
    return float(max(spreads)) if spreads else np.inf
