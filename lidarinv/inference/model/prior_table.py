"""Priors in one common form, evaluated together and mapped to the real line, compiled.

Every prior kind of :mod:`.priors` writes itself as a :class:`PriorForm`: bounds, a log
or linear scale and a (possibly flat) Gaussian in w. :class:`PriorTable` evaluates a
column of priors per row in one compiled pass and maps them to unbounded coordinates by
a CDF of :data:`UNBOUNDED_MAPS`.
"""

import math
from dataclasses import dataclass

import numpy as np
from scipy.special import logit, ndtri

from forward.backends import jit

_SQRT2 = math.sqrt(2.0)


@dataclass(frozen=True)
class PriorForm:
    """A prior written in the common form shared by every kind here.

    The support is x ∈ [lower, upper]. With w = log x (``log_scale``) or w = x, it is
    w ∈ [w_lower, w_upper] and log p(x) = −[log_scale]·ln x − ½((w − w_mean)/w_sd)² −
    log_norm (w_sd = ∞ for the uniform kinds); the unbounded coordinate is
    u = F⁻¹((w − w_lower)/(w_upper − w_lower)), F a CDF of :data:`UNBOUNDED_MAPS`.
    """

    lower: float
    upper: float
    log_scale: bool
    w_lower: float
    w_upper: float
    w_mean: float
    w_sd: float
    log_norm: float


@jit
def log_prior_form(x, lower, upper, log_scale, w_mean, w_sd, log_norm):
    """log p(x) of a prior in the common form of :class:`PriorForm`."""
    if not (lower <= x <= upper):
        return -math.inf
    log_x = math.log(x) if log_scale else 0.0
    y = ((log_x if log_scale else x) - w_mean) / w_sd  # 0 for the uniform kinds (sd = ∞)
    return -log_x - 0.5 * y * y - log_norm


@jit
def _prior_log_pdf(x, lower, upper, log_scale, w_mean, w_sd, log_norm):
    n, k = x.shape
    out = np.empty((n, k))
    for r in range(n):
        for c in range(k):
            out[r, c] = log_prior_form(
                x[r, c], lower[c], upper[c], log_scale[c], w_mean[c], w_sd[c], log_norm[c]
            )
    return out


@jit
def normal_cdf(x):
    """The standard normal CDF (compiled).

    Parameters
    ----------
    x : float

    Returns
    -------
    float
        Φ(x) = erfc(−x/√2)/2, accurate in both tails.
    """
    return 0.5 * math.erfc(-x / _SQRT2)


#: Codes of the unbounded maps in the compiled kernel (:data:`UNBOUNDED_MAPS`).
LOGIT, PROBIT = 0, 1

_LOG_SQRT_2PI = 0.5 * math.log(2.0 * math.pi)


@jit
def unit_and_log_slope(t, kind):
    """f(t) ∈ [0, 1] and log f′(t) of the logistic (``LOGIT``) or normal (``PROBIT``) CDF,
    without overflow either side."""
    if kind == PROBIT:
        return normal_cdf(t), -0.5 * t * t - _LOG_SQRT_2PI
    if t >= 0.0:
        e = math.exp(-t)
        return 1.0 / (1.0 + e), -t - 2.0 * math.log1p(e)
    e = math.exp(t)
    return e / (1.0 + e), t - 2.0 * math.log1p(e)


@jit
def _prior_from_unbounded(u, w_lower, span, log_scale, lower, upper, kind):
    n, k = u.shape
    x = np.empty((n, k))
    log_jac = np.empty((n, k))
    for r in range(n):
        for c in range(k):
            unit, log_slope = unit_and_log_slope(u[r, c], kind)
            w = w_lower[c] + span[c] * unit
            jac = math.log(span[c]) + log_slope
            value = w
            if log_scale[c]:
                value = math.exp(w)
                jac += w
            x[r, c] = min(max(value, lower[c]), upper[c])  # exp(log upper) may round above
            log_jac[r, c] = jac
    return x, log_jac


def prior_log_pdf(x, lower, upper, log_scale, w_mean, w_sd, log_norm) -> np.ndarray:
    """Log densities of the columns of x under priors in the common form (compiled).

    Parameters
    ----------
    x : array (n, k)
    lower, upper, log_scale, w_mean, w_sd, log_norm : arrays (k,)
        The :class:`PriorForm` of each column's prior.

    Returns
    -------
    array (n, k)
        −[log_scale]·ln x − ½((w − w_mean)/w_sd)² − log_norm within [lower, upper]; −inf
        outside each support and for NaN.
    """
    return _prior_log_pdf(
        np.ascontiguousarray(x, dtype=np.float64), lower, upper, log_scale, w_mean, w_sd, log_norm
    )


