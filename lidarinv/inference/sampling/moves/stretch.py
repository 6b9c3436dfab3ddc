"""Emcee's stretch move, its acceptance step batched (:mod:`.red_blue`)."""

import emcee

from .red_blue import BatchAcceptance


class StretchMove(BatchAcceptance, emcee.moves.StretchMove):
    """emcee's stretch move, batched acceptance.

    References
    ----------
    Goodman, J. & Weare, J. (2010). Ensemble samplers with affine invariance. *Commun. Appl.
    Math. Comput. Sci.* 5(1), 65–80 (the stretch move).
    Foreman-Mackey, D., Hogg, D. W., Lang, D. & Goodman, J. (2013). emcee: the MCMC hammer.
    *PASP* 125(925), 306–312.
    """
