"""Emcee's differential-evolution move, its acceptance step batched (:mod:`.red_blue`)."""

import emcee

from .red_blue import BatchAcceptance


class DEMove(BatchAcceptance, emcee.moves.DEMove):
    """emcee's differential-evolution move, batched acceptance.

    References
    ----------
    ter Braak, C. J. F. (2006). A Markov chain Monte Carlo version of the genetic algorithm
    Differential Evolution: easy Bayesian computing for real parameter spaces. *Stat.
    Comput.* 16(3), 239–249.
    Nelson, B., Ford, E. B. & Payne, M. J. (2014). Run DMC: an efficient, parallel code for
    analyzing radial velocity observations using N-body integrations and differential
    evolution Markov chain Monte Carlo. *Astrophys. J. Suppl.* 210(1), 11 (the stretch
    factor's distribution that emcee follows).
    """
