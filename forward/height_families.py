"""Tree-height distributions of parameterised stands, chosen through a registry.

Every family is parameterised by two numbers, ``mean`` and ``sd`` (m), documented per
family (:attr:`HeightFamily.meaning`), and has closed forms of its density, quantiles,
survival, raw moments and partial means (:attr:`HeightFamily.fast`) beside the scipy
distribution it is checked against.
"""

import math
from dataclasses import dataclass

import numpy as np
from scipy import stats
from scipy.special import gamma, gammaincc, ndtr, ndtri

_SQRT_2PI = math.sqrt(2.0 * math.pi)

_WEIBULL_SHAPES = np.geomspace(0.3, 200.0, 2000)
_WEIBULL_CV = np.sqrt(gamma(1 + 2 / _WEIBULL_SHAPES) / gamma(1 + 1 / _WEIBULL_SHAPES) ** 2 - 1)


def _weibull(mean, sd, truncation):
    """Weibull with the given mean and standard deviation (m); shape from the CV."""
    del truncation
    mean, sd = np.asarray(mean, float), np.asarray(sd, float)
    cv = sd / mean
    # the CV falls monotonically with the shape; interpolate in log space
    k = np.exp(np.interp(-cv, -_WEIBULL_CV, np.log(_WEIBULL_SHAPES)))
    return (k,), 0.0, mean / gamma(1 + 1 / k)


def _weibull_valid(mean, sd, truncation):
    del truncation
    cv = np.asarray(sd, float) / np.where(mean > 0, mean, 1.0)
    return (cv >= _WEIBULL_CV[-1]) & (cv <= _WEIBULL_CV[0])


def _lognormal(mean, sd, truncation):
    """Lognormal with the given mean and standard deviation (m)."""
    del truncation
    mean, sd = np.asarray(mean, float), np.asarray(sd, float)
    s2 = np.log1p((sd / mean) ** 2)
    return (np.sqrt(s2),), 0.0, mean * np.exp(-0.5 * s2)


def _truncnorm(mean, sd, truncation):
    """Normal N(mean, sd²) (the parent's mean and sd, m) truncated to mean ± truncation·sd
    and to positive heights."""
    mean, sd = np.asarray(mean, float), np.asarray(sd, float)
    low = np.maximum(-truncation, -mean / sd)
    return (low, np.full_like(low, truncation)), mean, sd


def _raw_moments(standard, orders, loc, scale):
    """E[h^k] for h = loc + scale·x, from the standard moments ``standard[j]`` = E[x^j]
    (a list, j ≤ max(orders)): Σ_j C(k, j)·loc^(k−j)·scale^j·E[x^j], by Horner's rule in
    loc. The orders k (ints) form the last axis of the result."""
    loc, scale = np.asarray(loc, float), np.asarray(scale, float)
    scaled, power = [standard[0]], 1.0
    for moment in standard[1:]:
        power = power * scale
        scaled.append(moment * power)  # E[(scale·x)^j]
    out = []
    for k in orders:
        acc = scaled[0]
        for j in range(1, k + 1):
            acc = acc * loc + math.comb(k, j) * scaled[j]
        out.append(acc)
    return np.stack(out, axis=-1)


# Closed forms through scipy.special for the hot path of the batched model: scipy.stats
# method calls cost 0.1–0.5 ms each in argument handling, more than the model itself.
# ``which = "moments"`` takes the orders k (a tuple of ints) as ``x`` and returns E[h^k]
# on a last axis.
def _weibull_fast(which, x, args, loc, scale):
    (k,) = args
    if which == "moments":
        shape = np.asarray(k, float)
        standard = [gamma(1.0 + j / shape) for j in range(max(x) + 1)]
        return _raw_moments(standard, x, loc, scale)
    if which == "pdf":
        y = np.maximum(x - loc, 0.0) / scale
        log_y = np.log(np.maximum(y, 1e-300))
        # k/λ·y^(k−1)·exp(−y^k) with one logarithm and two exponentials
        dens = k / scale * np.exp((k - 1) * log_y - np.exp(k * log_y))
        at_zero = k / scale * np.where(k < 1, np.inf, np.where(k == 1, 1.0, 0.0))
        return np.where(x >= loc, np.where(y > 0, dens, at_zero), 0.0)
    if which == "sf":
        return np.exp(-((np.maximum(x - loc, 0.0) / scale) ** k))
    if which == "mean_above":  # λ·Γ(1 + 1/k)·Q(1 + 1/k, y^k) + loc·S
        y_k = (np.maximum(x - loc, 0.0) / scale) ** k
        shape = 1.0 + 1.0 / k
        return scale * gamma(shape) * gammaincc(shape, y_k) + loc * np.exp(-y_k)
    tail = -np.log1p(-x) if which == "ppf" else -np.log(x)
    return loc + scale * tail ** (1.0 / k)


