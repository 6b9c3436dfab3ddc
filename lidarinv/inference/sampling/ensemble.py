"""The emcee sampler as lidarinv drives it: a batched log-probability, and a run's steps
taken in chunks that grow the chain's storage as the run lengthens."""

import emcee
import numpy as np

#: Steps of a run's first chunk; each later chunk is as long as the chain so far.
FIRST_CHUNK = 1000


class BatchedSampler(emcee.EnsembleSampler):
    """emcee's sampler for a log-probability that returns one (n, 1 + n_blobs) float array
    per batch (:class:`.posterior.LogPosterior`): the log-probability and the blobs are
    columns of it, not split walker by walker.

    References
    ----------
    Foreman-Mackey, D., Hogg, D. W., Lang, D. & Goodman, J. (2013). emcee: the MCMC hammer.
    *PASP* 125(925), 306–312.
    Goodman, J. & Weare, J. (2010). Ensemble samplers with affine invariance. *Commun. Appl.
    Math. Comput. Sci.* 5(1), 65–80.
    """

    def compute_log_prob(self, coords):
        """emcee's ``compute_log_prob`` for a log-probability that returns one (n, 1 + n_blobs)
        array per batch.

        Parameters
        ----------
        coords : array (n, ndim)

        Returns
        -------
        log_prob : array (n,)
        blobs : array (n, n_blobs), (n,) or None

        Raises
        ------
        ValueError
            For non-finite positions, a result of the wrong shape, or NaN log-probabilities.
        """
        coords = np.asarray(coords, float)
        if not np.all(np.isfinite(coords)):
            raise ValueError("a walker's position holds NaN or infinite values")
        values = np.asarray(self.log_prob_fn(coords), float)
        if values.ndim != 2 or values.shape[0] != coords.shape[0]:
            raise ValueError(
                f"the log-probability must return ({coords.shape[0]}, 1 + blobs) values, "
                f"got shape {values.shape}"
            )
        log_prob = values[:, 0]
        if np.any(np.isnan(log_prob)):
            raise ValueError("the log-probability returned NaN")
        blobs = values[:, 1:]
        if blobs.shape[1] < 2:  # as emcee: a single blob squeezed, none as None
            blobs = blobs[:, 0] if blobs.shape[1] else None
        return log_prob, blobs


def sample_in_chunks(sampler, state, steps, first=None):
    """Yield the states of ``steps`` steps of ``sampler`` from ``state``, as
    ``sampler.sample`` does, but through chunks of ``first`` steps (default
    :data:`FIRST_CHUNK`), then as many steps as the chain already holds.

    emcee grows its backend by all the steps asked of one ``sample`` call before taking
    the first; runs mostly stop far below their step cap. In chunks the storage stays
    within twice the steps taken, in a few grows. The chain is the same: each chunk
    resumes from the last state with its random state, the walkers not re-checked.

    Parameters
    ----------
    sampler : emcee.EnsembleSampler
    state : State or array (n_walkers, ndim)
    steps : int
    first : int, optional

    Yields
    ------
    emcee.State
        The state after each step.
    """
    first = FIRST_CHUNK if first is None else int(first)
    taken = 0
    while taken < steps:
        chunk = min(steps - taken, max(first, sampler.iteration))
        # the first chunk checks the walkers as one call would; the later ones resume
        states = sampler.sample(state, iterations=chunk, skip_initial_state_check=taken > 0)
        for state in states:
            yield state
        taken += chunk
