"""Priors on inversion parameters, chosen through a registry, and their unbounded maps.

Every prior here is proper and bounded, so each parameter maps to the real line by
w = w_lower + (w_upper − w_lower)·f(u), with w = x (uniform and truncated normal) or
w = log x (log-uniform and truncated log-normal), and f a CDF from
:data:`.prior_table.UNBOUNDED_MAPS`: the logistic one (``logit``, the default) or the normal one
(``probit``). The sampler works in u; the log-density in u adds log|dx/du|. Under a
uniform prior u is then logistic (``logit``) or N(0, 1) (``probit``); where the data push
a parameter against a bound, its tail in u falls off only exponentially under ``logit``
but like a Gaussian under ``probit``.
"""

import inspect
from dataclasses import dataclass

import numpy as np
from scipy.special import ndtr, ndtri

from .prior_table import DEFAULT_UNBOUNDED, PriorForm, PriorTable


def _check_bounds(lower, upper, kind):
    if not (np.isfinite(lower) and np.isfinite(upper) and lower < upper):
        raise ValueError(
            f"{kind} prior needs finite bounds with lower < upper, got {lower}, {upper}"
        )


class _OnePrior:
    """log_pdf and the unbounded maps of a single prior, through its :class:`PriorForm`."""

    def log_pdf(self, x):
        """Log density at ``x`` (parameter units); −inf outside the support."""
        x = np.asarray(x, float)
        return PriorTable([self]).log_pdf(x[..., None])[..., 0]

    def from_unbounded(self, u, unbounded=DEFAULT_UNBOUNDED):
        """Parameter values and log|dx/du| for unbounded values ``u``."""
        table = PriorTable([self], unbounded)
        x, log_jac = table.from_unbounded(np.asarray(u, float)[..., None])
        return x[..., 0], log_jac[..., 0]

    def to_unbounded(self, x, unbounded=DEFAULT_UNBOUNDED):
        """Unbounded values of parameter values ``x``."""
        return PriorTable([self], unbounded).to_unbounded(np.asarray(x, float)[..., None])[..., 0]


@dataclass(frozen=True)
class Uniform(_OnePrior):
    """Uniform on [lower, upper] (parameter units)."""

    lower: float
    upper: float

    def __post_init__(self):
        _check_bounds(self.lower, self.upper, "uniform")

    def sample(self, rng, size):
        """Draws from the prior.

        Parameters
        ----------
        rng : numpy.random.Generator
        size : int

        Returns
        -------
        array (size,)
        """
        return rng.uniform(self.lower, self.upper, size)

    def form(self):
        """The prior in the common form.

        Returns
        -------
        PriorForm
        """
        span = self.upper - self.lower
        return PriorForm(
            self.lower, self.upper, False, self.lower, self.upper, 0.0, np.inf, np.log(span)
        )

    def describe(self):
        """The prior as a JSON-ready dict.

        Returns
        -------
        dict
        """
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

    def sample(self, rng, size):
        """Draws from the prior.

        Parameters
        ----------
        rng : numpy.random.Generator
        size : int

        Returns
        -------
        array (size,)
        """
        return np.exp(rng.uniform(np.log(self.lower), np.log(self.upper), size))

    def form(self):
        """The prior in the common form (w = ln x).

        Returns
        -------
        PriorForm
        """
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
        """The prior as a JSON-ready dict.

        Returns
        -------
        dict
        """
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

    def form(self):
        """The prior in the common form.

        Returns
        -------
        PriorForm
        """
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
        """Draws from the prior, by inversion of the truncated CDF.

        Parameters
        ----------
        rng : numpy.random.Generator
        size : int

        Returns
        -------
        array (size,)
        """
        a, b = ndtr((self.lower - self.mean) / self.sd), ndtr((self.upper - self.mean) / self.sd)
        return self.mean + self.sd * ndtri(rng.uniform(a, b, size))

    def describe(self):
        """The prior as a JSON-ready dict.

        Returns
        -------
        dict
        """
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

    def form(self):
        """The prior in the common form (w = ln x).

        Returns
        -------
        PriorForm
        """
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
        """Draws from the prior, by inversion of the truncated CDF.

        Parameters
        ----------
        rng : numpy.random.Generator
        size : int

        Returns
        -------
        array (size,)
        """
        a, b = ndtr(self._standard(self.lower)), ndtr(self._standard(self.upper))
        return self.median * np.exp(self.sd_log * ndtri(rng.uniform(a, b, size)))

    def describe(self):
        """The prior as a JSON-ready dict.

        Returns
        -------
        dict
        """
        return {
            "kind": "truncated-log-normal",
            "median": self.median,
            "sd_log": self.sd_log,
            "lower": self.lower,
            "upper": self.upper,
        }