def _lognormal_fast(which, x, args, loc, scale):
    (sigma,) = args
    if which == "moments":
        s2 = np.asarray(sigma, float) ** 2
        return _raw_moments([np.exp(0.5 * j * j * s2) for j in range(max(x) + 1)], x, loc, scale)
    if which == "pdf":
        y = np.maximum(x - loc, 1e-300) / scale
        dens = np.exp(-0.5 * (np.log(y) / sigma) ** 2) / (y * scale * sigma * np.sqrt(2 * np.pi))
        return np.where(x > loc, dens, 0.0)
    if which == "sf":
        with np.errstate(divide="ignore"):
            return ndtr(-np.log(np.maximum(x - loc, 0.0) / scale) / sigma)
    if which == "mean_above":  # scale·e^{σ²/2}·Φ(σ − ln(y)/σ) + loc·S
        with np.errstate(divide="ignore"):
            log_y = np.log(np.maximum(x - loc, 0.0) / scale)
        above = scale * np.exp(0.5 * sigma**2) * ndtr(sigma - log_y / sigma)
        return above + loc * ndtr(-log_y / sigma)
    sign = 1.0 if which == "ppf" else -1.0
    return loc + scale * np.exp(sign * sigma * ndtri(x))


def _truncnorm_fast(which, x, args, loc, scale):
    a, b = args
    low, high = ndtr(a), ndtr(b)
    if which == "moments":
        standard = _truncated_standard_moments(a, b, high - low, max(x))
        return _raw_moments(standard, x, loc, scale)
    if which == "pdf":
        y = (x - loc) / scale
        dens = np.exp(-0.5 * y * y) / (np.sqrt(2 * np.pi) * scale * (high - low))
        return np.where((y >= a) & (y <= b), dens, 0.0)
    if which == "sf":
        y = np.clip((x - loc) / scale, a, b)
        return np.clip((high - ndtr(y)) / (high - low), 0.0, 1.0)
    if which == "mean_above":  # [loc·(Φ(b) − Φ(y)) + scale·(φ(y) − φ(b))] / (Φ(b) − Φ(a))
        y = np.clip((x - loc) / scale, a, b)
        mass = ndtr(-y) - ndtr(-b)  # upper-tail form: no cancellation near b
        density = (np.exp(-0.5 * y * y) - np.exp(-0.5 * b * b)) / np.sqrt(2 * np.pi)
        return (loc * mass + scale * density) / (high - low)
    p = low + x * (high - low) if which == "ppf" else high - x * (high - low)
    return loc + scale * ndtri(p)


