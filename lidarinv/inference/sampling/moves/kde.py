"""Emcee's KDE move, its acceptance step batched (:mod:`.red_blue`)."""

import emcee

from .red_blue import BatchAcceptance


class KDEMove(BatchAcceptance, emcee.moves.KDEMove):
    """emcee's KDE move, batched acceptance.

    References
    ----------
    Farr, B. & Farr, W. M. (2015). kombine: a kernel-density-based, embarrassingly parallel
    ensemble sampler. https://github.com/bfarr/kombine (the kernel-density proposal that
    emcee's KDE move simplifies).
    """
