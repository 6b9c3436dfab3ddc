"""emcee's red-blue moves with a batched acceptance step.

emcee's red-blue moves accept or reject the proposals of a half-ensemble walker by walker
in Python, one uniform draw each. :class:`BatchAcceptance` draws the half's uniforms in
one call, from the same stream in the same order, and tests them together: the same
chain, cheaper.
"""

import numpy as np
from emcee.moves.red_blue import RedBlueMove
from emcee.state import State


class BatchAcceptance(RedBlueMove):
    """A red-blue move whose Metropolis–Hastings tests run on a whole half-ensemble.

    References
    ----------
    Foreman-Mackey, D., Hogg, D. W., Lang, D. & Goodman, J. (2013). emcee: the MCMC hammer.
    *PASP* 125(925), 306–312 (the red-blue split of the ensemble that moves each half in
    parallel).
    Goodman, J. & Weare, J. (2010). Ensemble samplers with affine invariance. *Commun. Appl.
    Math. Comput. Sci.* 5(1), 65–80.
    """

    def propose(self, model, state):
        """emcee's ``Move.propose``: each half-ensemble proposed and tested in one batch.

        Parameters
        ----------
        model : emcee.model.Model
        state : emcee.State

        Returns
        -------
        state : emcee.State
        accepted : array of bool (n_walkers,)
        """
        n_walkers, ndim = state.coords.shape
        if n_walkers < 2 * ndim and not self.live_dangerously:
            raise RuntimeError(
                f"a red-blue move needs at least twice as many walkers as dimensions "
                f"({n_walkers} walkers, {ndim} dimensions)"
            )
        self.setup(state.coords)
        accepted = np.zeros(n_walkers, dtype=bool)
        splits = self.splits()
        group = np.arange(n_walkers) % splits
        if self.randomize_split:
            model.random.shuffle(group)
        for split in range(splits):
            moving = group == split
            halves = [state.coords[group == j] for j in range(splits)]
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

    def splits(self) -> int:
        """Groups moved in turn: emcee's ``nsplits``; a move whose proposal does not
        depend on the other walkers may move them all in one batch."""
        return self.nsplits
