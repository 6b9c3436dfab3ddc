"""Bayesian inversion of one waveform: parameters and priors, likelihood, posterior,
sampling with emcee, and the posterior result."""

from .invert import collect_result, invert_shot
from .likelihood import WindowData, log_likelihood, model_moments
from .parameters import Parameter, ParameterSpace, default_space, read_priors_file
from .posterior import BLOB_NAMES, LogPosterior
from .priors import PRIOR_KINDS, LogUniform, TruncatedNormal, Uniform, make_prior
from .problem import InversionProblem, InversionSettings, build_problem
from .realisations import RealisationSettings
from .result import InversionResult
from .sampling import SamplerSettings, find_map, run_sampler
from .stand_mapping import StandMapping, default_template

__all__ = [
    "BLOB_NAMES",
    "PRIOR_KINDS",
    "InversionProblem",
    "InversionResult",
    "InversionSettings",
    "LogPosterior",
    "LogUniform",
    "Parameter",
    "ParameterSpace",
    "RealisationSettings",
    "SamplerSettings",
    "StandMapping",
    "TruncatedNormal",
    "Uniform",
    "WindowData",
    "build_problem",
    "collect_result",
    "default_space",
    "default_template",
    "find_map",
    "invert_shot",
    "log_likelihood",
    "make_prior",
    "model_moments",
    "read_priors_file",
    "run_sampler",
]
