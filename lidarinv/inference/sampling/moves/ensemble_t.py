"""Independence proposals from a Student t fitted to the complementary half of the ensemble.

emcee's red-blue scheme updates one half of the walkers at a time, with proposals that may
depend on the other half only; each such proposal leaves the posterior invariant once its
Hastings factor q(x)/q(x') is applied. Here q is a multivariate Student t with the mean
and covariance of the other half. Where the posterior, in the sampler's coordinates, is
close to a Gaussian, a proposal from q is nearly a fresh draw and τ falls to a few steps;
the heavy tails keep walkers in the posterior's tails moving. Where it is not (several
modes, bent ridges), proposals are rejected and the mixture's other moves carry on.
"""

import numpy as np
from scipy.linalg import solve_triangular

from .red_blue import BatchAcceptance


class EnsembleStudentMove(BatchAcceptance):
    """Independence proposals from a Student t fitted to the complementary walkers.

    Parameters
    ----------
    dof : float
        Degrees of freedom ν of the t (ν → ∞ gives a Gaussian).
    scale : float
        Factor on the fitted covariance's square root.

    Notes
    -----
    The complementary half must hold more walkers than dimensions for a full-rank
    covariance; where it does not, or the covariance is singular, the move leaves the
    walkers where they are.

    References
    ----------
    Goodman, J. & Weare, J. (2010). Ensemble samplers with affine invariance. *Commun. Appl.
    Math. Comput. Sci.* 5(1), 65–80 (the replacement move: an independent draw from a
    density fitted to the complementary walkers; here a Student t).
    Tierney, L. (1994). Markov chains for exploring posterior distributions. *Ann. Statist.*
    22(4), 1701–1728 (independence proposals and their Hastings factor).
    """

    def __init__(self, dof=8.0, scale=1.0, **kwargs):
        if not (dof > 0 and scale > 0):
            raise ValueError(f"dof and scale must be positive, got {dof} and {scale}")
        self.dof, self.scale = float(dof), float(scale)
        super().__init__(**kwargs)

    def get_proposal(self, s, c, random):
        """emcee's ``RedBlueMove.get_proposal``: independence proposals from the t of the others.

        Parameters
        ----------
        s : array (k, ndim)
            The walkers moving.
        c : list of arrays
            The complementary walkers.
        random : numpy.random.RandomState

        Returns
        -------
        proposal : array (k, ndim)
        log_factor : array (k,)
            log q(s) − log q(proposal), the Hastings factors.
        """
        fitted = self._fit_t(np.concatenate(c, axis=0))
        if fitted is None:
            return s.copy(), np.zeros(len(s))
        return self._independence_proposal(s, *fitted, random)

    def _fit_t(self, points):
        """The t's mean and scale (lower Cholesky factor of the covariance times
        ``scale``) fitted to ``points`` (n, ndim); None where they cannot span the
        dimensions or their covariance is singular."""
        n, ndim = points.shape
        if n <= ndim:
            return None
        mean = points.mean(axis=0)
        centred = points - mean
        try:
            return mean, np.linalg.cholesky(centred.T @ centred / (n - 1)) * self.scale
        except np.linalg.LinAlgError:
            return None

    def _independence_proposal(self, s, mean, chol, random):
        """Draws from the t of ``mean`` and scale ``chol`` (lower Cholesky factor) for
        the walkers ``s``, and the log Hastings factors log q(s) − log q(proposal)."""
        ndim = mean.size
        normal = random.standard_normal((len(s), ndim))
        mixing = random.chisquare(self.dof, len(s)) / self.dof
        proposal = mean + (normal / np.sqrt(mixing)[:, None]) @ chol.T
        # the proposals' whitened distances are known: |normal|² / mixing
        whitened = solve_triangular(chol, (s - mean).T, lower=True, check_finite=False)
        log_q_current = self._log_density(np.sum(whitened**2, axis=0), ndim)
        log_q_proposal = self._log_density(np.sum(normal**2, axis=1) / mixing, ndim)
        return proposal, log_q_current - log_q_proposal

    def _log_density(self, distance, ndim):
        """log q up to a constant (the same for every point), from the squared whitened
        distance to the mean."""
        return -0.5 * (self.dof + ndim) * np.log1p(distance / self.dof)
