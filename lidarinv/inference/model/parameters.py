"""The default parameterisation: which parameters, their units and default priors.

The default parameterisation uses quantities a waveform identifies (crown cover and
plant area index rather than stem density and FAVD, the top height of the height
distribution rather than its mean) plus the nuisance parameters of the observation model
(ground elevation, gain, baseline, noise σ and the reflectance ratio ρv/ρg). A parameter
named as a field of the expected model's vector (:data:`forward.expected.VECTOR_FIELDS`)
reaches the model by that name (:class:`.stand.StandMapping`).
"""

from .coordinates import DEFAULT_RIDGES, INTERCEPTION_SLOPE
from .prior_table import DEFAULT_UNBOUNDED
from .priors import LogUniform, TruncatedLogNormal, Uniform
from .space import Parameter, ParameterSpace
from .tallest_stem import (
    NO_STEM_DEPTH_M,
    TALLEST_STEM,
    TALLEST_STEM_MEAN_POSITION,
    TALLEST_STEM_POSITION,
)
from .two_cohort import COHORT2, COHORT2_PRIORS

#: Structural parameters of the default parameterisation: name → (units, description).
STRUCTURE = {
    "cover": ("1", "crown cover: fraction of ground under at least one crown"),
    "pai": ("m2/m2", "plant area index of the tree crowns (one-sided)"),
    "top_height": (
        "m",
        "upper limit of the stand's height distribution (mean + 2 sd); one footprint "
        "rarely holds a stem that tall",
    ),
    "height_sd": ("m", "spread (sd) of the tree-height distribution"),
    "crown_length_ratio": ("1", "crown length over tree height"),
    "cone_fraction": ("1", "fraction of stems with conical crowns (the rest ellipsoids)"),
    "crown_radius_slope": ("m/m", "crown radius per metre of tree height"),
    "understory_height": ("m", "height of the uniform understory layer"),
    "understory_lai": ("m2/m2", "leaf area index of the understory layer"),
}

#: Observation-model (nuisance) parameters: name → (units, description).
NUISANCE = {
    "ground_elevation": ("m", "ground elevation on the waveform axis"),
    "gain": ("DN", "digitiser units per unit apparent reflectance (ρg = 1)"),
    "baseline": ("DN", "noise mean"),
    "noise_sigma": ("DN", "noise standard deviation"),
    "rho_ratio": ("1", "canopy over ground reflectance ρv/ρg"),
    "pulse_broadening": (
        "m",
        "σ of the Gaussian that widens the transmitted pulse (receiver, terrain slope, roughness)",
    ),
}

#: Latent parameters, in the space only where the settings ask: name → (units, description).
LATENT = {
    TALLEST_STEM: (
        "m",
        "height of the footprint's tallest stem (within 2 sigma_f); below the lowest tree: none",
    ),
    TALLEST_STEM_POSITION: (
        "1",
        "squared distance of that stem from the footprint centre over the disc's (2 sigma_f)",
    ),
}

UNITS = {name: units for name, (units, _) in {**STRUCTURE, **COHORT2, **NUISANCE, **LATENT}.items()}

#: Structural priors of the default parameterisation (nuisance priors depend on the shot).
DEFAULT_STRUCTURE_PRIORS = {
    "cover": Uniform(0.001, 0.99),
    "pai": LogUniform(0.01, 15.0),
    "top_height": Uniform(1.0, 80.0),
    "height_sd": Uniform(0.1, 10.0),
    "crown_length_ratio": Uniform(0.1, 1.0),
    "cone_fraction": Uniform(0.0, 1.0),
    "crown_radius_slope": LogUniform(0.02, 0.5),
    "understory_height": Uniform(0.2, 3.0),
    "understory_lai": Uniform(0.0, 3.0),
}

#: A physically plausible support for the implied FAVD (m²/m³), for ``favd_range`` (off by
#: default): tree crowns hold about 0.05–3 m²/m³ (the paper's jack pine 0.8).
PLAUSIBLE_FAVD_RANGE = (0.05, 3.0)

