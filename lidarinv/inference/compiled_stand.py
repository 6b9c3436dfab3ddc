"""The stand mapping for truncated-normal heights (the default template), compiled.

:meth:`.stand_mapping.StandMapping.model_vectors` for the ``truncnorm`` family in two
passes over the rows, instead of some forty numpy calls on short arrays: the raw moments
E[h^k] (k ≤ 3) of N(mean, sd²) truncated to [mean + a·sd, mean + b·sd], the Poisson-stand
identities for stem density and FAVD, and the dominant height, whose cut needs the
inverse normal CDF (scipy's ``ndtri``, called between the passes). The numpy path is the
reference (``tests/test_inference_stand_mapping.py``).
"""

import math

import numpy as np
from numba import njit
from scipy.special import ndtri

from .compiled import normal_cdf as _cdf

_SQRT_2PI = math.sqrt(2.0 * math.pi)

#: Columns of the array :func:`stand_columns` returns.
COLUMNS = ("density_m2", "mean", "favd", "crown_area", "mean_height", "volume", "dominant")


@njit(cache=True)
def _pdf(x):
    return math.exp(-0.5 * x * x) / _SQRT_2PI


@njit(cache=True)
def _stand_columns(top, sd, cover, pai, ratio, slope, cone, r0, top_sds, t, vol, leaf, per_ha):
    n = top.size
    out = np.empty((n, 8))
    for i in range(n):
        mean = top[i] - top_sds * sd[i]
        a = max(-t, -mean / sd[i])
        mass = _cdf(t) - _cdf(a)
        pa, pb = _pdf(a) / mass, _pdf(t) / mass
        s1 = pa - pb  # standard moments of the truncated normal
        s2 = 1.0 + a * pa - t * pb
        s3 = 2.0 * s1 + a * a * pa - t * t * pb
        m, s = mean, sd[i]
        m1 = m + s * s1
        m2 = m * m + 2.0 * m * s * s1 + s * s * s2
        m3 = m * m * m + 3.0 * m * m * s * s1 + 3.0 * m * s * s * s2 + s * s * s * s3
        r1 = slope[i]
        area = math.pi * (r0 * r0 + 2.0 * r0 * r1 * m1 + r1 * r1 * m2)  # E[π R²]
        crown = math.pi * (r0 * r0 * m1 + 2.0 * r0 * r1 * m2 + r1 * r1 * m3) * ratio[i]
        lam = -math.log1p(-cover[i]) / area
        mix_vol = cone[i] * vol[0] + (1.0 - cone[i]) * vol[1]
        mix_leaf = cone[i] * leaf[0] + (1.0 - cone[i]) * leaf[1]
        tail = min(max(per_ha / (lam * 1e4), 1e-9), 1.0)
        out[i, 0] = lam
        out[i, 1] = mean
        out[i, 2] = pai[i] / (lam * crown * mix_leaf)
        out[i, 3] = area
        out[i, 4] = m1
        out[i, 5] = lam * crown * mix_vol
        out[i, 6] = tail
        out[i, 7] = _cdf(t) - tail * mass  # Φ of the dominant stems' cut
    return out


@njit(cache=True)
def _dominant_heights(out, quantile, sd, t):
    """Mean height of the trees above each row's cut (column 6 of ``out``, overwritten),
    from the cut's standard normal score: [mean·(Φ(b) − Φ(y)) + sd·(φ(y) − φ(b))] /
    mass / tail."""
    for i in range(out.shape[0]):
        mean, tail = out[i, 1], out[i, 6]
        a = max(-t, -mean / sd[i])
        mass = _cdf(t) - _cdf(a)
        y = min(max(quantile[i], a), t)
        above = _cdf(-y) - _cdf(-t)  # upper-tail form: no cancellation near b
        density = _pdf(y) - _pdf(t)
        out[i, 6] = (mean * above + sd[i] * density) / mass / tail


#: Parameters read by :func:`stand_columns`, in the kernel's order.
_INPUTS = (
    "top_height",
    "height_sd",
    "cover",
    "pai",
    "crown_length_ratio",
    "crown_radius_slope",
    "cone_fraction",
)


def stand_columns(v, r0, top_sds, truncation, volume, leaf, per_ha):
    """(n, 7) array of the :data:`COLUMNS` (stems/m², m, m²/m³, m², m, m³/m², m) per row
    of parameters ``v`` (name → (n,) arrays); rows must be valid.

    Heights are normal, truncated at ±``truncation`` sd and at zero, with top = mean +
    ``top_sds``·sd; ``r0`` is the crown-radius intercept (m); ``volume`` and ``leaf`` the
    shape pair's volume and leaf-volume fractions (2,); the dominant height is the mean
    of the ``per_ha`` tallest stems per hectare (all if fewer).
    """
    args = [np.ascontiguousarray(v[name], dtype=np.float64) for name in _INPUTS]
    t = float(truncation)
    out = _stand_columns(*args, float(r0), float(top_sds), t, volume, leaf, float(per_ha))
    _dominant_heights(out, ndtri(out[:, 7]), args[1], t)
    return out[:, :7]
