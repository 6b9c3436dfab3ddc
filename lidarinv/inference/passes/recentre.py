"""The centre of a following discrepancy: the pilot MAP, or the optimum of the posterior
its simulation defines, whichever its own covariance rates higher.

The realisations of :mod:`.realisations` are simulated about the pilot MAP, searched under
the per-bin ``observed`` discrepancy. That variance grows with the observed signal, so the
pilot may leave part of a return unexplained: on tall, closed canopies its MAP can drop a
sparse upper storey. A covariance that follows each row's stand
(:mod:`.likelihood.following`) is scaled against the model signal at its centre and
holds the walkers near it, so its centre decides what the sampler sees.

The covariance C° simulated about the pilot has its own optimum, which may stand far from
the pilot: where the pilot dropped an upper storey, C°'s optimum often has it, but where
the pilot had it, C°'s spread at that storey may let its optimum leave that storey's return
to the discrepancy. Simulated again about that optimum, its covariance C¹ then finds the
return unexplained. Each candidate centre c is therefore judged under the covariance
simulated about it: the higher optimum of the two posteriors, max_θ log p(θ | y, C_c) (an
L-BFGS-B run from c, :func:`.sampling.start.local_optimum`), chooses the centre, a profile
likelihood of the centre over two candidates.
"""

import time
from dataclasses import dataclass, replace

import numpy as np

from ..sampling.start import find_map, local_optimum
from .realisations import SimulatedDiscrepancy, realisation_covariance

#: The candidate centres, by name, in the order they are simulated.
CENTRES = ("pilot", "refound")


@dataclass(frozen=True)
class Recentring:
    """The centre chosen for a following discrepancy.

    Attributes
    ----------
    simulation : SimulatedDiscrepancy
        The realisations about the chosen centre, which is its estimate; its seconds
        are all the simulations' and searches'.
    chosen : str
        One of :data:`CENTRES`.
    optima : dict of str → float
        Each centre's max_θ log p(θ | y, C_c), the log-posterior under the covariance
        simulated about it.
    """

    simulation: SimulatedDiscrepancy
    chosen: str
    optima: dict

    def describe(self) -> dict:
        """For the result's diagnostics."""
        return {"chosen": self.chosen, "optima": dict(self.optima)}


def recentre(posterior, instrument, rng, settings, sampler, simulation, diagonal) -> Recentring:
    """Simulate about the optimum of the posterior under the pilot's covariance, and keep
    the centre whose own covariance rates it higher.

    Parameters
    ----------
    posterior : LogPosterior
        The shot's posterior under the covariance ``simulation`` made, with the
        instrument model's error ``diagonal``.
    instrument : forward.instrument.Instrument
        The shot's instrument (for the explicit engine).
    rng : numpy.random.Generator
    settings : RealisationSettings
    sampler : SamplerSettings
        The MAP search's settings (:func:`.sampling.start.find_map`).
    simulation : SimulatedDiscrepancy
        The simulation about the pilot MAP, whose optimum seeds the search beside the
        prior draws.
    diagonal : array (bins,) (DN²)
        The instrument model's error, added to every simulated covariance.

    Returns
    -------
    Recentring
    """
    clock = time.perf_counter()
    pilot = np.asarray(simulation.estimate.u, float)
    log_prob = lambda u: posterior(u)[:, 0]  # noqa: E731
    estimate = find_map(log_prob, posterior.space, rng, sampler, pilot[None, :])
    same_count = replace(settings, count=simulation.residuals.shape[0])  # judged alike
    covariance, again = realisation_covariance(
        posterior, instrument, rng, same_count, sampler, estimate
    )
    likelihood = posterior.likelihood.with_fixed_discrepancy(covariance + np.diag(diagonal))
    about_refound = posterior.with_likelihood(likelihood)
    optima = {
        "pilot": local_optimum(log_prob, pilot),
        "refound": local_optimum(lambda u: about_refound(u)[:, 0], estimate.u),
    }
    chosen = "refound" if optima["refound"] > optima["pilot"] else "pilot"
    seconds = simulation.seconds + time.perf_counter() - clock
    kept = again if chosen == "refound" else simulation
    return Recentring(SimulatedDiscrepancy(seconds, kept.estimate, kept.residuals), chosen, optima)
