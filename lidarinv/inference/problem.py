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

from .likelihood.discrepancy import DISCREPANCY_MODELS
from .likelihood.gaussian import ShotLikelihood, correlation_obstacle
from .likelihood.marginal import gain_marginal_obstacle
from .model.parameters import DEFAULT_STRUCTURE_PRIORS, default_space
from .model.stand import StandMapping, default_template
from .model.two_cohort import TwoCohortMapping
from .model.waveform import ShotModel
from .posterior import LogPosterior
from .settings import AUTO, InversionSettings
from .shot import Shot

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

    def with_fixed_discrepancy(self, fixed_discrepancy) -> "InversionProblem":
        """The same problem with another fixed discrepancy in its likelihood.

        Parameters
        ----------
        fixed_discrepancy : array (bins,) or (bins, bins) (DN²)
            A variance per bin or a covariance between bins.

        Returns
        -------
        InversionProblem
        """
        post = self.log_posterior.with_fixed_discrepancy(fixed_discrepancy)
        return InversionProblem(self.shot, post, self.settings)


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
        :func:`.invert.choose_cohorts` weighs against the two-cohort one.

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
    top = DEFAULT_STRUCTURE_PRIORS["top_height"]
    nuisance = shot.nuisance_priors(settings.ground_prior_sd_m, (top.lower, top.upper))
    correlation = shot.noise_correlation() if settings.correlated_noise else None
    fixed = fixed_discrepancy(shot, settings)
    # under whitened correlated noise a sampled σn would fit the whitened residuals, not
    # the noise's marginal σ that the whitening assumes: the noise is held at its estimate
    correlated = correlation is not None and correlation.order > 0
    if correlated:
        scale = settings.discrepancy if fixed is None else 0.0
        correlated = correlation_obstacle(shot.window, settings.shot_factor, scale) is None
    overrides = {
        **shot.noise_overrides(settings.sample_noise and not correlated),
        **settings.priors,
    }
    if settings.marginalise_gain and overrides.get("gain", {}).get("fixed") is None:
        scale = settings.discrepancy if fixed is None else 0.0
        if gain_marginal_obstacle(shot.window, settings.shot_factor, scale) is None:
            overrides["gain"] = {**overrides.get("gain", {}), "marginalised": True}
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
    likelihood = ShotLikelihood(
        shot.window,
        settings.shot_factor,
        settings.discrepancy,
        fixed,
        gain.prior if gain.marginalised else None,
        correlation,
    )
    favd_range = (0.0, np.inf) if settings.favd_range is None else settings.favd_range
    post = LogPosterior(space, ShotModel(mapping, expected), likelihood, favd_range)
    return InversionProblem(shot, post, settings)
