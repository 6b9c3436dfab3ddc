"""Emcee's snooker move, its acceptance step batched (:mod:`.red_blue`)."""

import emcee

from .red_blue import BatchAcceptance


class DESnookerMove(BatchAcceptance, emcee.moves.DESnookerMove):
    """emcee's snooker move, batched acceptance.

    References
    ----------
    ter Braak, C. J. F. & Vrugt, J. A. (2008). Differential Evolution Markov Chain with
    snooker updater and fewer chains. *Stat. Comput.* 18(4), 435–446.
    """
