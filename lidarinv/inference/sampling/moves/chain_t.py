"""The chain-t move, independence proposals from a t fitted to the chain's own steps, and
its adaptation: when to fit it, and its last fit kept with an HDF5 chain so that a
resumed run makes it again.

A move is adaptive if it has a ``fit(points) -> bool`` method.
:func:`..sampler.run_sampler` fits the adaptive moves at a few early steps. Between two
fits every proposal is fixed (one fixed q, so the Hastings factor makes that stretch an
exact MCMC chain that leaves the posterior invariant), and each fit only changes q for
the steps after it. Burn-in (a multiple of τ) reaches at least the first fit; steps
between later fits are kept.
"""

import emcee
import numpy as np

from .ensemble_t import EnsembleStudentMove


class ChainStudentMove(EnsembleStudentMove):
    """Independence proposals from a Student t fitted to the chain's own steps.

    The ensemble-t fits its t to the 32 walkers of the other half, a noisy covariance in
    10 dimensions; this one fits it to thousands of points of the chain so far. Until
    :meth:`fit` is called it is the ensemble-t move. :func:`..sampler.run_sampler` fits
    it at a few early steps and then freezes it: between fits the proposal is one fixed
    distribution, so each stretch is an exact MCMC chain.

    References
    ----------
    Tierney, L. (1994). Markov chains for exploring posterior distributions. *Ann. Statist.*
    22(4), 1701–1728 (independence proposals and their Hastings factor).
    Goodman, J. & Weare, J. (2010). Ensemble samplers with affine invariance. *Commun. Appl.
    Math. Comput. Sci.* 5(1), 65–80 (the replacement move).
    """

    def __init__(self, dof=8.0, scale=1.0, **kwargs):
        super().__init__(dof, scale, **kwargs)
        self.mean = self.chol = None

    def fit(self, points) -> bool:
        """Fit the t's mean and covariance to points of the chain.

        Parameters
        ----------
        points : array (n, ndim)

        Returns
        -------
        bool
            False (and no change) where their covariance is singular.
        """
        fitted = self._fit_t(np.asarray(points, float))
        if fitted is None:
            return False
        self.mean, self.chol = fitted
        return True

    def splits(self) -> int:
        """Once fitted, the proposal is one fixed t for every walker: all of them move in
        one batch (one log-probability call a step instead of two)."""
        return self.nsplits if self.mean is None else 1

    def get_proposal(self, s, c, random):
        """emcee's ``RedBlueMove.get_proposal``: from the fitted t, or the ensemble-t's until the
        first fit.

        Parameters
        ----------
        s : array (k, ndim)
        c : list of arrays
        random : numpy.random.RandomState

        Returns
        -------
        proposal : array (k, ndim)
        log_factor : array (k,)
        """
        if self.mean is None:
            return super().get_proposal(s, c, random)
        return self._independence_proposal(s, self.mean, self.chol, random)


#: HDF5 attribute of a chain's group: the step of the adaptive moves' last fit.
LAST_FIT_ATTRIBUTE = "lidarinv_last_fit"


def fit_moves(sampler, adaptive, step=None) -> bool:
    """Fit the adaptive moves to the second half of the chain's first ``step`` steps.

    Parameters
    ----------
    sampler : emcee.EnsembleSampler
    adaptive : list
        Moves with a ``fit(points) -> bool`` method.
    step : int, optional
        Default: all steps so far.

    Returns
    -------
    bool
        False where there are none or a fit fails (a move then keeps its former fit).
    """
    step = sampler.iteration if step is None else step
    chain = sampler.get_chain()
    points = chain[step // 2 : step].reshape(-1, chain.shape[2])
    return bool(adaptive) and all([move.fit(points) for move in adaptive])


def worth_refitting(step, tau, fit_fraction, tau_multiple, max_steps) -> bool:
    """Whether to fit the adaptive moves again at a step.

    Parameters
    ----------
    step : int
    tau : array (steps)
        The latest τ.
    fit_fraction, tau_multiple : float
    max_steps : int

    Returns
    -------
    bool
        Only while the run, ``tau_multiple`` times the latest τ but at most ``max_steps``,
        is expected to last at least ``step / fit_fraction`` steps (a short run is left
        with the proposal it has); always while τ is unknown, within that cap.
    """
    expected = tau_multiple * np.max(tau) if np.all(np.isfinite(tau)) else np.inf
    return fit_fraction * min(expected, max_steps) >= step


def record_fit(backend, step):
    """Keep the last fit's step with an HDF5 chain (:data:`LAST_FIT_ATTRIBUTE`).

    Parameters
    ----------
    backend : emcee.backends.Backend
    step : int
    """
    if isinstance(backend, emcee.backends.HDFBackend):
        with backend.open("a") as handle:
            handle[backend.name].attrs[LAST_FIT_ATTRIBUTE] = step


def refit_on_resume(sampler, adaptive, backend) -> int:
    """On resuming, the adaptive moves' last fit, made again from the stored steps.

    Parameters
    ----------
    sampler : emcee.EnsembleSampler
    adaptive : list
    backend : emcee.backends.Backend

    Returns
    -------
    int
        The fit's step (the same points, the same fit); 0 if none.
    """
    if not adaptive or not isinstance(backend, emcee.backends.HDFBackend):
        return 0
    with backend.open("r") as handle:
        step = int(handle[backend.name].attrs.get(LAST_FIT_ATTRIBUTE, 0))
    return step if step and fit_moves(sampler, adaptive, step) else 0
