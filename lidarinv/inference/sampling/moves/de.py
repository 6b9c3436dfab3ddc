"""Emcee's differential-evolution move, its acceptance step batched (:mod:`.red_blue`)."""

import emcee

from .red_blue import BatchAcceptance


class DEMove(BatchAcceptance, emcee.moves.DEMove):
    """emcee's differential-evolution move, batched acceptance."""
