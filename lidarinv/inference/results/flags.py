"""What a result's flags say: which warn that the answer may be wrong, and which only say
how it was reached.

Every flag an inversion raises begins with the words of its kind (:data:`FLAG_KINDS`).
A *warning* tells the user not to take the reported quantities as they stand: the model
misses part of the waveform, the footprint's canopy height contradicts its own waveform,
the ground may be another, or the run stopped at its step cap. The other kinds are notes:
how the answer was reached (the instrument model's error raised, a few slow walkers, the
realisations' seed), on many shots whose answers are right. A result without warnings is
what the validation pages call clean (``studies/real_inversion.py``: far-off answers
without a warning are the ones that pass as clean).
"""

from dataclasses import dataclass

from ...observe.terrain import TERRAIN_FLAG
from ..likelihood.gaussian import WHITE_NOISE_NOTE
from ..passes.ambiguity import COMPETING_GROUNDS_NOTE, GROUND_MODES_FLAG
from ..passes.cohorts import UNDECIDED_NOTE
from ..passes.hidden_ground import HIDDEN_GROUND_FLAG
from ..passes.model_error import MISFIT_FLAG, MODEL_ERROR_FLAG
from ..passes.realisations import PER_BIN_NOTE
from ..sampling.sampler import LOW_ACCEPTANCE_NOTE, NOT_CONVERGED_FLAG
from ..sampling.start import MAP_NOT_CONVERGED_NOTE
from .footprint import CANOPY_HEIGHT_FLAG, STAND_RH98_FLAG, UNSEEN_TOP_NOTE
from .realisation_spread import SEED_SPREAD_NOTE, SPREAD_NOT_MEASURED_NOTE


@dataclass(frozen=True)
class FlagKind:
    """One kind of flag.

    Attributes
    ----------
    warning : bool
        Whether it says the reported quantities may be wrong.
    meaning : str
        What it says, and what to take instead where there is something.
    """

    warning: bool
    meaning: str


#: Kinds of flag by the words they begin with.
FLAG_KINDS = {
    MISFIT_FLAG: FlagKind(
        True,
        "the model does not explain part of the waveform (the flag names the heights): "
        "quantities that depend on that part, e.g. a mid-storey or emergents two storeys "
        "cannot hold, are not the footprint's",
    ),
    CANOPY_HEIGHT_FLAG: FlagKind(
        True,
        "the footprint's tallest stem, drawn from the stand, stands well below the RH98 of "
        "the footprint's own waveform: take rh98_footprint as the canopy's top",
    ),
    STAND_RH98_FLAG: FlagKind(
        True,
        "the expected stand's RH98 lies well below that of the footprint's own waveform: "
        "the discrepancy carries the canopy's top, and the stand's quantities (rh98, "
        "cover, PAI, crown volume) describe a lower canopy: take rh98_footprint",
    ),
    GROUND_MODES_FLAG: FlagKind(
        True,
        "the posterior keeps two grounds (the flag gives their elevations and "
        "probabilities): every height above ground depends on which is right",
    ),
    COMPETING_GROUNDS_NOTE: FlagKind(
        False,
        "other grounds explained the waveform nearly as well at the start, and walkers "
        "started at each; the posterior's ground says which it kept",
    ),
    HIDDEN_GROUND_FLAG: FlagKind(
        True,
        "the lowest return may be the understory's over a ground too weak to show: the "
        "ground may lie lower and the heights be larger",
    ),
    TERRAIN_FLAG: FlagKind(
        True,
        "the ground departs from the terrain its neighbours along the track show",
    ),
    NOT_CONVERGED_FLAG: FlagKind(
        True,
        "the run stopped at its step cap before the stopping rule passed (the flag names "
        "what failed and the quantiles' Monte Carlo error)",
    ),
    MODEL_ERROR_FLAG: FlagKind(
        False,
        "the residuals at the MAP exceeded the noise and the simulated discrepancy, so the "
        "instrument model's error was raised: the intervals widen to hold them",
    ),
    UNDECIDED_NOTE: FlagKind(False, "one and two storeys explain the waveform about as well (BIC)"),
    LOW_ACCEPTANCE_NOTE: FlagKind(False, "some walkers accepted fewer than 5 % of their moves"),
    MAP_NOT_CONVERGED_NOTE: FlagKind(
        False, "the MAP search, which starts the walkers, ended at its iteration limit"
    ),
    UNSEEN_TOP_NOTE: FlagKind(
        False,
        "the footprint's tallest stem, drawn from the stand, stands well above the highest "
        "return that clears the noise floor: the stand model, not a detected return, sets "
        "the canopy height (in-family synthetic shots so flagged are calibrated)",
    ),
    SEED_SPREAD_NOTE: FlagKind(
        False,
        "another seed for the discrepancy's realisations would move a quantity's quantiles "
        "by more than the flag's share of a posterior sd",
    ),
    SPREAD_NOT_MEASURED_NOTE: FlagKind(False, "the realisations' bootstrap could not be run"),
    WHITE_NOISE_NOTE: FlagKind(
        False,
        "the window holds censored or saturated samples (or another obstacle the note "
        "gives), so the read noise's correlation was left out",
    ),
    PER_BIN_NOTE: FlagKind(
        False, "the window cannot carry the simulated covariance (the flag says why)"
    ),
}


def flag_kind(flag: str) -> str | None:
    """The key of :data:`FLAG_KINDS` that ``flag`` begins with (the longest, where more
    than one does); None for a flag of no known kind (e.g. one a caller appended)."""
    known = [kind for kind in FLAG_KINDS if flag.startswith(kind)]
    return max(known, key=len) if known else None


def is_warning(flag: str) -> bool:
    """Whether ``flag`` warns that the reported quantities may be wrong
    (:attr:`FlagKind.warning`); False for a flag of no known kind."""
    kind = flag_kind(flag)
    return kind is not None and FLAG_KINDS[kind].warning


def warnings_among(flags) -> list:
    """The ``flags`` that are warnings (:func:`is_warning`), in their order: none for a
    clean result."""
    return [flag for flag in flags if is_warning(flag)]
