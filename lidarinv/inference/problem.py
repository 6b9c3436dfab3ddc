"""One observation's inversion problem: the stages joined, once.

:func:`build_problem` runs the stages in order and never returns to one: the shot
(:class:`.shot.Shot`: instrument, analysis, window, noise), its parameter space (its
nuisance priors with the default structure, :func:`.model.parameters.default_space`), the
model stage (:class:`.model.waveform.ShotModel`), the likelihood stage
(:class:`.likelihood.gaussian.ShotLikelihood`) and the posterior joining them.
"""

from dataclasses import dataclass, replace

import numpy as np

from forward.expected import ExpectedWaveformModel
from lidarinv.observe.observation import Observation

from .likelihood import LIKELIHOODS
from .likelihood.discrepancy import DISCREPANCY_MODELS
from .model.parameters import DEFAULT_STRUCTURE_PRIORS, default_space
from .model.stand import StandMapping, default_template
from .model.two_cohort import TwoCohortMapping
from .model.waveform import ShotModel
from .posterior import LogPosterior
from .settings import AUTO, InversionSettings
from .shot import Shot, WindowData

#: The stand mapping of each count of height cohorts.
MAPPINGS = {1: StandMapping, 2: TwoCohortMapping}


@dataclass
class InversionProblem:
    """A ready-to-sample posterior with the shot it is of.

    Attributes
    ----------
    shot : Shot
    log_posterior : LogPosterior
    settings : InversionSettings
    """

    shot: Shot
    log_posterior: LogPosterior
    settings: InversionSettings

    @property
    def space(self):
        """The parameter space (:class:`.model.space.ParameterSpace`)."""
        return self.log_posterior.space

    @property
    def observation(self) -> Observation:
        return self.shot.observation

    @property
    def analysis(self):
        return self.shot.analysis

    @property
    def window(self):
        return self.shot.window

    @property
    def instrument(self):
        return self.shot.instrument

    def with_likelihood(self, likelihood) -> "InversionProblem":
        """The same problem with another likelihood of its window.

        Parameters
        ----------
        likelihood : Likelihood

        Returns
        -------
        InversionProblem
        """
        return replace(self, log_posterior=self.log_posterior.with_likelihood(likelihood))


def fixed_discrepancy(shot: Shot, settings: InversionSettings, smooth_bins=1.0):
    """The discrepancy variance the observation fixes for the shot.

    Parameters
    ----------
    shot : Shot
    settings : InversionSettings
        ``discrepancy_model`` and ``discrepancy`` (η).
    smooth_bins : float
        Smoothing of the observed signal (bins).

    Returns
    -------
    array (bins,) (DN²) or None
        None where the model's own signal sets it
        (:data:`.likelihood.discrepancy.DISCREPANCY_MODELS`).

    Raises
    ------
    ValueError
        For an unknown discrepancy model.
    """
    try:
        function = DISCREPANCY_MODELS[settings.discrepancy_model]
    except KeyError:
        raise ValueError(
            f"unknown discrepancy model {settings.discrepancy_model!r}; "
            f"known: {sorted(DISCREPANCY_MODELS)}"
        ) from None
    if function is None:
        return None
    return function(shot.window.samples, shot.noise_mean, smooth_bins, settings.discrepancy)


def likelihood_class(name: str):
    """The likelihood registered as ``name`` (:data:`.likelihood.LIKELIHOODS`).

    Raises
    ------
    ValueError
        For an unknown name.
    """
    try:
        return LIKELIHOODS[name]
    except KeyError:
        raise ValueError(f"unknown likelihood {name!r}; known: {sorted(LIKELIHOODS)}") from None


def parameter_overrides(settings, holds_noise, gain_obstacle, noise_estimates) -> dict:
    """The parameter overrides of an inversion: the noise held where it is not sampled,
    the gain integrated out where it can be, then the settings' own priors.

    Parameters
    ----------
    settings : InversionSettings
        ``sample_noise``, ``marginalise_gain`` and ``priors``.
    holds_noise : bool
        The likelihood holds the noise at the shot's estimates (whitened read noise).
    gain_obstacle : str or None
        Why the likelihood cannot integrate the gain out; None if it can.
    noise_estimates : dict
        ``{"baseline": {"fixed": b̂}, "noise_sigma": {"fixed": σ̂}}``, the shot's.

    Returns
    -------
    dict
        ``{name: {"prior": …, "fixed": …, "marginalised": …}}`` for
        :func:`.model.parameters.default_space`.
    """
    held = not settings.sample_noise or holds_noise
    overrides = {**(noise_estimates if held else {}), **settings.priors}
    if settings.marginalise_gain and overrides.get("gain", {}).get("fixed") is None:
        if gain_obstacle is None:
            overrides["gain"] = {**overrides.get("gain", {}), "marginalised": True}
    return overrides


