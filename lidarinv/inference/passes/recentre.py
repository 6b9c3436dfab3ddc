"""The simulated discrepancy re-centred on the optimum of the posterior it defines.

The realisations of :mod:`.realisations` are simulated about the pilot MAP, searched under
the per-bin ``observed`` discrepancy. That variance grows with the observed signal, so the
pilot may leave part of a return unexplained: on tall, closed canopies its MAP can drop a
sparse upper storey that the posterior under the simulated covariance then recovers, its
own optimum far above the pilot's. A fixed covariance leaves the walkers free to go there.
A covariance that follows each row's stand (:mod:`.likelihood.following`) is scaled
against the model signal at its centre and holds them near it, so it is centred instead on
the MAP of the posterior under the fixed covariance, with its realisations simulated again
about that MAP: one step of the iteration covariance → MAP → covariance.
"""

import time

import numpy as np

from ..sampling.start import find_map
from .realisations import SimulatedDiscrepancy, realisation_covariance


def recentred_simulation(posterior, instrument, rng, settings, sampler, simulation):
    """The realisations simulated again about the MAP of the posterior they define.

    Parameters
    ----------
    posterior : LogPosterior
        The shot's posterior under the covariance ``simulation`` made (with the instrument
        model's error), whose MAP is searched.
    instrument : forward.instrument.Instrument
        The shot's instrument (for the explicit engine).
    rng : numpy.random.Generator
    settings : RealisationSettings
    sampler : SamplerSettings
        The MAP search's settings (:func:`.sampling.start.find_map`).
    simulation : SimulatedDiscrepancy
        The simulation about the pilot MAP, whose optimum seeds the search beside the
        prior draws.

    Returns
    -------
    SimulatedDiscrepancy
        Simulated about the MAP found, with that search as its estimate; its seconds are
        both simulations' and the search's.
    """
    clock = time.perf_counter()
    pilot = np.atleast_2d(np.asarray(simulation.estimate.u, float))
    estimate = find_map(lambda u: posterior(u)[:, 0], posterior.space, rng, sampler, pilot)
    _, again = realisation_covariance(posterior, instrument, rng, settings, sampler, estimate)
    seconds = simulation.seconds + time.perf_counter() - clock
    return SimulatedDiscrepancy(seconds, estimate, again.residuals)
