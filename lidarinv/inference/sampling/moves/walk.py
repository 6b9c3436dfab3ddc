"""Emcee's walk move, its acceptance step batched (:mod:`.red_blue`)."""

import emcee

from .red_blue import BatchAcceptance


class WalkMove(BatchAcceptance, emcee.moves.WalkMove):
    """emcee's walk move, batched acceptance."""
