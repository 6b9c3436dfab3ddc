"""The settings of an inversion that are not priors: one picklable record per run.

:class:`InversionSettings` controls a whole inversion (stored with its results), with
:class:`RealisationSettings` (the simulated discrepancy), ``SamplerSettings``
(:mod:`.sampling.sampler`) and :class:`forward.expected.ModelSettings` nested in it. A
priors file holds, beside the parameters' priors, tables that set some of these
(:data:`.priors_file.SETTINGS_TABLES`: ``[favd]``, ``[ground]``, ``[discrepancy]``).
"""

import math
from dataclasses import asdict, dataclass, field, replace

from forward.expected import ModelSettings
from forward.explicit import AccuracySettings
from lidarinv.observe.processing import ProcessingSettings

from .model.coordinates import DEFAULT_RIDGES
from .model.prior_table import DEFAULT_UNBOUNDED
from .model.tallest_stem import TALLEST_STEM_LATENTS
from .model.two_cohort import COHORT2
from .priors_file import read_priors_file, read_settings_tables
from .sampling.sampler import SamplerSettings

#: ``InversionSettings.cohorts`` for a stand model chosen per shot by evidence.
AUTO = "auto"

#: Height cohorts a stand may have (``InversionSettings.cohorts``), or :data:`AUTO`.
COHORT_COUNTS = (1, 2, AUTO)

#: ``InversionSettings.tallest_stem``: always, never, or :data:`AUTO` (with two storeys).
TALLEST_STEM_CHOICES = (True, False, AUTO)

#: The explicit engine's accuracy for the discrepancy (see ``RealisationSettings``): its
#: column grid at a 1 % L1 tolerance.
DISCREPANCY_QUADRATURE = AccuracySettings(tolerance=1e-2)


@dataclass(frozen=True)
class RealisationSettings:
    """How the discrepancy covariance is simulated.

    Parameters
    ----------
    count : int
        Explicit realisations K, one per parameter draw.
    shrinkage : float
        γ ∈ [0, 1], the weight of the diagonal in C = (1 − γ)·S + γ·diag(S).
    ball : float
        Scale of the Laplace ball the draws come from (as ``SamplerSettings.ball``).
    plot_diameters : float
        Side of the square plot each stand is realised on, in footprint diameters
        (1/e² diameters, 4σf); the footprint sits at its centre.
    accuracy : forward.explicit.AccuracySettings
        Accuracy of the explicit engine: its column grid at a 1 % L1 tolerance, cheaper
        than the default and closer to it than a coarse per-crown quadrature (the
        CHANGELOG gives the comparison).
    instrument_floor : float
        η₀, the per-bin discrepancy (a fraction of the shot's own signal, as the
        ``observed`` model) added to the diagonal of the simulated covariance: the error
        of the instrument model itself (the shape of the measured pulse, what widens a
        real ground return), which realisations drawn from the same model cannot hold.
        The least value: raised per shot where its residuals at the MAP call for more
        (:mod:`.model_error`). 0 for none.
    resamples : int
        Bootstrap resamples of the realisations with which the result measures how far
        another draw of them would move its quantiles (:mod:`.results.realisation_spread`,
        about 30 ms each); 0 for none.
    two_cohort_factor : int
        A two-cohort stand model simulates ``count`` times this many realisations
        (:meth:`for_cohorts`). Its discrepancy varies more: under the tall, closed
        two-storey canopies of the tall LVIS line, 256 realisations left the answer moving
        by 0.63 posterior sd (median of eight shots) over resamples of them, where GEDI
        shots moved by 0.01 and one-storey LVIS shots by about 0.3; the spread falls as
        one over the square root of the count.
    first_fraction : float
        The share of ``count`` simulated first; the rest only where these leave the
        answer moving by more than ``spread_target`` (:mod:`.passes.realisation_count`).
        1 simulates them all at once.
    spread_target : float
        The largest spread (posterior sd) of the Laplace ball's quantiles over bootstrap
        resamples of the first realisations at which they suffice. The post-sampling
        spread (``resamples``) is measured on the realisations used, whatever their count.
    """

    count: int = 256
    shrinkage: float = 0.3
    ball: float = 1.0
    plot_diameters: float = 3.0
    accuracy: AccuracySettings = DISCREPANCY_QUADRATURE
    instrument_floor: float = 0.1
    resamples: int = 16
    two_cohort_factor: int = 4
    first_fraction: float = 0.25
    spread_target: float = 0.1

    def __post_init__(self):
        if not self.instrument_floor >= 0.0:
            raise ValueError(f"instrument_floor must be ≥ 0, got {self.instrument_floor}")
        if self.count < 2:
            raise ValueError(f"the discrepancy needs at least 2 realisations, got {self.count}")
        if self.resamples == 1 or self.resamples < 0:
            raise ValueError(f"resamples must be 0 (none) or at least 2, got {self.resamples}")
        if not 0.0 <= self.shrinkage <= 1.0:
            raise ValueError(f"shrinkage must lie in [0, 1], got {self.shrinkage}")
        if not (self.ball > 0 and self.plot_diameters > 0):
            raise ValueError("ball and plot_diameters must be positive")
        if not 0.0 < self.first_fraction <= 1.0:
            raise ValueError(f"first_fraction must lie in (0, 1], got {self.first_fraction}")
        if not self.spread_target >= 0.0:
            raise ValueError(f"spread_target must be ≥ 0, got {self.spread_target}")
        if not (isinstance(self.two_cohort_factor, int) and self.two_cohort_factor >= 1):
            factor = self.two_cohort_factor
            raise ValueError(f"two_cohort_factor must be an integer ≥ 1, got {factor}")

    @property
    def first_count(self) -> int:
        """Realisations simulated first: ``first_fraction`` of ``count``, at least 2."""
        return min(self.count, max(2, math.ceil(self.first_fraction * self.count)))

    def for_cohorts(self, cohorts) -> "RealisationSettings":
        """These settings for a stand model of ``cohorts`` height cohorts: with two, the
        count multiplied by :attr:`two_cohort_factor`.

        Parameters
        ----------
        cohorts : int

        Returns
        -------
        RealisationSettings
        """
        if cohorts == 2 and self.two_cohort_factor > 1:
            return replace(self, count=self.count * self.two_cohort_factor)
        return self