#: Held fixed unless a priors file frees them: the crown-radius slope, and the tallest
#: stem's position (when that latent is in the space) at its mean footprint weight, whose
#: spread the realisation covariance then carries.
DEFAULT_FIXED = {"crown_radius_slope": 0.1, TALLEST_STEM_POSITION: TALLEST_STEM_MEAN_POSITION}

#: Default prior of ρv/ρg: median 1.5 (the GEDI L2B value), a factor e^0.3 ≈ 1.35 either
#: side at one sd; on the log scale because the data fix the product gain·ρv.
DEFAULT_RHO_RATIO_PRIOR = TruncatedLogNormal(1.5, 0.3, 0.3, 5.0)


def default_space(
    nuisance_priors: dict,
    overrides: dict | None = None,
    ridges=DEFAULT_RIDGES,
    unbounded=DEFAULT_UNBOUNDED,
    tallest_stem=False,
    interception_slope=INTERCEPTION_SLOPE,
    backend="auto",
    cohorts=1,
) -> ParameterSpace:
    """The default parameterisation with shot-specific nuisance priors.

    Parameters
    ----------
    nuisance_priors : dict
        Priors for every name in :data:`NUISANCE` except ``rho_ratio`` (optional) and
        ``pulse_broadening`` (held at 0 when not given).
    overrides : dict, optional
        ``{name: {"prior": prior, "fixed": value or None}}``, e.g. from a priors file.
    ridges : tuple of str
        Sampling coordinates (see :class:`ParameterSpace`).
    unbounded : str
        Map of the bounded priors to the real line (see :class:`ParameterSpace`).
    tallest_stem : bool
        Add the latents :data:`LATENT` of the tallest stem, for a mapping that conditions
        each footprint on its tallest stem: its height, over [−NO_STEM_DEPTH_M, the top
        height's upper bound] (the range sampled; the stand gives its law), and its
        position, uniform on [0, 1], held at its mean weight unless freed.
    interception_slope : float
        k·G·Ω of the shot's instrument (see :class:`.space.ParameterSpace`).
    backend : str
        ``"auto"``, ``"numba"`` or ``"numpy"`` for the ridge maps.
    cohorts : int
        1, or 2 for a lower storey: the parameters :data:`.two_cohort.COHORT2` with their
        priors :data:`.two_cohort.COHORT2_PRIORS`.

    Returns
    -------
    ParameterSpace
    """
    priors = {**DEFAULT_STRUCTURE_PRIORS, "rho_ratio": DEFAULT_RHO_RATIO_PRIOR, **nuisance_priors}
    fixed = dict(DEFAULT_FIXED)
    if "pulse_broadening" not in nuisance_priors:  # a preset pulse: the whole response
        priors["pulse_broadening"], fixed["pulse_broadening"] = Uniform(0.0, 1.0), 0.0
    params = []
    described = {**STRUCTURE, **(COHORT2 if cohorts == 2 else {}), **NUISANCE}
    if cohorts == 2:
        priors = {**COHORT2_PRIORS, **priors}
    for name, (units, description) in described.items():
        if name not in priors:
            raise ValueError(f"no prior given for {name}")
        params.append(Parameter(name, units, priors[name], fixed.get(name), description))
    if tallest_stem:
        top = {**{"prior": priors["top_height"]}, **(overrides or {}).get("top_height", {})}
        highest = max(top["prior"].form().upper, top.get("fixed") or 0.0)
        ranges = {TALLEST_STEM: (-NO_STEM_DEPTH_M, highest), TALLEST_STEM_POSITION: (0.0, 1.0)}
        for name, (units, description) in LATENT.items():
            prior, fixed = Uniform(*ranges[name]), DEFAULT_FIXED.get(name)
            params.append(Parameter(name, units, prior, fixed, description))
    space = ParameterSpace(params, ridges, unbounded, interception_slope, backend)
    return space.with_changes(overrides) if overrides else space
