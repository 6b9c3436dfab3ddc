"""Stand quantities derived from :class:`~forward.stand_params.StandParams`.

All are expectations for the Poisson stand the parameters describe: the identities of
:mod:`forward.poisson_stand` with their expectations over heights computed by quadrature
over the height distribution (a fine grid, trapezoid rule). Crowns are the only
woody-free plant material modelled, so the plant area index equals the leaf area index
of crowns plus understory.
"""

import numpy as np

from . import poisson_stand
from .crowns import CROWN_SHAPES, SHAPE_NAMES

_GRID = 4001
_TAIL = 1e-10


def _height_grid(params):
    cohorts = params.cohorts()
    lo = min(float(dist.ppf(_TAIL)) for _, dist, _ in cohorts)
    hi = max(float(dist.isf(_TAIL)) for _, dist, _ in cohorts)
    return np.linspace(max(lo, 0.0), hi, _GRID)


def _shape_densities(params, h):
    """Stem-fraction density over height for each shape: (n_shapes, len(h)) (1/m)."""
    out = np.zeros((len(SHAPE_NAMES), h.size))
    for weight, dist, mix in params.cohorts():
        out += weight * mix[:, None] * dist.pdf(h)[None, :]
    return out


def _expect(params, values):
    """Σ_shapes ∫ f_s(h)·values[s](h) dh, with ``values`` (n_shapes, len(h)) on the grid."""
    h = _height_grid(params)
    f = _shape_densities(params, h)
    return float(np.trapezoid(np.sum(f * values(h), axis=0), h))


def mean_height(params) -> float:
    """Mean tree height over all stems.

    Parameters
    ----------
    params : StandParams

    Returns
    -------
    float (m)
        E[h] = Σ_s ∫ f_s(h)·h dh over both cohorts.
    """
    return _expect(params, lambda h: np.broadcast_to(h, (len(SHAPE_NAMES), h.size)))


def canopy_cover(params) -> float:
    """Fraction of ground under at least one crown.

    Parameters
    ----------
    params : StandParams

    Returns
    -------
    float
        c = 1 − exp(−λ·E[π Rc²]) (:func:`forward.poisson_stand.cover_from_density`).

    References
    ----------
    Chiu, S. N., Stoyan, D., Kendall, W. S. & Mecke, J. (2013). *Stochastic Geometry and its
    Applications*, 3rd ed., Wiley, Sec. 3.1 (the coverage of a Boolean model).
    """
    area = _expect(
        params,
        lambda h: np.broadcast_to(np.pi * params.crown_radius(h) ** 2, (len(SHAPE_NAMES), h.size)),
    )
    return float(poisson_stand.cover_from_density(params.density_per_m2, area))


def _crown_volume(params, h):
    fractions = np.array([CROWN_SHAPES[name].volume_fraction for name in SHAPE_NAMES])
    volume = np.pi * params.crown_radius(h) ** 2 * params.crown_length(h)
    return fractions[:, None] * volume[None, :]


def crown_volume_per_ha(params) -> float:
    """Crown volume per hectare.

    Parameters
    ----------
    params : StandParams

    Returns
    -------
    float (m³/ha)
        λ·E[v_s·π Rc²·Lc] with λ in stems/ha (:func:`forward.poisson_stand.crown_volume`).
    """
    volume = _expect(params, lambda h: _crown_volume(params, h))
    return poisson_stand.crown_volume(params.density, volume, 1.0)


def leaf_area_index(params) -> float:
    """One-sided leaf area index of crowns plus understory.

    Parameters
    ----------
    params : StandParams

    Returns
    -------
    float (m²/m²)
        λ·E[FAVD_s·v_s·π Rc²·Lc] (:func:`forward.poisson_stand.lai_from_foliage`) plus the
        understory LAI.
    """
    favd = params.favd_by_shape()[:, None]
    foliage = _expect(params, lambda h: favd * _crown_volume(params, h))
    return poisson_stand.lai_from_foliage(params.density_per_m2, foliage) + params.understory_lai


#: Plant area index (m²/m²): equal to the LAI here, since no wood is modelled.
plant_area_index = leaf_area_index


def crown_volume_profile(params, z) -> np.ndarray:
    """Crown volume per unit ground area and unit height.

    Parameters
    ----------
    params : StandParams
    z : float or array (m)
        Heights above the ground.

    Returns
    -------
    array (m³/m²/m), shape (len(z),)
        λ·Σ_s ∫ f_s(h)·π Rc(h)²·a_s((z − (h − Lc))/Lc) dh, a_s the shape's horizontal
        section at a fraction of the crown length (:meth:`forward.crowns.CrownShape.section`).
    """
    z = np.atleast_1d(np.asarray(z, float))
    h = _height_grid(params)
    f = _shape_densities(params, h)
    length = params.crown_length(h)
    area = np.pi * params.crown_radius(h) ** 2
    s = (z[:, None] - (h - length)[None, :]) / length[None, :]
    out = np.zeros(z.size)
    for k, name in enumerate(SHAPE_NAMES):
        if f[k].any():
            section = CROWN_SHAPES[name].section(s)
            out += np.trapezoid(f[k][None, :] * area[None, :] * section, h, axis=1)
    return params.density_per_m2 * out


def _survival(params, h):
    return sum(weight * dist.sf(h) for weight, dist, _ in params.cohorts())


def dominant_height(params, top_per_ha=100.0) -> float:
    """Mean height of the tallest stems.

    Parameters
    ----------
    params : StandParams
    top_per_ha : float (stems/ha)
        How many of the tallest stems per hectare to average.

    Returns
    -------
    float (m)
        The mean height of the ``top_per_ha`` tallest stems per hectare: E[h | h ≥ h*]
        with S(h*) = top_per_ha / density; the mean height if the density is lower.
    """
    if params.density <= top_per_ha:
        return mean_height(params)
    h = _height_grid(params)
    tail = top_per_ha / params.density
    f = _shape_densities(params, h).sum(axis=0)
    cut = h[np.searchsorted(-_survival(params, h), -tail)]  # S(cut) ≈ tail
    keep = h >= cut
    return float(np.trapezoid(h[keep] * f[keep], h[keep]) / np.trapezoid(f[keep], h[keep]))


def expected_max_height(params, footprint_diameter_m) -> float:
    """Expected height of the tallest tree with its stem in a disc.

    Parameters
    ----------
    params : StandParams
    footprint_diameter_m : float (m)
        Diameter D of the disc.

    Returns
    -------
    float (m)
        E[max] = ∫_0^∞ (1 − exp(−λA·S(h))) dh, A = πD²/4, the tallest of no trees counted
        as 0 (:func:`forward.poisson_stand.tallest_above`).

    References
    ----------
    Chiu, S. N., Stoyan, D., Kendall, W. S. & Mecke, J. (2013). *Stochastic Geometry and its
    Applications*, 3rd ed., Wiley, Ch. 2 (the Poisson point process: the probability of no
    stem above h).
    """
    area = np.pi * footprint_diameter_m**2 / 4.0
    h = np.linspace(0.0, _height_grid(params)[-1], _GRID)
    above = poisson_stand.tallest_above(params.density_per_m2 * area, _survival(params, h))
    return float(np.trapezoid(above, h))