@dataclass(frozen=True)
class InversionSettings:
    """Everything that controls one inversion (picklable; stored with the results).

    Parameters
    ----------
    instrument : str or None
        Instrument preset (``gedi``, ``lvis``, ``slicer``) overriding the one the file
        names; None for the file's. The bin height is taken from the observation.
    use_measured_pulse : bool
        Use the shot's transmit pulse when the file has one.
    processing : lidarinv.observe.ProcessingSettings or None
        How the shot is analysed (noise, signal extent, ground); None for the defaults of
        its instrument, the same as ``lidarinv metrics`` uses.
    correlated_noise : bool
        The likelihood takes the read noise as correlated from bin to bin: an AR(1) with
        the integrated autocorrelation time measured on the shot's signal-free bins
        (:mod:`.likelihood.ar_noise`); white noise overstates what the samples say. The
        noise mean and σ are then held at their estimates (see ``sample_noise``).
    marginalise_gain : bool
        Integrate the gain out of the likelihood analytically (:mod:`.likelihood.marginal`) where
        that is exact: no shot noise, a discrepancy fixed by the observation (not
        ``"model"``), no censored or saturated bins in the window, and the gain not
        fixed. The sampler then has one dimension fewer and no gain–ρv/ρg ridge; each
        posterior sample's gain is drawn from its conditional density. Otherwise, or if
        False, the gain is sampled.
    sample_noise : bool
        Sample the baseline and noise σ where the noise is taken as white (under
        correlated noise they are held); if False, hold them at the shot's estimates from
        the signal-free bins (two fewer free parameters; a GEDI window has hundreds of such
        bins, so the estimates are far tighter than anything else in the posterior). A
        priors-file entry for either still takes precedence.
    ground_prior_sd_m : float (m) or None
        Sd of the ground-elevation prior, a normal centred on the detected ground peak;
        None for one bin height, or the peak fit's uncertainty if larger. Low vegetation
        pulls the detected peak up, so a prior much narrower drags the posterior with it;
        one as wide as the pulse lets the ground trade off against the understory.
    margin_above_m, margin_below_m : float (m)
        Window beyond the detected signal; above, at least half the detected canopy
        height too. Signal-free bins above the canopy constrain the top height, and the
        top-height prior ends where the canopy would leave the window.
    shot_factor : float (DN)
        Shot-noise variance per unit signal, g.
    discrepancy : float
        η, the model-discrepancy sd as a fraction of the signal (the one random arrangement
        of trees in a footprint against the expected stand; ``studies/discrepancy.py``
        measures it on explicit realisations).
    discrepancy_model : str
        Which signal the discrepancy is a fraction of (:mod:`.likelihood.discrepancy`): ``model``,
        each row's model waveform, or ``observed``, the shot's own signal; or
        ``realisations``, a covariance between bins simulated from explicit stands around
        a pilot MAP found with ``observed`` (:mod:`.realisations`).
    realisations : RealisationSettings
        How the ``realisations`` covariance is simulated.
    tallest_stem : bool or str
        Condition the footprint on its tallest stem (within the 1/e² disc): latent
        parameters for its height, whose law the stand gives (of one storey or both),
        and its position (:class:`.model.stand.StandMapping`): one
        footprint rarely holds a stem in the upper tail of the stand's heights, and a
        Gaussian discrepancy, symmetric, cannot say so. The ``realisations`` covariance
        then holds what remains once each stand's own tallest stem is accounted for.
        ``"auto"`` (the default) conditions a two-storey stand model and not a one-storey
        one (:meth:`latent_stem`): under a sparse upper storey the discrepancy, simulated
        about the MAP's stand, can otherwise take the whole upper storey's return while
        the lower storey explains the rest. A priors file turns it on with a table for
        either latent (e.g. ``[tallest_stem_height]`` with ``free = true``, or a prior or
        a value).
    cohorts : int or str
        Height cohorts of the stand: 1, one truncated-normal height family; 2, a lower
        storey beside it (:mod:`.model.two_cohort`), for multi-layer canopies and
        emergents; ``"auto"`` (the default), the one with the lower BIC at its MAP
        (:func:`.passes.cohorts.choose_cohorts`; one MAP search more). A priors file turns 2 on
        with a table for a parameter of :data:`.model.two_cohort.COHORT2`.
    favd_range : (float, float) (m²/m³) or None
        Prior support of the implied foliage area volume density, a joint constraint on
        cover, PAI, heights and crown length (see :class:`.posterior.LogPosterior`); None
        for none (:data:`.model.parameters.PLAUSIBLE_FAVD_RANGE` is one choice).
    shape_pair : (str, str)
        Crown shapes mixed by ``cone_fraction``.
    ridges : tuple of str
        Ridge-straightening sampling coordinates (:mod:`.model.coordinates`; the posterior
        is the same, the chains mix faster), from
        :data:`.model.coordinates.RIDGE_COORDINATES`: :data:`.model.coordinates.DEFAULT_RIDGES`
        by default, ``()`` samples each parameter on its own.
    unbounded : str
        Map of the bounded priors to the real line the sampler moves on
        (:data:`.model.prior_table.UNBOUNDED_MAPS`): ``"logit"`` (logistic CDF, the default) or
        ``"probit"`` (normal CDF, lighter tails where a parameter piles against a bound).
        The posterior is the same; only the coordinates the ensemble moves in change.
    priors : dict
        Parameter overrides ``{name: {"prior": …, "fixed": …}}`` (see
        :func:`lidarinv.inference.priors_file.read_priors_file`).
    sampler : SamplerSettings
    model : forward.expected.ModelSettings
        Its ``backend`` also chooses the inversion's compiled or numpy paths (stand
        mapping, ridge maps).
    likelihood : str
        The likelihood, by name (:data:`.likelihood.LIKELIHOODS`): ``"gaussian"``.
    footprint_cover_draws : int
        Posterior samples given a draw of the footprint's own crown cover,
        ``footprint_cover`` (:func:`.realisations.footprint_cover`: an explicit stand each,
        a few milliseconds); 0 (the default) for none. The stand's ``cover`` is the
        expectation over footprints; this is what one footprint holds.
    """

    instrument: str | None = None
    use_measured_pulse: bool = True
    processing: ProcessingSettings | None = None
    correlated_noise: bool = True
    marginalise_gain: bool = True
    sample_noise: bool = True
    ground_prior_sd_m: float | None = None
    margin_above_m: float = 10.0
    margin_below_m: float = 5.0
    shot_factor: float = 0.0
    discrepancy: float = 0.2
    discrepancy_model: str = "realisations"
    favd_range: tuple | None = None
    shape_pair: tuple = ("cone", "ellipsoid")
    ridges: tuple = DEFAULT_RIDGES
    unbounded: str = DEFAULT_UNBOUNDED
    priors: dict = field(default_factory=dict)
    sampler: SamplerSettings = field(default_factory=SamplerSettings)
    model: ModelSettings = field(default_factory=ModelSettings)
    realisations: RealisationSettings = field(default_factory=RealisationSettings)
    tallest_stem: bool | str = AUTO
    cohorts: int | str = AUTO
    likelihood: str = "gaussian"
    footprint_cover_draws: int = 0

    def __post_init__(self):
        if self.cohorts not in COHORT_COUNTS:
            raise ValueError(f"cohorts must be one of {COHORT_COUNTS}, got {self.cohorts!r}")
        if self.tallest_stem not in TALLEST_STEM_CHOICES:
            raise ValueError(
                f"tallest_stem must be one of {TALLEST_STEM_CHOICES}, got {self.tallest_stem!r}"
            )
        if not self.footprint_cover_draws >= 0:
            raise ValueError(f"footprint_cover_draws must be ≥ 0, got {self.footprint_cover_draws}")

    def latent_stem(self, cohorts) -> bool:
        """Whether a stand model of ``cohorts`` height cohorts carries the tallest-stem
        latents: as set, or with ``tallest_stem="auto"``, where it has two.

        Parameters
        ----------
        cohorts : int or str
            1, 2, or ``"auto"`` (the larger model it may choose).

        Returns
        -------
        bool
        """
        if self.tallest_stem == AUTO:
            return cohorts != 1
        return bool(self.tallest_stem)

    @classmethod
    def from_priors_file(cls, path, **changes) -> "InversionSettings":
        """Settings with the priors and settings tables of a priors file.

        Parameters
        ----------
        path : path
            A TOML priors file: parameter tables (:func:`lidarinv.inference.priors_file.
            read_priors_file`) and the settings tables of :data:`.priors_file.SETTINGS_TABLES`.
        **changes
            Other settings; a file's table does not override one given here.

        Returns
        -------
        InversionSettings
        """
        priors = read_priors_file(path)
        tables = read_settings_tables(path)
        favd = tables.get("favd")
        if favd is not None:
            changes.setdefault("favd_range", favd["range"])
        ground = tables.get("ground")
        if ground is not None:
            changes.setdefault("ground_prior_sd_m", ground["prior_sd"])
        if set(TALLEST_STEM_LATENTS) & set(priors):  # a table for a latent turns them on
            changes.setdefault("tallest_stem", True)
        if set(COHORT2) & set(priors):  # a table for the lower storey turns it on
            changes.setdefault("cohorts", 2)
        discrepancy = tables.get("discrepancy", {})
        if "model" in discrepancy:
            changes.setdefault("discrepancy_model", discrepancy["model"])
        if "eta" in discrepancy:
            changes.setdefault("discrepancy", discrepancy["eta"])
        if "count" in discrepancy:
            changes.setdefault("realisations", RealisationSettings(count=discrepancy["count"]))
        return cls(priors=priors, **changes)

    def describe(self) -> dict:
        """The settings as a JSON-ready dict (stored with each result).

        Returns
        -------
        dict
        """
        nested = ("priors", "sampler", "model", "realisations", "processing")
        out = {k: v for k, v in self.__dict__.items() if k not in nested}
        out["processing"] = None if self.processing is None else asdict(self.processing)
        out["realisations"] = asdict(self.realisations)
        out["shape_pair"] = list(self.shape_pair)
        out["ridges"] = list(self.ridges)
        out["favd_range"] = None if self.favd_range is None else list(self.favd_range)
        out["sampler"] = {k: v for k, v in self.sampler.__dict__.items()}
        out["sampler"]["moves"] = [list(m) for m in self.sampler.moves]
        out["sampler"]["importance"] = asdict(self.sampler.importance)
        out["model"] = dict(self.model.__dict__)
        out["priors"] = {
            name: {
                "fixed": change.get("fixed"),
                "prior": change["prior"].describe() if "prior" in change else None,
            }
            for name, change in self.priors.items()
        }
        return out
