"""Ensemble moves: emcee's red-blue moves with a batched acceptance step, and two moves
for near-Gaussian posteriors, independence proposals from a Student t fitted to the
complementary half of the ensemble or to the chain's own early steps.

emcee's red-blue moves accept or reject the proposals of a half-ensemble walker by walker
in Python, one uniform draw each (about 0.1 ms a step for 64 walkers).
:class:`BatchAcceptance` draws the half's uniforms in one call, from the same stream in
the same order, and tests them together: the same chain, cheaper.

emcee's red-blue scheme updates one half of the walkers at a time, with proposals that may
depend on the other half only; each such proposal leaves the posterior invariant once its
Hastings factor q(x)/q(x') is applied. Here q is a multivariate Student t with the mean
and covariance of the other half. Where the posterior, in the sampler's coordinates, is
close to a Gaussian, a proposal from q is nearly a fresh draw and τ falls to a few steps;
the heavy tails keep walkers in the posterior's tails moving. Where it is not (several
modes, bent ridges), proposals are rejected and the mixture's other moves carry on.
The chain-t move fits its t once or a few times to the chain so far and then holds it:
a fixed q, so the same Hastings factor makes it exact too.
"""

import emcee
import numpy as np
from emcee.moves.red_blue import RedBlueMove
from emcee.state import State
from scipy.linalg import solve_triangular


class BatchAcceptance(RedBlueMove):
    """A red-blue move whose Metropolis–Hastings tests run on a whole half-ensemble."""

    def propose(self, model, state):
        n_walkers, ndim = state.coords.shape
        if n_walkers < 2 * ndim and not self.live_dangerously:
            raise RuntimeError(
                f"a red-blue move needs at least twice as many walkers as dimensions "
                f"({n_walkers} walkers, {ndim} dimensions)"
            )
        self.setup(state.coords)
        accepted = np.zeros(n_walkers, dtype=bool)
        group = np.arange(n_walkers) % self.nsplits
        if self.randomize_split:
            model.random.shuffle(group)
        for split in range(self.nsplits):
            moving = group == split
            halves = [state.coords[group == j] for j in range(self.nsplits)]
            others = halves[:split] + halves[split + 1 :]
            proposal, log_factor = self.get_proposal(halves[split], others, model.random)
            log_prob, blobs = model.compute_log_prob_fn(proposal)
            log_uniform = np.log(model.random.rand(int(moving.sum())))
            gain = log_factor + log_prob - state.log_prob[moving]
            accepted[moving] = gain > log_uniform  # NaN (−inf − −inf) is rejected
            state = self.update(
                state, State(proposal, log_prob=log_prob, blobs=blobs), accepted, moving
            )
        return state, accepted


class DEMove(BatchAcceptance, emcee.moves.DEMove):
    """emcee's differential-evolution move, batched acceptance."""


class DESnookerMove(BatchAcceptance, emcee.moves.DESnookerMove):
    """emcee's snooker move, batched acceptance."""


class StretchMove(BatchAcceptance, emcee.moves.StretchMove):
    """emcee's stretch move, batched acceptance."""


class WalkMove(BatchAcceptance, emcee.moves.WalkMove):
    """emcee's walk move, batched acceptance."""


class KDEMove(BatchAcceptance, emcee.moves.KDEMove):
    """emcee's KDE move, batched acceptance."""


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
    """

    def __init__(self, dof=8.0, scale=1.0, **kwargs):
        if not (dof > 0 and scale > 0):
            raise ValueError(f"dof and scale must be positive, got {dof} and {scale}")
        self.dof, self.scale = float(dof), float(scale)
        super().__init__(**kwargs)

    def get_proposal(self, s, c, random):
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


class ChainStudentMove(EnsembleStudentMove):
    """Independence proposals from a Student t fitted to the chain's own steps.

    The ensemble-t fits its t to the 32 walkers of the other half, a noisy covariance in
    10 dimensions; this one fits it to thousands of points of the chain so far. Until
    :meth:`fit` is called it is the ensemble-t move. :func:`.sampling.run_sampler` fits
    it at a few early steps and then freezes it: from the last fit on the proposal is one
    fixed distribution, so the chain is an exact MCMC chain, and the run discards the
    steps before that fit as burn-in.
    """

    def __init__(self, dof=8.0, scale=1.0, **kwargs):
        super().__init__(dof, scale, **kwargs)
        self.mean = self.chol = None

    def fit(self, points) -> bool:
        """Fit the t's mean and covariance to ``points`` (n, ndim); False (and no change)
        where their covariance is singular."""
        fitted = self._fit_t(np.asarray(points, float))
        if fitted is None:
            return False
        self.mean, self.chol = fitted
        return True

    def get_proposal(self, s, c, random):
        if self.mean is None:
            return super().get_proposal(s, c, random)
        return self._independence_proposal(s, self.mean, self.chol, random)


#: Move constructors by name.
MOVES = {
    "de": DEMove,
    "de-snooker": DESnookerMove,
    "stretch": StretchMove,
    "walk": WalkMove,
    "kde": KDEMove,
    "ensemble-t": EnsembleStudentMove,
    "chain-t": ChainStudentMove,
}
