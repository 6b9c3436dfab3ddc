"""Ensemble moves, one per module as in emcee's ``moves/``: emcee's red-blue moves with a
batched acceptance step (:mod:`.red_blue`), and two independence moves for
near-Gaussian posteriors, from a Student t fitted to the other half of the ensemble
(:mod:`.ensemble_t`) or to the chain's own early steps (:mod:`.chain_t`, with its
adaptation)."""

from .chain_t import ChainStudentMove
from .de import DEMove
from .de_snooker import DESnookerMove
from .ensemble_t import EnsembleStudentMove
from .kde import KDEMove
from .red_blue import BatchAcceptance
from .stretch import StretchMove
from .walk import WalkMove

#: Move constructors by name (``SamplerSettings.moves``).
MOVES = {
    "de": DEMove,
    "de-snooker": DESnookerMove,
    "stretch": StretchMove,
    "walk": WalkMove,
    "kde": KDEMove,
    "ensemble-t": EnsembleStudentMove,
    "chain-t": ChainStudentMove,
}

__all__ = [
    "MOVES",
    "BatchAcceptance",
    "ChainStudentMove",
    "DEMove",
    "DESnookerMove",
    "EnsembleStudentMove",
    "KDEMove",
    "StretchMove",
    "WalkMove",
]
