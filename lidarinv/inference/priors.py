"""Priors on inversion parameters, chosen through a registry, and their unbounded transforms.

Every prior here is proper and bounded, so each parameter maps to the real line by
x = lo + (hi − lo)·σ(u) (uniform and truncated normal) or log x = log lo + (log hi −
log lo)·σ(u) (log-uniform), with σ the logistic function. The sampler works in u; the
log-density in u adds log|dx/du|.
"""

from dataclasses import dataclass

import numpy as np
from scipy.special import logit, ndtr, ndtri

from . import compiled


def _check_bounds(lower, upper, kind):
    if not (np.isfinite(lower) and np.isfinite(upper) and lower < upper):
        raise ValueError(
            f"{kind} prior needs finite bounds with lower < upper, got {lower}, {upper}"
        )


@dataclass(frozen=True)
class PriorForm:
    """A prior written in the common form shared by every kind here.

    The support is x ∈ [lower, upper]. With w = log x (``log_scale``) or w = x, it is
    w ∈ [w_lower, w_upper] and log p(x) = −[log_scale]·ln x − ½((w − w_mean)/w_sd)² −
    log_norm (w_sd = ∞ for the uniform kinds); the unbounded coordinate is
    u = logit((w − w_lower)/(w_upper − w_lower)).
    """

    lower: float
    upper: float
    log_scale: bool
    w_lower: float
    w_upper: float
    w_mean: float
    w_sd: float
    log_norm: float


class PriorTable:
    """Several priors evaluated together, column by column of an (n, k) array, in one
    compiled pass (:mod:`.compiled`).

    Parameters
    ----------
    priors : sequence of priors with a ``form()`` method
    """

    def __init__(self, priors):
        forms = [p.form() for p in priors]
        self._log = np.array([f.log_scale for f in forms], np.bool_)
        self._lower = np.array([f.w_lower for f in forms], float)
        self._span = np.array([f.w_upper - f.w_lower for f in forms], float)
        self._mean = np.array([f.w_mean for f in forms], float)
        self._sd = np.array([f.w_sd for f in forms], float)
        self._norm = np.array([f.log_norm for f in forms], float)
        self._x_lower = np.array([f.lower for f in forms], float)
        self._x_upper = np.array([f.upper for f in forms], float)

    def log_pdf(self, x) -> np.ndarray:
        """Log densities (..., k) of the columns of x (..., k); −inf outside each support."""
        x = np.asarray(x, float)
        flat = x.reshape(-1, x.shape[-1]) if x.ndim != 2 else x
        density = compiled.prior_log_pdf(
            flat, self._x_lower, self._x_upper, self._log, self._mean, self._sd, self._norm
        )
        return density.reshape(x.shape)

    def from_unbounded(self, u):
        """Values (..., k) and log|dx/du| (..., k) of unbounded coordinates u (..., k)."""
        u = np.asarray(u, float)
        flat = u.reshape(-1, u.shape[-1]) if u.ndim != 2 else u
        x, log_jac = compiled.prior_from_unbounded(
            flat, self._lower, self._span, self._log, self._x_lower, self._x_upper
        )
        return x.reshape(u.shape), log_jac.reshape(u.shape)


class _OnePrior:
    """log_pdf and from_unbounded of a single prior, through its :class:`PriorForm`."""

    def log_pdf(self, x):
        """Log density at ``x`` (parameter units); −inf outside the support."""
        x = np.asarray(x, float)
        return PriorTable([self]).log_pdf(x[..., None])[..., 0]

    def from_unbounded(self, u):
        """Parameter values and log|dx/du| for unbounded values ``u``."""
        x, log_jac = PriorTable([self]).from_unbounded(np.asarray(u, float)[..., None])
        return x[..., 0], log_jac[..., 0]


@dataclass(frozen=True)
class Uniform(_OnePrior):
    """Uniform on [lower, upper] (parameter units)."""

    lower: float
    upper: float

    def __post_init__(self):
        _check_bounds(self.lower, self.upper, "uniform")

    def to_unbounded(self, x):
        return logit((np.asarray(x, float) - self.lower) / (self.upper - self.lower))

    def sample(self, rng, size):
        return rng.uniform(self.lower, self.upper, size)

    def form(self):
        span = self.upper - self.lower
        return PriorForm(
            self.lower, self.upper, False, self.lower, self.upper, 0.0, np.inf, np.log(span)
        )

    def describe(self):
        return {"kind": "uniform", "lower": self.lower, "upper": self.upper}


