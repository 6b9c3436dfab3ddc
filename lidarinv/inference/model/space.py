"""Inversion parameters: names, units, priors, fixed values, and the unbounded coordinates.

The default parameterisation uses quantities a waveform identifies (crown cover and
plant area index rather than stem density and FAVD, the top height of the height
distribution rather than its mean) plus the nuisance parameters of the observation model
(ground elevation, gain, baseline, noise σ and the reflectance ratio ρv/ρg).
"""

import tomllib
from dataclasses import dataclass, replace

import numpy as np

from . import compiled_coordinates, coordinates
from .discrepancy import DISCREPANCY_MODELS
from .priors import (
    DEFAULT_UNBOUNDED,
    LogUniform,
    PriorTable,
    TruncatedLogNormal,
    Uniform,
    make_prior,
)
from .stand_mapping import (
    NO_STEM_DEPTH_M,
    TALLEST_STEM,
    TALLEST_STEM_MEAN_POSITION,
    TALLEST_STEM_POSITION,
    TOP_SDS,
)


@dataclass(frozen=True)
class Parameter:
    """One inversion parameter.

    Parameters
    ----------
    name : str
    units : str
    prior : Uniform, LogUniform or TruncatedNormal
    fixed : float or None
        If set, the parameter is held at this value and not sampled.
    description : str
    marginalised : bool
        Integrated out of the likelihood against its prior (:mod:`.marginal`, the gain
        only) instead of sampled; its posterior samples are drawn afterwards.
    """

    name: str
    units: str
    prior: object
    fixed: float | None = None
    description: str = ""
    marginalised: bool = False

    @property
    def free(self) -> bool:
        """Sampled: neither fixed nor marginalised."""
        return self.fixed is None and not self.marginalised


