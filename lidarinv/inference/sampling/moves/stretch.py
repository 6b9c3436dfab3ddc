"""Emcee's stretch move, its acceptance step batched (:mod:`.red_blue`)."""

import emcee

from .red_blue import BatchAcceptance


class StretchMove(BatchAcceptance, emcee.moves.StretchMove):
    """emcee's stretch move, batched acceptance."""