@dataclass(frozen=True)
class TruncatedNormalMixture(_OnePrior):
    """Two normals, N(mean, sd²) of weight 1 − ``alt_weight`` and N(alt_mean, alt_sd²) of
    weight ``alt_weight``, each truncated to [lower, upper] (parameter units): a
    parameter the data show at one of two places (a ground under a closed canopy).

    Its :meth:`form` carries the support and the first component only (the unbounded map
    is uniform over the support whatever the density); :meth:`exact_log_pdf` is the
    mixture's density, which :class:`.prior_table.PriorTable` uses instead of the form's.
    """

    mean: float
    sd: float
    alt_mean: float
    alt_sd: float
    alt_weight: float
    lower: float
    upper: float

    def __post_init__(self):
        _check_bounds(self.lower, self.upper, "truncated-normal-mixture")
        for mean, sd in ((self.mean, self.sd), (self.alt_mean, self.alt_sd)):
            if not (np.isfinite(mean) and np.isfinite(sd) and sd > 0):
                raise ValueError(f"a mixture's component needs a finite mean and sd > 0: {self}")
        if not 0.0 < self.alt_weight < 1.0:
            raise ValueError(f"a mixture's alt_weight must lie in (0, 1), got {self.alt_weight}")

    def components(self) -> tuple:
        """The two components as :class:`TruncatedNormal`, and their weights."""
        first = TruncatedNormal(self.mean, self.sd, self.lower, self.upper)
        second = TruncatedNormal(self.alt_mean, self.alt_sd, self.lower, self.upper)
        return (first, second), (1.0 - self.alt_weight, self.alt_weight)

    def component_log_pdf(self, x) -> np.ndarray:
        """log(w_k·p_k(x)) of each component (..., 2); −inf outside the support."""
        x = np.asarray(x, float)
        (first, second), weights = self.components()
        inside = (x >= self.lower) & (x <= self.upper)
        terms = []
        for part, weight in zip((first, second), weights):
            z = (x - part.mean) / part.sd
            terms.append(np.where(inside, np.log(weight) - 0.5 * z * z - part._log_norm(), -np.inf))
        return np.stack(terms, axis=-1)

    def exact_log_pdf(self, x) -> np.ndarray:
        """The mixture's log density at ``x``; −inf outside the support and for NaN."""
        with np.errstate(invalid="ignore"):
            total = np.logaddexp.reduce(self.component_log_pdf(x), axis=-1)
        return np.where(np.isfinite(total), total, -np.inf)

    def responsibilities(self, x) -> np.ndarray:
        """P(component k | x) (..., 2): how much of each value the second component explains."""
        terms = self.component_log_pdf(x)
        with np.errstate(invalid="ignore"):
            return np.exp(terms - np.logaddexp.reduce(terms, axis=-1)[..., None])

    def form(self):
        """The support, with the first component's Gaussian (see the class).

        Returns
        -------
        PriorForm
        """
        return TruncatedNormal(self.mean, self.sd, self.lower, self.upper).form()

    def sample(self, rng, size):
        """Draws from the mixture.

        Parameters
        ----------
        rng : numpy.random.Generator
        size : int

        Returns
        -------
        array (size,)
        """
        (first, second), _ = self.components()
        second_part = rng.uniform(size=size) < self.alt_weight
        return np.where(second_part, second.sample(rng, size), first.sample(rng, size))

    def describe(self):
        """The prior as a JSON-ready dict.

        Returns
        -------
        dict
        """
        return {
            "kind": "truncated-normal-mixture",
            **{k: getattr(self, k) for k in ("mean", "sd", "alt_mean", "alt_sd", "alt_weight")},
            "lower": self.lower,
            "upper": self.upper,
        }


#: Prior kinds by name (the ``kind`` key of a priors file).
PRIOR_KINDS = {
    "uniform": Uniform,
    "log-uniform": LogUniform,
    "truncated-normal": TruncatedNormal,
    "truncated-log-normal": TruncatedLogNormal,
    "truncated-normal-mixture": TruncatedNormalMixture,
}


def make_prior(spec) -> object:
    """A prior from a mapping such as ``{"kind": "uniform", "lower": 0, "upper": 1}``.

    Parameters
    ----------
    spec : mapping
        ``kind`` (a key of :data:`PRIOR_KINDS`, default ``uniform``) and the kind's
        numbers.

    Returns
    -------
    Uniform, LogUniform, TruncatedNormal or TruncatedLogNormal

    Raises
    ------
    ValueError
        For an unknown kind, an unknown, missing or non-numeric number.
    """
    spec = dict(spec)
    kind = spec.pop("kind", "uniform")
    try:
        factory = PRIOR_KINDS[kind]
    except KeyError:
        raise ValueError(f"unknown prior kind {kind!r}; known: {sorted(PRIOR_KINDS)}") from None
    parameters = inspect.signature(factory).parameters
    accepted = list(parameters)
    unknown = sorted(set(spec) - set(accepted))
    if unknown:
        raise ValueError(f"a {kind} prior takes kind and {accepted}, not {unknown}")
    missing = [k for k, p in parameters.items() if p.default is p.empty and k not in spec]
    if missing:
        raise ValueError(f"a {kind} prior needs {missing}")
    values = {}
    for key, value in spec.items():
        try:
            values[key] = float(value)
        except (TypeError, ValueError):
            raise ValueError(f"{kind} prior: {key} must be a number, got {value!r}") from None
    return factory(**values)