def _truncated_standard_moments(a, b, mass, top):
    """[E[x^j] for j ≤ ``top``] of the standard normal truncated to [a, b] (mass
    Φ(b) − Φ(a)): m_j = (j − 1)·m_{j−2} + (a^{j−1}φ(a) − b^{j−1}φ(b))/mass."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    edge_a = np.exp(-0.5 * a * a) / (_SQRT_2PI * mass)  # φ(a)/mass
    edge_b = np.exp(-0.5 * b * b) / (_SQRT_2PI * mass)
    moments = [np.ones_like(a), edge_a - edge_b]
    for j in range(2, top + 1):
        edge_a, edge_b = edge_a * a, edge_b * b
        moments.append((j - 1) * moments[j - 2] + edge_a - edge_b)
    return moments[: top + 1]


def _always_valid(mean, sd, truncation):
    del truncation
    return np.ones(np.broadcast(mean, sd).shape, bool)


@dataclass(frozen=True)
class HeightFamily:
    """A two-parameter height distribution.

    Attributes
    ----------
    name : str
    dist : scipy.stats.rv_continuous
        The scipy distribution (the reference the closed forms are tested against).
    arguments : callable
        ``arguments(mean, sd, truncation) -> (shape_args, loc, scale)`` for ``dist``
        (array-aware).
    valid : callable
        ``valid(mean, sd, truncation) -> bool array``: extra validity beyond mean, sd > 0.
    meaning : str
        What ``mean`` and ``sd`` mean for this family.
    fast : callable
        ``fast(which, x, args, loc, scale)`` for ``which`` in pdf/ppf/isf/sf/mean_above/
        moments: the same functions in closed form through scipy.special (array-aware, no
        scipy.stats overhead); :meth:`pdf`, :meth:`ppf`, :meth:`isf`, :meth:`sf`,
        :meth:`mean_above` and :meth:`raw_moments` use it.
    """

    name: str
    dist: object
    arguments: object
    valid: object
    meaning: str
    fast: object

    def frozen(self, mean, sd, truncation=2.0):
        """Frozen scipy distribution (convenient, but slow to build: not for hot loops).

        Parameters
        ----------
        mean, sd : float (m)
            As :attr:`meaning` says for the family.
        truncation : float (sd units)

        Returns
        -------
        scipy.stats.rv_frozen
        """
        args, loc, scale = self.arguments(mean, sd, truncation)
        return self.dist(*args, loc=loc, scale=scale)

    def pdf(self, x, mean, sd, truncation=2.0):
        """Height density.

        Parameters
        ----------
        x : float or array (m)
        mean, sd : float or array (m)
        truncation : float (sd units)

        Returns
        -------
        float or array (1/m)
        """
        return self.fast("pdf", x, *self.arguments(mean, sd, truncation))

    def ppf(self, q, mean, sd, truncation=2.0):
        """Height below which a fraction of the trees lies.

        Parameters
        ----------
        q : float or array
        mean, sd : float or array (m)
        truncation : float (sd units)

        Returns
        -------
        float or array (m)
        """
        return self.fast("ppf", q, *self.arguments(mean, sd, truncation))

    def isf(self, q, mean, sd, truncation=2.0):
        """Height above which a fraction of the trees lies.

        Parameters
        ----------
        q : float or array
        mean, sd : float or array (m)
        truncation : float (sd units)

        Returns
        -------
        float or array (m)
        """
        return self.fast("isf", q, *self.arguments(mean, sd, truncation))

    def sf(self, x, mean, sd, truncation=2.0):
        """Fraction of the trees taller than a height.

        Parameters
        ----------
        x : float or array (m)
        mean, sd : float or array (m)
        truncation : float (sd units)

        Returns
        -------
        float or array
            S(x).
        """
        return self.fast("sf", x, *self.arguments(mean, sd, truncation))

    def raw_moments(self, orders, mean, sd, truncation=2.0):
        """Raw moments of tree height, in closed form.

        Parameters
        ----------
        orders : sequence of int
        mean, sd : float or array (m)
        truncation : float (sd units)

        Returns
        -------
        array (..., len(orders)) (m^k)
            E[h^k] for each order k, on a last axis.
        """
        orders = tuple(int(k) for k in np.ravel(orders))
        return self.fast("moments", orders, *self.arguments(mean, sd, truncation))

    def mean_above(self, x, mean, sd, truncation=2.0):
        """Partial mean of the trees taller than a height, in closed form.

        Parameters
        ----------
        x : float or array (m)
        mean, sd : float or array (m)
        truncation : float (sd units)

        Returns
        -------
        float or array (m)
            ∫ₓ^∞ h·f(h) dh; divided by :meth:`sf`, the trees' mean height.
        """
        return self.fast("mean_above", x, *self.arguments(mean, sd, truncation))


#: Height-distribution families by name.
HEIGHT_DISTRIBUTIONS: dict[str, HeightFamily] = {
    "weibull": HeightFamily(
        "weibull",
        stats.weibull_min,
        _weibull,
        _weibull_valid,
        "mean and sd of the distribution (CV 0.007–3.5)",
        _weibull_fast,
    ),
    "lognormal": HeightFamily(
        "lognormal",
        stats.lognorm,
        _lognormal,
        _always_valid,
        "mean and sd of the distribution",
        _lognormal_fast,
    ),
    "truncnorm": HeightFamily(
        "truncnorm",
        stats.truncnorm,
        _truncnorm,
        _always_valid,
        "mean and sd of the parent normal, truncated at ±truncation·sd and at 0",
        _truncnorm_fast,
    ),
}


def height_distribution(family, mean, sd, truncation=2.0):
    """Frozen scipy distribution of tree height for one family (array-aware).

    Parameters
    ----------
    family : str
        A key of :data:`HEIGHT_DISTRIBUTIONS`.
    mean, sd : float or array (m)
    truncation : float (sd units)

    Returns
    -------
    scipy.stats.rv_frozen

    Raises
    ------
    ValueError
        For an unknown family.
    """
    try:
        return HEIGHT_DISTRIBUTIONS[family].frozen(mean, sd, truncation)
    except KeyError:
        raise ValueError(
            f"unknown height distribution {family!r}; known: {sorted(HEIGHT_DISTRIBUTIONS)}"
        ) from None