#: Structural parameters of the default parameterisation: name → (units, description).
STRUCTURE = {
    "cover": ("1", "crown cover: fraction of ground under at least one crown"),
    "pai": ("m2/m2", "plant area index of the tree crowns (one-sided)"),
    "top_height": ("m", "top of the height distribution, mean + 2 sd (tallest tree)"),
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

UNITS = {name: units for name, (units, _) in {**STRUCTURE, **NUISANCE, **LATENT}.items()}

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

#: Held fixed unless a priors file frees them. The tallest stem's position (when that
#: latent is in the space) at its mean footprint weight: sampling it lengthened the chains
#: by two fifths and changed no coverage of the required quantities (README, "The
#: footprint's tallest stem, a latent").
DEFAULT_FIXED = {"crown_radius_slope": 0.1, TALLEST_STEM_POSITION: TALLEST_STEM_MEAN_POSITION}

#: Default prior of ρv/ρg: median 1.5 (the GEDI L2B value), a factor e^0.3 ≈ 1.35 either
#: side at one sd; on the log scale because the data fix the product gain·ρv.
DEFAULT_RHO_RATIO_PRIOR = TruncatedLogNormal(1.5, 0.3, 0.3, 5.0)


#: Cover within this of 1 is left out of the joint cover-PAI coordinates' range (a prior
#: reaching cover 1 would leave the ridge unbounded; the mass left out is ~1e-9).
COVER_MARGIN = 1e-9


def _support(parameter, upper=np.inf) -> tuple:
    """[lower, min(upper, the prior's upper)] of a parameter's prior."""
    form = parameter.prior.form()
    return float(form.lower), float(min(form.upper, upper))


class ParameterSpace:
    """An ordered set of :class:`Parameter`; the free ones form the sampled vector.

    Parameters
    ----------
    parameters : iterable of Parameter
    ridges : tuple of str
        Ridge-straightening coordinates of :mod:`.coordinates` to sample in, from
        :data:`.coordinates.RIDGE_COORDINATES`; each applies when its parameters are free
        (the posterior is unchanged; only its sampling coordinates):

        - ``cover-pai``: cover and PAI jointly, when both are free;
        - ``crown-base``: the log crown-base height of the mean tree instead of
          ``crown_length_ratio``, when that is free and ``top_height`` and ``height_sd``
          are in the space (free or fixed).
        - ``ground-centroid``: the centroid of the ground-plus-understory return instead
          of ``ground_elevation``, when that is free and the understory is in the space
          with a non-zero LAI (free or fixed).
        - ``tallest-stem``: the log gap between the top height and the tallest stem
          instead of ``top_height``, when both are free.
    unbounded : str
        Map of each bounded prior to the real line, from :data:`.priors.UNBOUNDED_MAPS`.
    """

    def __init__(self, parameters, ridges=coordinates.DEFAULT_RIDGES, unbounded=DEFAULT_UNBOUNDED):
        self.parameters = tuple(parameters)
        self.ridges = tuple(ridges)
        self.unbounded = unbounded
        unknown = sorted(set(self.ridges) - set(coordinates.RIDGE_COORDINATES))
        if unknown:
            raise ValueError(
                f"unknown sampling coordinates {unknown}; known: "
                f"{list(coordinates.RIDGE_COORDINATES)}"
            )
        names = [p.name for p in self.parameters]
        if len(set(names)) != len(names):
            raise ValueError(f"duplicate parameter names in {names}")
        self.by_name = {p.name: p for p in self.parameters}
        self.free = tuple(p for p in self.parameters if p.free)
        self.names = tuple(p.name for p in self.free)
        if not self.free:
            raise ValueError("every parameter is fixed; nothing to infer")
        self._priors = PriorTable([p.prior for p in self.free], unbounded)
        both = "cover" in self.names and "pai" in self.names
        self._joint = (
            (
                self.names.index("cover"),
                self.names.index("pai"),
                _support(self.by_name["cover"], upper=1.0 - COVER_MARGIN),
                _support(self.by_name["pai"]),
            )
            if both and "cover-pai" in self.ridges
            else None
        )
        needed = ("crown_length_ratio", "top_height", "height_sd")
        self._base = (
            self.names.index("crown_length_ratio")
            if "crown-base" in self.ridges
            and "crown_length_ratio" in self.names
            and set(needed) <= set(names)
            else None
        )
        self._centroid = self._centroid_map() if "ground-centroid" in self.ridges else None
        stem = ("top_height", TALLEST_STEM)
        self._stem = (
            tuple(self.names.index(n) for n in stem)
            if "tallest-stem" in self.ridges and set(stem) <= set(self.names)
            else None
        )
        inputs = ("top_height", "height_sd", "understory_lai", "understory_height", "rho_ratio")
        self._ridge_inputs = (  # for the compiled maps: each a column, or FIXED and a value
            np.array([self._index(n) for n in inputs], np.int64),
            np.array([self._fixed_value(n) for n in inputs], float),
        )

    @property
    def ndim(self) -> int:
        return len(self.free)

    def signature(self) -> str:
        """The sampled coordinates, for labelling stored chains: free names and transforms."""
        joint = "cover-pai-joint-v2" if self._joint is not None else "per-parameter"
        if self._base is not None:
            joint += ", crown-base-v1"
        if self._centroid is not None:
            joint += ", ground-centroid-v1"
        if self._stem is not None:
            joint += ", tallest-stem-gap-v1"
        priors = ";".join(f"{p.name}:{p.prior.describe()}" for p in self.free)
        marginalised = "".join(f"; marginalised {name}" for name in self.marginalised)
        return f"lidarinv {self.unbounded} transforms, {joint}; {priors}{marginalised}"

    @property
    def marginalised(self) -> tuple:
        """Names of the parameters integrated out of the likelihood."""
        return tuple(p.name for p in self.parameters if p.marginalised)

    def units(self, name) -> str:
        return self.by_name[name].units

    def values(self, x) -> dict:
        """Every parameter's values (free from the columns of ``x`` (n, ndim), fixed filled;
        marginalised ones are absent)."""
        x = np.atleast_2d(np.asarray(x, float))
        out = {p.name: x[:, i] for i, p in enumerate(self.free)}
        for p in self.parameters:
            if p.fixed is not None:
                out[p.name] = np.full(x.shape[0], float(p.fixed))
        return out

    def log_prior(self, x) -> np.ndarray:
        """Sum of the free parameters' log prior densities; −inf outside the support."""
        x = np.atleast_2d(np.asarray(x, float))
        total = self._priors.log_pdf(x).sum(axis=1)
        return np.where(np.isfinite(total), total, -np.inf)

    def from_unbounded(self, u, reference=False):
        """Physical values (n, ndim) and log|Jacobian| (n,) from unbounded coordinates;
        ``reference=True`` maps the ridge coordinates with numpy instead of compiled code."""
        u = np.atleast_2d(np.asarray(u, float))
        x, log_jac = self._priors.from_unbounded(u)
        if self._stem is not None:  # before the crown base, which needs the top
            top, stem = self._stem
            x[:, top], log_jac[:, top] = coordinates.top_from_stem_gap(x[:, stem], u[:, top])
        (self._ridges_numpy if reference else self._ridges_compiled)(u, x, log_jac)
        return x, log_jac.sum(axis=1)

    def _ridges_numpy(self, u, x, log_jac):
        """Overwrite the ridge-coordinate columns of x and log_jac in place."""
        if self._joint is not None:
            c, a, cover_bounds, pai_bounds = self._joint
            x[:, c], x[:, a], log_jac[:, c] = coordinates.to_cover_pai_bounded(
                u[:, c], u[:, a], cover_bounds, pai_bounds
            )
            log_jac[:, a] = 0.0
        if self._base is not None:
            r = self._base
            x[:, r], log_jac[:, r] = coordinates.ratio_from_crown_base(u[:, r], self._mean(x))
        if self._centroid is not None:
            g, lower, stretch = self._centroid
            centroid = lower + (x[:, g] - lower) * stretch
            x[:, g] = centroid - self._understory_centroid(x)
            log_jac[:, g] += np.log(stretch)

    def _ridges_compiled(self, u, x, log_jac):
        """As :meth:`_ridges_numpy`, in :mod:`.compiled_coordinates`."""
        slope = coordinates.INTERCEPTION_SLOPE
        if self._joint is not None:
            c, a, cover_bounds, pai_bounds = self._joint
            compiled_coordinates.cover_pai_bounded(
                u, x, log_jac, c, a, cover_bounds, pai_bounds, slope
            )
        if self._base is not None or self._centroid is not None:
            columns, fixed = self._ridge_inputs
            compiled_coordinates.crown_and_ground(
                u, x, log_jac, self._base, self._centroid, columns, fixed, TOP_SDS, slope
            )

    def to_unbounded(self, x):
        x = np.atleast_2d(np.asarray(x, float))
        if self._centroid is not None:
            g, lower, stretch = self._centroid
            centroid = x[:, g] + self._understory_centroid(x)
            x = x.copy()
            x[:, g] = lower + (centroid - lower) / stretch
        u = self._priors.to_unbounded(x)
        if self._joint is not None:
            c, a, cover_bounds, pai_bounds = self._joint
            u[:, c], u[:, a] = coordinates.from_cover_pai_bounded(
                x[:, c], x[:, a], cover_bounds, pai_bounds
            )
        if self._base is not None:
            r = self._base
            u[:, r] = coordinates.crown_base_from_ratio(x[:, r], self._mean(x))
        if self._stem is not None:
            top, stem = self._stem
            u[:, top] = coordinates.stem_gap_from_top(x[:, top], x[:, stem])
        return u

    def _index(self, name) -> int:
        return self.names.index(name) if name in self.names else compiled_coordinates.FIXED

    def _fixed_value(self, name) -> float:
        p = self.by_name.get(name)
        return np.nan if p is None or p.fixed is None else float(p.fixed)

    def _column(self, x, name):
        """Values of parameter ``name`` in rows x, free or fixed."""
        return x[:, self.names.index(name)] if name in self.names else self.by_name[name].fixed

    def _mean(self, x):
        """Mean tree height (m) of rows x: top − TOP_SDS·sd, free or fixed."""
        return self._column(x, "top_height") - TOP_SDS * self._column(x, "height_sd")

    def _understory_centroid(self, x):
        """Height (m) of the ground-plus-understory centroid above the ground, rows x."""
        lai, height, ratio = (
            self._column(x, name) for name in ("understory_lai", "understory_height", "rho_ratio")
        )
        return coordinates.understory_centroid(lai, height, ratio)

    def _centroid_map(self):
        """(column, lower, stretch) of the ground-centroid coordinate, or None where it does
        not apply: the ground prior's range [lower, upper] widened to upper + the tallest
        understory, so that c = zg + f(…) covers it (f ≤ hu)."""
        needed = ("understory_lai", "understory_height", "rho_ratio")
        if "ground_elevation" not in self.names or not set(needed) <= set(self.by_name):
            return None
        lai = self.by_name["understory_lai"]
        if lai.fixed is not None and lai.fixed <= 0:
            return None
        height = self.by_name["understory_height"]
        tallest = height.fixed if height.fixed is not None else height.prior.form().upper
        ground = self.by_name["ground_elevation"].prior.form()
        if ground.log_scale or not np.isfinite(ground.upper - ground.lower + tallest):
            return None
        span = ground.upper - ground.lower
        return self.names.index("ground_elevation"), ground.lower, (span + tallest) / span

    def sample_prior(self, rng, size) -> np.ndarray:
        """Draws from the free parameters' priors; a tallest stem sampled with the top
        height is drawn uniformly over the stand's height range below it, and the no-stem
        range under that, instead (its law given the stand needs the stand's density:
        these are candidates, to be scored)."""
        x = np.column_stack([p.prior.sample(rng, size) for p in self.free])
        if TALLEST_STEM in self.names and "top_height" in self.by_name:
            top = self._column(x, "top_height")
            span = np.minimum(2.0 * TOP_SDS * self._column(x, "height_sd"), top)
            span += NO_STEM_DEPTH_M  # and the no-stem range below the lowest tree
            x[:, self.names.index(TALLEST_STEM)] = top - span * rng.uniform(size=size)
        return x

    def with_changes(self, changes: dict) -> "ParameterSpace":
        """A copy with per-parameter changes: ``{name: {"prior": …, "fixed": …}}``."""
        unknown = sorted(set(changes) - set(self.by_name))
        if unknown:
            raise ValueError(f"unknown parameter(s) {unknown}; known: {sorted(self.by_name)}")
        out = []
        for p in self.parameters:
            change = changes.get(p.name, {})
            out.append(replace(p, **change) if change else p)
        return ParameterSpace(out, self.ridges, self.unbounded)

    def describe(self) -> list:
        return [
            {
                "name": p.name,
                "units": p.units,
                "fixed": p.fixed,
                "marginalised": p.marginalised,
                "prior": p.prior.describe(),
                "description": p.description,
            }
            for p in self.parameters
        ]


def default_space(
    nuisance_priors: dict,
    overrides: dict | None = None,
    ridges=coordinates.DEFAULT_RIDGES,
    unbounded=DEFAULT_UNBOUNDED,
    tallest_stem=False,
) -> ParameterSpace:
    """The default parameterisation with shot-specific nuisance priors.

    Parameters
    ----------
    nuisance_priors : dict
        Priors for every name in :data:`NUISANCE` except ``rho_ratio`` (optional).
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
    """
    priors = {**DEFAULT_STRUCTURE_PRIORS, "rho_ratio": DEFAULT_RHO_RATIO_PRIOR, **nuisance_priors}
    params = []
    for name, (units, description) in {**STRUCTURE, **NUISANCE}.items():
        if name not in priors:
            raise ValueError(f"no prior given for {name}")
        params.append(Parameter(name, units, priors[name], DEFAULT_FIXED.get(name), description))
    if tallest_stem:
        top = {**{"prior": priors["top_height"]}, **(overrides or {}).get("top_height", {})}
        highest = max(top["prior"].form().upper, top.get("fixed") or 0.0)
        ranges = {TALLEST_STEM: (-NO_STEM_DEPTH_M, highest), TALLEST_STEM_POSITION: (0.0, 1.0)}
        for name, (units, description) in LATENT.items():
            prior, fixed = Uniform(*ranges[name]), DEFAULT_FIXED.get(name)
            params.append(Parameter(name, units, prior, fixed, description))
    space = ParameterSpace(params, ridges, unbounded)
    return space.with_changes(overrides) if overrides else space


def read_priors_file(path) -> dict:
    """Prior overrides from a TOML file.

    Each table is a parameter name; keys ``kind`` (uniform, log-uniform,
    truncated-normal) with its numbers, and/or ``fixed = value``, or ``free = true`` to
    sample a parameter that is fixed by default::

        [top_height]
        kind = "uniform"
        lower = 5.0
        upper = 40.0

        [understory_lai]
        fixed = 0.0

    A ``[favd]`` table with ``lower`` and ``upper`` (m²/m³) bounds the FAVD implied by the
    other parameters (a joint prior constraint, see ``InversionSettings.favd_range``); it
    is returned under the key ``"favd"`` as ``{"range": (lower, upper)}``. A ``[ground]``
    table with ``prior_sd`` (m) sets the width of the ground-elevation prior around the
    detected peak (``InversionSettings.ground_prior_sd_m``); it is returned under the key
    ``"ground"`` as ``{"prior_sd": value}``. A ``[discrepancy]`` table with any of
    ``model`` (``realisations``, ``observed`` or ``model``), ``eta`` (η) and ``count``
    (realisations) chooses the model-discrepancy term (``InversionSettings.
    discrepancy_model``, ``discrepancy``, ``realisations.count``); it is returned under
    the key ``"discrepancy"`` as a dict of those keys. A table for either latent of
    :data:`LATENT` (e.g. ``[tallest_stem_height]`` with ``free = true``) conditions
    each footprint on its tallest stem (``InversionSettings.tallest_stem``).
    """
    try:
        with open(path, "rb") as handle:
            table = tomllib.load(handle)
    except tomllib.TOMLDecodeError as error:
        raise ValueError(f"{path}: not valid TOML: {error}") from None
    known = set(STRUCTURE) | set(NUISANCE) | set(LATENT) | set(_SETTINGS_TABLES)
    unknown = sorted(set(table) - known)
    if unknown:
        raise ValueError(f"{path}: unknown parameter(s) {unknown}; known: {sorted(known)}")
    changes = {}
    for name, spec in table.items():
        if not isinstance(spec, dict):
            raise ValueError(f"{path}: [{name}] must be a table")
        if name in _SETTINGS_TABLES:
            changes[name] = _SETTINGS_TABLES[name](path, spec)
            continue
        spec = dict(spec)
        change = {}
        if "fixed" in spec:
            value = float(spec.pop("fixed"))
            if not np.isfinite(value):
                raise ValueError(f"{path}: [{name}] fixed value must be finite")
            change["fixed"] = value
        elif spec.pop("free", False) or spec:
            change["fixed"] = None
        if spec:
            try:
                change["prior"] = make_prior(spec)
            except ValueError as error:
                raise ValueError(f"{path}: [{name}] {error}") from None
        changes[name] = change
    return changes


def _favd_range(path, spec) -> dict:
    unknown = sorted(set(spec) - {"lower", "upper"})
    if unknown:
        raise ValueError(f"{path}: [favd] takes lower and upper (m2/m3), not {unknown}")
    low, high = float(spec.get("lower", 0.0)), float(spec.get("upper", np.inf))
    if not (0.0 <= low < high):
        raise ValueError(f"{path}: [favd] needs 0 <= lower < upper, got {low}, {high}")
    return {"range": (low, high)}


def _ground_prior(path, spec) -> dict:
    unknown = sorted(set(spec) - {"prior_sd"})
    if unknown:
        raise ValueError(f"{path}: [ground] takes prior_sd (m), not {unknown}")
    sd = float(spec.get("prior_sd", np.nan))
    if not (np.isfinite(sd) and sd > 0):
        raise ValueError(f"{path}: [ground] prior_sd must be a positive number of metres")
    return {"prior_sd": sd}


def _discrepancy(path, spec) -> dict:
    unknown = sorted(set(spec) - {"model", "eta", "count"})
    if unknown:
        raise ValueError(f"{path}: [discrepancy] takes model, eta and count, not {unknown}")
    out = {}
    if "model" in spec:
        if spec["model"] not in DISCREPANCY_MODELS:
            raise ValueError(
                f"{path}: [discrepancy] model {spec['model']!r} is not one of "
                f"{sorted(DISCREPANCY_MODELS)}"
            )
        out["model"] = spec["model"]
    if "eta" in spec:
        eta = float(spec["eta"])
        if not (np.isfinite(eta) and eta >= 0):
            raise ValueError(f"{path}: [discrepancy] eta must be a number ≥ 0")
        out["eta"] = eta
    if "count" in spec:
        count = spec["count"]
        if not (isinstance(count, int) and count >= 2):
            raise ValueError(f"{path}: [discrepancy] count must be an integer ≥ 2")
        out["count"] = count
    return out


#: Priors-file tables that set InversionSettings rather than a parameter's prior.
_SETTINGS_TABLES = {"favd": _favd_range, "ground": _ground_prior, "discrepancy": _discrepancy}
