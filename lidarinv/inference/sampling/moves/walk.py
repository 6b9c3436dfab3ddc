"""Emcee's walk move, its acceptance step batched (:mod:`.red_blue`)."""

import emcee

from .red_blue import BatchAcceptance


class WalkMove(BatchAcceptance, emcee.moves.WalkMove):
    """emcee's walk move, batched acceptance.

    References
    ----------
    Goodman, J. & Weare, J. (2010). Ensemble samplers with affine invariance. *Commun. Appl.
    Math. Comput. Sci.* 5(1), 65–80 (the walk move).
    """