def prior_from_unbounded(u, w_lower, span, log_scale, lower, upper, kind=LOGIT):
    """Values and log-Jacobians of unbounded coordinates (compiled).

    Parameters
    ----------
    u : array (n, k)
    w_lower, span, log_scale, lower, upper : arrays (k,)
        Of each column's :class:`PriorForm` (span = w_upper − w_lower).
    kind : int
        :data:`LOGIT` or :data:`PROBIT`.

    Returns
    -------
    x : array (n, k)
        w = w_lower + span·f(u), f the logistic or normal CDF; x = w, or exp(w) for
        log-scale columns, within [lower, upper].
    log_jac : array (n, k)
        log|dx/du|.
    """
    return _prior_from_unbounded(
        np.ascontiguousarray(u, dtype=np.float64), w_lower, span, log_scale, lower, upper, kind
    )


@dataclass(frozen=True)
class UnboundedMap:
    """A CDF f that maps u ∈ ℝ onto the unit interval of a prior's support, with its
    inverse (numpy) and its code in the compiled kernel (:data:`LOGIT`, :data:`PROBIT`)."""

    code: int
    inverse: object


#: Unbounded maps by name (``InversionSettings.unbounded``). Neither is better on every
#: shot: ``probit`` helps where a parameter piles against a bound (its tail in u falls off
#: like a Gaussian), ``logit`` where the slowest direction lies inside the prior
#: (``studies/inversion_speed.py --unbounded`` compares them).
UNBOUNDED_MAPS = {
    "logit": UnboundedMap(LOGIT, logit),
    "probit": UnboundedMap(PROBIT, ndtri),
}

#: The default unbounded map.
DEFAULT_UNBOUNDED = "logit"


def unbounded_map(name) -> UnboundedMap:
    """The :data:`UNBOUNDED_MAPS` entry of a name.

    Parameters
    ----------
    name : str

    Returns
    -------
    UnboundedMap

    Raises
    ------
    ValueError
        Naming the known maps.
    """
    try:
        return UNBOUNDED_MAPS[name]
    except KeyError:
        raise ValueError(
            f"unknown unbounded map {name!r}; known: {sorted(UNBOUNDED_MAPS)}"
        ) from None


class PriorTable:
    """Several priors evaluated together, column by column of an (n, k) array, in one
    compiled pass (:func:`prior_log_pdf`, :func:`prior_from_unbounded`).

    Parameters
    ----------
    priors : sequence of priors with a ``form()`` method
    unbounded : str
        Name of the map to the real line, from :data:`UNBOUNDED_MAPS`.
    """

    def __init__(self, priors, unbounded=DEFAULT_UNBOUNDED):
        priors = list(priors)
        forms = [p.form() for p in priors]
        self._map = unbounded_map(unbounded)
        self._log = np.array([f.log_scale for f in forms], np.bool_)
        self._lower = np.array([f.w_lower for f in forms], float)
        self._span = np.array([f.w_upper - f.w_lower for f in forms], float)
        self._mean = np.array([f.w_mean for f in forms], float)
        self._sd = np.array([f.w_sd for f in forms], float)
        self._norm = np.array([f.log_norm for f in forms], float)
        self._x_lower = np.array([f.lower for f in forms], float)
        self._x_upper = np.array([f.upper for f in forms], float)
        # priors whose density the common form cannot write (a mixture): their own, in numpy
        self._exact = [(c, p) for c, p in enumerate(priors) if hasattr(p, "exact_log_pdf")]

    def log_pdf(self, x) -> np.ndarray:
        """Log densities of the columns of x.

        Parameters
        ----------
        x : array (..., k)

        Returns
        -------
        array (..., k)
            −inf outside each support.
        """
        x = np.asarray(x, float)
        flat = x.reshape(-1, x.shape[-1]) if x.ndim != 2 else x
        density = prior_log_pdf(
            flat, self._x_lower, self._x_upper, self._log, self._mean, self._sd, self._norm
        )
        for column, prior in self._exact:
            density[:, column] = prior.exact_log_pdf(flat[:, column])
        return density.reshape(x.shape)

    def from_unbounded(self, u):
        """Values and log|dx/du| of unbounded coordinates.

        Parameters
        ----------
        u : array (..., k)

        Returns
        -------
        x, log_jac : arrays (..., k)
        """
        u = np.asarray(u, float)
        flat = u.reshape(-1, u.shape[-1]) if u.ndim != 2 else u
        x, log_jac = prior_from_unbounded(
            flat, self._lower, self._span, self._log, self._x_lower, self._x_upper, self._map.code
        )
        return x.reshape(u.shape), log_jac.reshape(u.shape)

    def to_unbounded(self, x):
        """Unbounded coordinates of values: the inverse of :meth:`from_unbounded`.

        Parameters
        ----------
        x : array (..., k)

        Returns
        -------
        array (..., k)
            ±inf at the bounds.
        """
        x = np.asarray(x, float)
        with np.errstate(divide="ignore", invalid="ignore"):
            w = np.where(self._log, np.log(x), x)
            return self._map.inverse((w - self._lower) / self._span)