def build_problem(obs: Observation, settings: InversionSettings | None = None) -> InversionProblem:
    """Analyse the shot, choose the window, set the shot's priors and build the posterior.

    Parameters
    ----------
    obs : Observation
    settings : InversionSettings, optional

    Returns
    -------
    InversionProblem
        With the discrepancy the observation fixes (a ``realisations`` discrepancy starts
        from ``observed``: :func:`.invert.prepare_problem` simulates it). A problem holds
        one stand model: with ``cohorts="auto"`` the one-cohort one, which
        :func:`.passes.cohorts.choose_cohorts` weighs against the two-cohort one.

    Raises
    ------
    ValueError
        If the shot has no usable signal or ground peak, or a setting is invalid.
    """
    settings = InversionSettings() if settings is None else settings
    return problem_for_shot(Shot.from_observation(obs, settings), settings)


def problem_for_shot(shot: Shot, settings: InversionSettings) -> InversionProblem:
    """The inversion problem of an analysed shot (see :func:`build_problem`).

    Parameters
    ----------
    shot : Shot
    settings : InversionSettings

    Returns
    -------
    InversionProblem
    """
    if settings.cohorts == AUTO:  # one stand model a problem (see build_problem)
        settings = replace(settings, cohorts=1)
    settings = replace(settings, tallest_stem=settings.latent_stem(settings.cohorts))
    top = DEFAULT_STRUCTURE_PRIORS["top_height"]
    nuisance = shot.nuisance_priors(settings.ground_prior_sd_m, (top.lower, top.upper))
    fixed = fixed_discrepancy(shot, settings)
    likelihood = likelihood_class(settings.likelihood).for_shot(
        shot.window, shot.analysis.noise, settings, fixed
    )
    overrides = parameter_overrides(
        settings, likelihood.holds_noise, likelihood.gain_obstacle, shot.noise_estimates()
    )
    backend = settings.model.backend
    instrument = shot.instrument
    space = default_space(
        nuisance, overrides, settings.ridges, settings.unbounded, settings.tallest_stem,
        instrument.extinction_per_favd, backend, settings.cohorts,
    )  # fmt: skip
    template = default_template(settings.shape_pair)
    sigma = instrument.footprint_sigma_m if settings.tallest_stem else None
    mapping = MAPPINGS[settings.cohorts](
        template, settings.shape_pair, footprint_sigma_m=sigma, backend=backend
    )
    expected = ExpectedWaveformModel(
        instrument, shot.window.axis, mapping.template, mapping.model_free, settings.model
    )
    gain = space.by_name["gain"]
    if gain.marginalised:
        likelihood = likelihood.with_gain_prior(gain.prior)
    favd_range = (0.0, np.inf) if settings.favd_range is None else settings.favd_range
    broadening = space.by_name.get("pulse_broadening")
    reach = None if broadening is None else getattr(broadening.prior, "upper", None)
    model = ShotModel(mapping, expected, reach)
    post = LogPosterior(space, model, likelihood, favd_range)
    return InversionProblem(shot, post, settings)


def sampled_dimensions(settings: InversionSettings, measured_pulse: bool = True) -> int:
    """Coordinates the sampler moves for ``settings`` on a shot whose every bin is exactly
    recorded, before any shot is read (e.g. to check a walker count): the parameter space
    of :func:`problem_for_shot` with the noise sampled unless the settings hold it, and
    two height cohorts for ``cohorts="auto"`` (the larger model it may choose).

    Parameters
    ----------
    settings : InversionSettings
    measured_pulse : bool
        The shot carries its transmitted waveform (as GEDI and LVIS files do): the pulse's
        broadening is sampled too.

    Returns
    -------
    int
    """
    from .model.priors import Uniform

    bins = 3
    window = WindowData(np.arange(float(bins)), np.zeros(bins), np.zeros(bins, bool),
                        np.zeros(bins, bool))  # fmt: skip
    fixed = None if DISCREPANCY_MODELS.get(settings.discrepancy_model) is None else np.zeros(bins)
    likelihood = likelihood_class(settings.likelihood).for_shot(window, None, settings, fixed)
    estimates = {"baseline": {"fixed": 0.0}, "noise_sigma": {"fixed": 1.0}}
    overrides = parameter_overrides(settings, False, likelihood.gain_obstacle, estimates)
    placeholder = Uniform(0.0, 1.0)
    nuisance = {name: placeholder for name in ("ground_elevation", "baseline")}
    nuisance.update(gain=Uniform(1.0, 2.0), noise_sigma=Uniform(1.0, 2.0))
    if measured_pulse and settings.use_measured_pulse:
        nuisance["pulse_broadening"] = placeholder
    cohorts = 1 if settings.cohorts == 1 else 2
    space = default_space(
        nuisance, overrides, settings.ridges, settings.unbounded, settings.latent_stem(cohorts),
        cohorts=cohorts,
    )  # fmt: skip
    return space.ndim
