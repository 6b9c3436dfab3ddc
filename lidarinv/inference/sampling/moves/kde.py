"""Emcee's KDE move, its acceptance step batched (:mod:`.red_blue`)."""

import emcee

from .red_blue import BatchAcceptance


class KDEMove(BatchAcceptance, emcee.moves.KDEMove):
    """emcee's KDE move, batched acceptance."""
