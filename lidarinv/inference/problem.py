"""Turn one observation into an inversion problem: window, priors, model and posterior."""

from dataclasses import asdict, dataclass, field

import numpy as np

from forward.expected import ExpectedWaveformModel, ModelSettings
from lidarinv.observe.analyse import analyse
from lidarinv.observe.instrument import shot_instrument
from lidarinv.observe.observation import Observation
from lidarinv.observe.processing import ProcessingSettings

from .coordinates import DEFAULT_RIDGES
from .discrepancy import DISCREPANCY_MODELS
from .likelihood import WindowData
from .marginal import gain_marginal_obstacle
from .parameters import DEFAULT_STRUCTURE_PRIORS, default_space, read_priors_file
from .posterior import LogPosterior
from .priors import DEFAULT_UNBOUNDED, LogUniform, TruncatedNormal, Uniform
from .realisations import RealisationSettings
from .sampling import SamplerSettings
from .stand_mapping import TALLEST_STEM_LATENTS, StandMapping, default_template


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
    marginalise_gain : bool
        Integrate the gain out of the likelihood analytically (:mod:`.marginal`) where
        that is exact: no shot noise, a discrepancy fixed by the observation (not
        ``"model"``), no censored or saturated bins in the window, and the gain not
        fixed. The sampler then has one dimension fewer and no gain–ρv/ρg ridge; each
        posterior sample's gain is drawn from its conditional density. Otherwise, or if
        False, the gain is sampled.
    sample_noise : bool
        Sample the baseline and noise σ; if False, hold them at the shot's estimates from
        the signal-free bins (two fewer free parameters; a GEDI window has hundreds of such
        bins, so the estimates are far tighter than anything else in the posterior). A
        priors-file entry for either still takes precedence.
    ground_prior_sd_m : float (m) or None
        Sd of the ground-elevation prior, a normal centred on the detected ground peak;
        None for one bin height, or the peak fit's uncertainty if larger. Low vegetation
        pulls the detected peak up (by +0.11 m on average, RMS error 0.14 m, in the
        recovery study's explicit GEDI stands), so a prior as narrow as half a bin, the
        former width, dragged the posterior with it (errors correlated at 0.95) and left
        it under-covered; one as wide as the pulse (σ 0.96 m) let the ground trade off
        against the understory (README, "Ground prior").
    margin_above_m, margin_below_m : float (m)
        Window beyond the detected signal; above, at least half the detected canopy
        height too. Signal-free bins above the canopy constrain the top height, and the
        top-height prior ends where the canopy would leave the window.
    shot_factor : float (DN)
        Shot-noise variance per unit signal, g.
    discrepancy : float
        η, the model-discrepancy sd as a fraction of the signal (the one random arrangement
        of trees in a footprint against the expected stand); explicit realisations of
        GEDI footprints spread by a median 0.22–0.34 per crown bin around the expected
        waveform (``studies/discrepancy.py``), and 0.2 recovered best in the study.
    discrepancy_model : str
        Which signal the discrepancy is a fraction of (:mod:`.discrepancy`): ``model``,
        each row's model waveform, or ``observed``, the shot's own signal; or
        ``realisations``, a covariance between bins simulated from explicit stands around
        a pilot MAP found with ``observed`` (:mod:`.realisations`).
    realisations : RealisationSettings
        How the ``realisations`` covariance is simulated.
    tallest_stem : bool
        Condition the footprint on its tallest stem (within the 1/e² disc): latent
        parameters for its height, whose law the stand gives, and its position
        (:class:`.stand_mapping.StandMapping`): one
        footprint rarely holds a stem in the upper tail of the stand's heights, and a
        Gaussian discrepancy, symmetric, cannot say so. The ``realisations`` covariance
        then holds what remains once each stand's own tallest stem is accounted for. A
        priors file turns it on with a table for either latent (e.g.
        ``[tallest_stem_height]`` with ``free = true``, or a prior or a value).
    favd_range : (float, float) (m²/m³) or None
        Prior support of the implied foliage area volume density, a joint constraint on
        cover, PAI, heights and crown length (see :class:`.posterior.LogPosterior`); None
        for none. ``parameters.PLAUSIBLE_FAVD_RANGE`` narrows the PAI posterior but, in
        the recovery study, leaves the cover intervals too narrow (README).
    shape_pair : (str, str)
        Crown shapes mixed by ``cone_fraction``.
    ridges : tuple of str
        Ridge-straightening sampling coordinates (:mod:`.coordinates`; the posterior is
        the same, the chains mix faster): all three of
        :data:`.coordinates.RIDGE_COORDINATES` by default, ``()`` samples each parameter
        on its own.
    unbounded : str
        Map of the bounded priors to the real line the sampler moves on
        (:data:`.priors.UNBOUNDED_MAPS`): ``"logit"`` (logistic CDF, the default) or
        ``"probit"`` (normal CDF, lighter tails where a parameter piles against a bound).
        The posterior is the same; only the coordinates the ensemble moves in change.
    priors : dict
        Parameter overrides ``{name: {"prior": …, "fixed": …}}`` (see
        :func:`.parameters.read_priors_file`).
    sampler : SamplerSettings
    model : forward.expected.ModelSettings
    """

    instrument: str | None = None
    use_measured_pulse: bool = True
    processing: ProcessingSettings | None = None
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
    tallest_stem: bool = False

    @classmethod
    def from_priors_file(cls, path, **changes) -> "InversionSettings":
        priors = read_priors_file(path)
        favd = priors.pop("favd", None)
        if favd is not None:
            changes.setdefault("favd_range", favd["range"])
        ground = priors.pop("ground", None)
        if ground is not None:
            changes.setdefault("ground_prior_sd_m", ground["prior_sd"])
        if set(TALLEST_STEM_LATENTS) & set(priors):  # a table for a latent turns them on
            changes.setdefault("tallest_stem", True)
        discrepancy = priors.pop("discrepancy", {})
        if "model" in discrepancy:
            changes.setdefault("discrepancy_model", discrepancy["model"])
        if "eta" in discrepancy:
            changes.setdefault("discrepancy", discrepancy["eta"])
        if "count" in discrepancy:
            changes.setdefault("realisations", RealisationSettings(count=discrepancy["count"]))
        return cls(priors=priors, **changes)

    def describe(self) -> dict:
        nested = ("priors", "sampler", "model", "realisations", "processing")
        out = {k: v for k, v in self.__dict__.items() if k not in nested}
        out["processing"] = None if self.processing is None else asdict(self.processing)
        out["realisations"] = asdict(self.realisations)
        out["shape_pair"] = list(self.shape_pair)
        out["ridges"] = list(self.ridges)
        out["favd_range"] = None if self.favd_range is None else list(self.favd_range)
        out["sampler"] = {k: v for k, v in self.sampler.__dict__.items()}
        out["sampler"]["moves"] = [list(m) for m in self.sampler.moves]
        out["model"] = dict(self.model.__dict__)
        out["priors"] = {
            name: {
                "fixed": change.get("fixed"),
                "prior": change["prior"].describe() if "prior" in change else None,
            }
            for name, change in self.priors.items()
        }
        return out


@dataclass
class InversionProblem:
    """A ready-to-sample posterior with what went into it."""

    observation: Observation
    analysis: object
    window: WindowData
    instrument: object
    log_posterior: LogPosterior
    settings: InversionSettings

    @property
    def space(self):
        return self.log_posterior.space


def pulse_quantiles(pulse, tail):
    """Height offsets (m) below and above which a fraction ``tail`` of the pulse lies
    (a measured pulse's ``support`` is its whole sampled span)."""
    low, high = pulse.support(tail)
    grid = np.linspace(low, high, 4001)
    cdf = pulse.cdf(grid)
    return float(np.interp(tail, cdf, grid)), float(np.interp(1.0 - tail, cdf, grid))


def _window_bounds(obs, analysis, settings, pulse_low, pulse_high):
    bottom = min(analysis.signal_end, analysis.ground + pulse_low) - settings.margin_below_m
    height = analysis.signal_start - analysis.ground
    top = analysis.signal_start + max(settings.margin_above_m, 0.5 * height)
    lo = int(np.searchsorted(obs.axis, bottom, side="left"))
    hi = int(np.searchsorted(obs.axis, top, side="right"))
    return max(lo, 0), min(hi, obs.n_bins)


def _fixed_discrepancy(window, analysis, settings, smooth_bins):
    try:
        function = DISCREPANCY_MODELS[settings.discrepancy_model]
    except KeyError:
        raise ValueError(
            f"unknown discrepancy model {settings.discrepancy_model!r}; "
            f"known: {sorted(DISCREPANCY_MODELS)}"
        ) from None
    if function is None:
        return None
    return function(window.samples, analysis.noise_mean, smooth_bins, settings.discrepancy)


def build_problem(obs: Observation, settings: InversionSettings | None = None) -> InversionProblem:
    """Analyse the shot, choose the window, set the shot's priors and build the posterior."""
    settings = InversionSettings() if settings is None else settings
    instrument = shot_instrument(
        obs, settings.instrument, measured_pulse=settings.use_measured_pulse
    )
    pulse_low, pulse_high = pulse_quantiles(instrument.pulse, 1e-3)
    analysis = analyse(obs, settings.processing, instrument=instrument)
    if not analysis.ok:
        raise ValueError(f"shot {obs.shot_id}: {analysis.status}: {analysis.reason}")
    lo, hi = _window_bounds(obs, analysis, settings, pulse_low, pulse_high)
    window = WindowData.from_observation(obs, lo, hi)
    b, sigma = analysis.noise_mean, analysis.noise_sigma
    energy = float(np.sum(np.clip(window.samples - b, 0.0, None)))
    if not energy > 0:
        raise ValueError(f"shot {obs.shot_id}: no energy above the noise mean in the window")
    g = analysis.ground
    g_sd = settings.ground_prior_sd_m
    if g_sd is None:
        g_sd = max(float(analysis.ground_uncertainty), obs.bin_size)
    if not (np.isfinite(g_sd) and g_sd > 0):
        raise ValueError(f"ground_prior_sd_m must be positive, got {settings.ground_prior_sd_m}")
    g_width = max(6.0 * g_sd, pulse_high - pulse_low)
    nuisance = {
        "ground_elevation": TruncatedNormal(g, g_sd, g - g_width, g + g_width),
        "gain": LogUniform(energy / 20.0, energy * 20.0),
        "baseline": Uniform(b - 5.0 * sigma, b + 5.0 * sigma),
        "noise_sigma": LogUniform(sigma / 3.0, sigma * 3.0),
    }
    # the canopy must fit inside the window, so that empty bins above it constrain it
    room = window.axis[-1] - g - pulse_high
    default_top = DEFAULT_STRUCTURE_PRIORS["top_height"]
    if room <= default_top.lower + 1.0:
        raise ValueError(f"shot {obs.shot_id}: the window leaves no room above the ground")
    nuisance["top_height"] = Uniform(default_top.lower, min(default_top.upper, room))
    overrides = dict(settings.priors)
    if not settings.sample_noise:
        overrides.setdefault("baseline", {"fixed": float(b)})
        overrides.setdefault("noise_sigma", {"fixed": float(sigma)})
    fixed_discrepancy = _fixed_discrepancy(window, analysis, settings, smooth_bins=1.0)
    if settings.marginalise_gain and overrides.get("gain", {}).get("fixed") is None:
        scale = settings.discrepancy if fixed_discrepancy is None else 0.0
        if gain_marginal_obstacle(window, settings.shot_factor, scale) is None:
            overrides["gain"] = {**overrides.get("gain", {}), "marginalised": True}
    space = default_space(
        nuisance, overrides, settings.ridges, settings.unbounded, settings.tallest_stem
    )
    mapping = StandMapping(
        default_template(settings.shape_pair),
        settings.shape_pair,
        footprint_sigma_m=instrument.footprint_sigma_m if settings.tallest_stem else None,
    )
    model = ExpectedWaveformModel(
        instrument,
        window.axis,
        mapping.template,
        free=mapping.model_free,
        settings=settings.model,
    )
    log_posterior = LogPosterior(
        space,
        mapping,
        model,
        window,
        settings.shot_factor,
        settings.discrepancy,
        (0.0, np.inf) if settings.favd_range is None else settings.favd_range,
        fixed_discrepancy,
    )
    return InversionProblem(obs, analysis, window, instrument, log_posterior, settings)