@dataclass(frozen=True)
class LogUniform(_OnePrior):
    """Log-uniform on [lower, upper] (parameter units, both > 0)."""

    lower: float
    upper: float

    def __post_init__(self):
        _check_bounds(self.lower, self.upper, "log-uniform")
        if self.lower <= 0:
            raise ValueError(f"log-uniform prior needs lower > 0, got {self.lower}")

    def to_unbounded(self, x):
        x = np.asarray(x, float)
        return logit(np.log(x / self.lower) / np.log(self.upper / self.lower))

    def sample(self, rng, size):
        return np.exp(rng.uniform(np.log(self.lower), np.log(self.upper), size))

    def form(self):
        span = np.log(self.upper / self.lower)
        return PriorForm(
            self.lower,
            self.upper,
            True,
            np.log(self.lower),
            np.log(self.upper),
            0.0,
            np.inf,
            np.log(span),
        )

    def describe(self):
        return {"kind": "log-uniform", "lower": self.lower, "upper": self.upper}


@dataclass(frozen=True)
class TruncatedNormal(_OnePrior):
    """Normal N(mean, sd²) truncated to [lower, upper] (parameter units)."""

    mean: float
    sd: float
    lower: float
    upper: float

    def __post_init__(self):
        _check_bounds(self.lower, self.upper, "truncated-normal")
        if not (np.isfinite(self.mean) and np.isfinite(self.sd) and self.sd > 0):
            raise ValueError(f"truncated-normal prior needs a finite mean and sd > 0, got {self}")

    def _log_norm(self):
        a, b = (self.lower - self.mean) / self.sd, (self.upper - self.mean) / self.sd
        return np.log(self.sd) + np.log(ndtr(b) - ndtr(a)) + 0.5 * np.log(2 * np.pi)

    to_unbounded = Uniform.to_unbounded

    def form(self):
        return PriorForm(
            self.lower,
            self.upper,
            False,
            self.lower,
            self.upper,
            self.mean,
            self.sd,
            self._log_norm(),
        )

    def sample(self, rng, size):
        a, b = ndtr((self.lower - self.mean) / self.sd), ndtr((self.upper - self.mean) / self.sd)
        return self.mean + self.sd * ndtri(rng.uniform(a, b, size))

    def describe(self):
        return {
            "kind": "truncated-normal",
            "mean": self.mean,
            "sd": self.sd,
            "lower": self.lower,
            "upper": self.upper,
        }


@dataclass(frozen=True)
class TruncatedLogNormal(_OnePrior):
    """Log-normal with median ``median`` and log-sd ``sd_log``, truncated to [lower, upper]
    (parameter units, lower > 0). Sampled on the log scale, so that a quantity identified
    only as a product with another (ρv/ρg against the gain) lies on a straight ridge."""

    median: float
    sd_log: float
    lower: float
    upper: float

    def __post_init__(self):
        _check_bounds(self.lower, self.upper, "truncated-log-normal")
        if self.lower <= 0 or not (self.median > 0 and self.sd_log > 0):
            raise ValueError(f"truncated-log-normal prior needs lower, median, sd_log > 0: {self}")

    def _standard(self, x):
        return (np.log(x) - np.log(self.median)) / self.sd_log

    def _log_norm(self):
        a, b = self._standard(self.lower), self._standard(self.upper)
        return np.log(self.sd_log) + np.log(ndtr(b) - ndtr(a)) + 0.5 * np.log(2 * np.pi)

    to_unbounded = LogUniform.to_unbounded

    def form(self):
        w_lower, w_upper = np.log(self.lower), np.log(self.upper)
        return PriorForm(
            self.lower,
            self.upper,
            True,
            w_lower,
            w_upper,
            np.log(self.median),
            self.sd_log,
            self._log_norm(),
        )

    def sample(self, rng, size):
        a, b = ndtr(self._standard(self.lower)), ndtr(self._standard(self.upper))
        return self.median * np.exp(self.sd_log * ndtri(rng.uniform(a, b, size)))

    def describe(self):
        return {
            "kind": "truncated-log-normal",
            "median": self.median,
            "sd_log": self.sd_log,
            "lower": self.lower,
            "upper": self.upper,
        }


#: Prior kinds by name (the ``kind`` key of a priors file).
PRIOR_KINDS = {
    "uniform": Uniform,
    "log-uniform": LogUniform,
    "truncated-normal": TruncatedNormal,
    "truncated-log-normal": TruncatedLogNormal,
}


def make_prior(spec) -> object:
    """A prior from a mapping such as ``{"kind": "uniform", "lower": 0, "upper": 1}``."""
    spec = dict(spec)
    kind = spec.pop("kind", "uniform")
    try:
        factory = PRIOR_KINDS[kind]
    except KeyError:
        raise ValueError(f"unknown prior kind {kind!r}; known: {sorted(PRIOR_KINDS)}") from None
    try:
        return factory(**{key: float(value) for key, value in spec.items()})
    except TypeError as error:
        raise ValueError(f"{kind} prior: {error}") from None
