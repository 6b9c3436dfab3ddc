"""Bayesian inversion of one waveform, in stages that run one way.

1. The shot (:mod:`.shot`): instrument, analysis, window and noise model, built once.
2. The model (:mod:`.model`): parameters and their priors → stand → expected waveform.
3. The likelihood (:mod:`.likelihood`): the window's samples given a model waveform.
4. The posterior (:mod:`.posterior`) joins them; :mod:`.problem` builds it for a shot,
   and :mod:`.realisations` simulates its discrepancy covariance.
5. Sampling (:mod:`.sampling`): the MAP search, the emcee run and its moves.
6. Results (:mod:`.collect`, :mod:`.result`): the posterior summary of a finished run.

:func:`invert_shot` (:mod:`.invert`) runs them all; :mod:`.settings` holds the settings
that are not priors.
"""

from lidarinv.inference.priors_file import read_priors_file

from .invert import invert_shot, prepare_problem, sample_prepared
from .likelihood.gaussian import ShotLikelihood, model_moments
from .model.parameters import default_space
from .model.priors import PRIOR_KINDS, LogUniform, TruncatedNormal, Uniform, make_prior
from .model.space import Parameter, ParameterSpace
from .model.stand import StandMapping, default_template
from .model.waveform import ShotModel
from .posterior import BLOB_NAMES, LogPosterior
from .problem import InversionProblem, build_problem
from .results.collect import collect_result
from .results.result import InversionResult
from .sampling import SamplerSettings, find_map, run_sampler
from .settings import InversionSettings, RealisationSettings
from .shot import Shot, WindowData

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
    "Shot",
    "ShotLikelihood",
    "ShotModel",
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
    "make_prior",
    "model_moments",
    "prepare_problem",
    "read_priors_file",
    "run_sampler",
    "sample_prepared",
]
