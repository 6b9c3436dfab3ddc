"""The stand quantities of parameter rows: the Poisson-stand identities, numpy and compiled.

:func:`stand_columns` gives, per row of the default parameterisation, the stem density
and FAVD that cover and PAI imply, the mean height, crown area and volume and the dominant
height: the identities of :mod:`forward.poisson_stand` over the closed-form raw moments
E[h^k] of the height family. Its compiled kernel (truncated-normal heights) computes the
same in two passes over the rows (scipy's ``ndtri`` between them), calling the same
identity functions compiled.
"""

import math

import numpy as np
from scipy.special import ndtri

from forward import poisson_stand
from forward.backends import jit, resolve

from .prior_table import normal_cdf as _cdf

#: Stems per hectare whose mean height is the dominant height.
DOMINANT_PER_HA = 100.0

#: Columns of the array :func:`stand_columns` returns.
COLUMNS = ("density_m2", "mean", "favd", "crown_area", "mean_height", "volume", "dominant")


def stand_columns(v, r0, top_sds, family, truncation, volume, leaf, per_ha, *, backend="auto"):
    """Stand quantities per row of parameters: the Poisson-stand identities.

    Parameters
    ----------
    v : dict
        ``top_height`` (m), ``height_sd`` (m), ``cover``, ``pai`` (m²/m²),
        ``crown_length_ratio``, ``crown_radius_slope`` (m/m), ``cone_fraction``: (n,) each;
        rows must be valid.
    r0 : float or array (n,) (m)
        Crown-radius intercept.
    top_sds : float
        Mean height = top − ``top_sds``·sd.
    family : forward.stand_params.HeightFamily
    truncation : float (sd units)
    volume, leaf : array (2,)
        The shape pair's volume fractions v_s and leaf-volume fractions κ_s·v_s.
    per_ha : float (stems/ha)
        The dominant height is the mean of the ``per_ha`` tallest stems per hectare (all
        if fewer).
    backend : str
        ``"auto"``, ``"numba"`` or ``"numpy"``; compiled for ``truncnorm`` heights only.

    Returns
    -------
    array (n, 7)
        The :data:`COLUMNS`: density λ (stems/m²), height mean (m), FAVD (m²/m³), crown
        area E[π R²] (m²), mean height E[h] (m), crown volume (m³/m²), dominant height (m).

    Notes
    -----
    λ = −ln(1 − c)/E[π R²], FAVD = L/(λ·E[π R² ℓ h]·Σ m_s κ_s v_s), crown volume
    λ·E[π R² ℓ h]·Σ m_s v_s (:mod:`forward.poisson_stand`), from the raw moments
    E[h], E[h²], E[h³] of the height family.
    """
    if resolve(backend) == "numba" and family.name == "truncnorm":
        args = [np.ascontiguousarray(v[name], dtype=np.float64) for name in _INPUTS]
        r0 = np.ascontiguousarray(np.broadcast_to(np.asarray(r0, float), args[0].shape))
        t = float(truncation)
        out = _stand_columns(*args, r0, float(top_sds), t, volume, leaf, float(per_ha))
        _dominant_heights(out, ndtri(out[:, 7]), args[1], t)
        return out[:, :7]
    mean, sd = v["top_height"] - top_sds * v["height_sd"], v["height_sd"]
    m1, m2, m3 = np.moveaxis(family.raw_moments((1, 2, 3), mean, sd, truncation), -1, 0)
    r1 = v["crown_radius_slope"]
    mix = np.column_stack([v["cone_fraction"], 1.0 - v["cone_fraction"]])
    area = poisson_stand.crown_area_moment(r0, r1, m1, m2)  # E[π R²]
    crown = poisson_stand.crown_volume_moment(r0, r1, m1, m2, m3, v["crown_length_ratio"])
    lam = poisson_stand.density_from_cover(v["cover"], area)
    crown_volume = poisson_stand.crown_volume(lam, crown, mix @ volume)
    favd = poisson_stand.favd_from_lai(v["pai"], lam, crown, mix @ leaf)
    dominant = _dominant_height(family, mean, sd, truncation, lam * 1e4, per_ha)
    return np.column_stack([lam, mean, favd, area, m1, crown_volume, dominant])


def _dominant_height(family, mean, sd, truncation, density, per_ha):
    """Mean height of the ``per_ha`` tallest stems per hectare (all if fewer):
    the family's closed-form partial mean above the cut over the share above it, which
    is the tail the cut was taken at."""
    tail = np.clip(per_ha / density, 1e-9, 1.0)
    args = family.arguments(mean, sd, truncation)
    cut = family.fast("isf", tail, *args)
    return family.fast("mean_above", cut, *args) / tail


#: Parameters read by the kernel of :func:`stand_columns`, in its order.
_INPUTS = (
    "top_height",
    "height_sd",
    "cover",
    "pai",
    "crown_length_ratio",
    "crown_radius_slope",
    "cone_fraction",
)

_SQRT_2PI = math.sqrt(2.0 * math.pi)
_density_from_cover = jit(poisson_stand.density_from_cover)
_crown_area_moment = jit(poisson_stand.crown_area_moment)
_crown_volume_moment = jit(poisson_stand.crown_volume_moment)
_crown_volume = jit(poisson_stand.crown_volume)
_favd_from_lai = jit(poisson_stand.favd_from_lai)


@jit
def _pdf(x):
    return math.exp(-0.5 * x * x) / _SQRT_2PI


@jit
def _stand_columns(top, sd, cover, pai, ratio, slope, cone, r0, top_sds, t, vol, leaf, per_ha):
    """The kernel of :func:`stand_columns` for truncated-normal heights: raw moments
    E[h^k], k ≤ 3, of N(mean, sd²) truncated to [max(mean − t·sd, 0), mean + t·sd], the
    Poisson-stand identities, and the dominant stems' share (column 6) and Φ of their cut
    (column 7) for :func:`_dominant_heights`."""
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
        area = _crown_area_moment(r0[i], slope[i], m1, m2)  # E[π R²]
        crown = _crown_volume_moment(r0[i], slope[i], m1, m2, m3, ratio[i])  # E[π R² ℓ h]
        lam = _density_from_cover(cover[i], area)
        mix_vol = cone[i] * vol[0] + (1.0 - cone[i]) * vol[1]
        mix_leaf = cone[i] * leaf[0] + (1.0 - cone[i]) * leaf[1]
        tail = min(max(per_ha / (lam * 1e4), 1e-9), 1.0)
        out[i, 0] = lam
        out[i, 1] = mean
        out[i, 2] = _favd_from_lai(pai[i], lam, crown, mix_leaf)
        out[i, 3] = area
        out[i, 4] = m1
        out[i, 5] = _crown_volume(lam, crown, mix_vol)
        out[i, 6] = tail
        out[i, 7] = _cdf(t) - tail * mass  # Φ of the dominant stems' cut
    return out


@jit
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
