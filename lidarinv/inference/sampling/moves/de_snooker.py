"""Emcee's snooker move, its acceptance step batched (:mod:`.red_blue`)."""

import emcee

from .red_blue import BatchAcceptance


class DESnookerMove(BatchAcceptance, emcee.moves.DESnookerMove):
    """emcee's snooker move, batched acceptance."""
