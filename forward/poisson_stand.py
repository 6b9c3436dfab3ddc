r"""Identities of a Poisson stand: cover, stem density, foliage and the tallest stem.

Stems stand as a Poisson process of intensity λ (stems/m²) with independent marks (height
h, crown radius R(h), crown length ℓ·h, shape s). The crowns' vertical projections then
form a Boolean model, so the number of crowns over a ground point is Poisson with mean

    X = λ·E[π R²],                      cover c = 1 − e^{−X},   X = −ln(1 − c),

and the crowns hold, per unit ground area, the volume λ·E[π R² ℓ h]·Σ_s m_s v_s and the
foliage area L = λ·FAVD·E[π R² ℓ h]·Σ_s m_s κ_s v_s, with m_s the shape fractions, v_s
their volume fractions and κ_s their FAVD ratios. On a disc holding N ~ Poisson(λ·A)
stems of height survival S(h), the tallest stem H has P(H ≤ h) = exp(−λ·A·S(h)).

Every function here is written once, with numpy's ufuncs and without calls to other
Python functions, so that it serves arrays, scalars and compiled kernels alike:
:mod:`forward.derived`'s quadratures, the inversion's stand mapping and its compiled
kernel (``forward.backends.jit`` of these functions) all call them.

References
----------
Chiu, S. N., Stoyan, D., Kendall, W. S. & Mecke, J. (2013). *Stochastic Geometry and its
Applications*, 3rd ed., Wiley, Sec. 3.1 (the Boolean model, its coverage).
Strahler, A. H. & Jupp, D. L. B. (1990). Modeling bidirectional reflectance of forests
and woodlands using Boolean models and geometric optics. *Remote Sens. Environ.* 34,
153–166.
"""

import numpy as np


def crown_count(cover):
    """Mean number of crowns over a ground point, X = −ln(1 − c).

    Parameters
    ----------
    cover : float or array
        Crown cover c ∈ [0, 1), the fraction of ground under at least one crown.

    Returns
    -------
    float or array
        X = λ·E[π R²] (crowns per point, dimensionless).

    Notes
    -----
    The crowns over a point are Poisson with mean X, so c = 1 − P(none) = 1 − e^{−X}.

    References
    ----------
    Chiu, S. N., Stoyan, D., Kendall, W. S. & Mecke, J. (2013). *Stochastic Geometry and its
    Applications*, 3rd ed., Wiley, Sec. 3.1 (the coverage of a Boolean model).
    """
    return -np.log1p(-cover)


def cover_from_crown_count(count):
    """Crown cover c = 1 − e^{−X} of a mean crown count X; the inverse of :func:`crown_count`.

    Parameters
    ----------
    count : float or array
        X = λ·E[π R²] ≥ 0.

    Returns
    -------
    float or array
        Cover c ∈ [0, 1).
    """
    return -np.expm1(-count)


def cover_from_density(density, crown_area):
    """Crown cover c = 1 − exp(−λ·E[π R²]).

    Parameters
    ----------
    density : float or array (stems/m²)
        λ.
    crown_area : float or array (m²)
        E[π R²], the mean crown area per stem.

    Returns
    -------
    float or array
        Cover c: :func:`cover_from_crown_count` of X = λ·E[π R²] (written out, so that
        compiled kernels can call it).

    References
    ----------
    Chiu, S. N., Stoyan, D., Kendall, W. S. & Mecke, J. (2013). *Stochastic Geometry and its
    Applications*, 3rd ed., Wiley, Sec. 3.1 (the coverage of a Boolean model).
    Strahler, A. H. & Jupp, D. L. B. (1990). Modeling bidirectional reflectance of forests
    and woodlands using Boolean models and geometric optics. *Remote Sens. Environ.* 34,
    153–166.
    """
    return -np.expm1(-(density * crown_area))


def density_from_cover(cover, crown_area):
    """Stem density λ = −ln(1 − c) / E[π R²] (stems/m²): the inverse of
    :func:`cover_from_density`.

    Parameters
    ----------
    cover : float or array
        Crown cover c ∈ [0, 1).
    crown_area : float or array (m²)
        E[π R²].

    Returns
    -------
    float or array (stems/m²)
        :func:`crown_count` over E[π R²] (written out, so that compiled kernels can call
        it).

    References
    ----------
    Chiu, S. N., Stoyan, D., Kendall, W. S. & Mecke, J. (2013). *Stochastic Geometry and its
    Applications*, 3rd ed., Wiley, Sec. 3.1 (the coverage of a Boolean model).
    """
    return -np.log1p(-cover) / crown_area


def crown_area_moment(r0, r1, m1, m2):
    """Mean crown area E[π R²] (m²) of crowns of radius R = r0 + r1·h.

    Parameters
    ----------
    r0 : float or array (m)
        Crown-radius intercept.
    r1 : float or array (m/m)
        Crown radius per metre of height.
    m1, m2 : float or array (m, m²)
        Raw moments E[h], E[h²] of the height distribution.

    Returns
    -------
    float or array (m²)

    Notes
    -----
    E[π R²] = π·(r0² + 2·r0·r1·E[h] + r1²·E[h²]).
    """
    return np.pi * (r0 * r0 + 2.0 * r0 * r1 * m1 + r1 * r1 * m2)


def crown_volume_moment(r0, r1, m1, m2, m3, ratio):
    """E[π R² ℓ h] (m³): the mean volume of the cylinder around each crown.

    Parameters
    ----------
    r0, r1 : float or array (m, m/m)
        Crown radius R = r0 + r1·h.
    m1, m2, m3 : float or array (m, m², m³)
        Raw moments E[h], E[h²], E[h³] of the height distribution.
    ratio : float or array
        Crown length ratio ℓ (crown length over tree height).

    Returns
    -------
    float or array (m³)

    Notes
    -----
    E[π R² ℓ h] = π·(r0²·E[h] + 2·r0·r1·E[h²] + r1²·E[h³])·ℓ; a crown of shape s fills
    the volume fraction v_s of it.
    """
    return np.pi * (r0 * r0 * m1 + 2.0 * r0 * r1 * m2 + r1 * r1 * m3) * ratio


def crown_volume(density, volume_moment, fraction):
    """Crown volume per unit ground area, λ·E[π R² ℓ h]·Σ_s m_s v_s.

    Parameters
    ----------
    density : float or array
        λ (stems per unit area: m² gives m³/m², ha gives m³/ha).
    volume_moment : float or array (m³)
        E[π R² ℓ h] (:func:`crown_volume_moment`), or a crown volume per stem.
    fraction : float or array
        Σ_s m_s v_s, the stems' mean volume fraction (1 if ``volume_moment`` is one).

    Returns
    -------
    float or array
        Crown volume (m³ per unit of ``density``'s area).
    """
    return density * volume_moment * fraction


def favd_from_lai(lai, density, volume_moment, leaf_fraction):
    """Foliage area volume density FAVD = L / (λ·E[π R² ℓ h]·Σ_s m_s κ_s v_s) (m²/m³).

    Parameters
    ----------
    lai : float or array (m²/m²)
        Crown leaf (plant) area index L.
    density : float or array (stems/m²)
        λ.
    volume_moment : float or array (m³)
        E[π R² ℓ h] (:func:`crown_volume_moment`).
    leaf_fraction : float or array
        Σ_s m_s κ_s v_s: shape fractions times FAVD ratios times volume fractions.

    Returns
    -------
    float or array (m²/m³)
    """
    return lai / (density * volume_moment * leaf_fraction)


def lai_from_foliage(density, foliage):
    """Crown leaf area index L = λ·E[FAVD·V] (m²/m²).

    Parameters
    ----------
    density : float or array (stems/m²)
        λ.
    foliage : float or array (m²)
        Mean foliage area per stem, E[FAVD_s·V_s(h)].

    Returns
    -------
    float or array (m²/m²)
    """
    return density * foliage


def tallest_above(stems, survival):
    """P(H > h) = 1 − exp(−N·S(h)) of the tallest of Poisson(N) stems.

    Parameters
    ----------
    stems : float or array
        N, the expected stems on the area (λ·A).
    survival : float or array
        S(h), the share of stems taller than h.

    Returns
    -------
    float or array
        The probability that some stem is taller than h (0 where no stem stands).

    Notes
    -----
    The stems taller than h are Poisson with mean N·S(h); H ≤ h where there are none.
    Its mean is E[H] = ∫_0^∞ P(H > h) dh (the tallest of no stems counted as 0).

    References
    ----------
    Chiu, S. N., Stoyan, D., Kendall, W. S. & Mecke, J. (2013). *Stochastic Geometry and its
    Applications*, 3rd ed., Wiley, Ch. 2 (the Poisson point process: the probability of no
    stem above h).
    """
    return -np.expm1(-stems * survival)


def tallest_log_density(stems, pdf, survival):
    """Log density (1/m) of the tallest stem's height H at h, ln(N·f(h)) − N·S(h).

    Parameters
    ----------
    stems : float or array
        N = λ·A.
    pdf, survival : float or array
        f(h) (1/m) and S(h) of the stems' heights.

    Returns
    -------
    float or array
        d/dh P(H ≤ h) = N·f(h)·exp(−N·S(h)), on the log scale (−inf where f = 0).

    References
    ----------
    Chiu, S. N., Stoyan, D., Kendall, W. S. & Mecke, J. (2013). *Stochastic Geometry and its
    Applications*, 3rd ed., Wiley, Ch. 2 (the Poisson point process: the probability of no
    stem above h).
    """
    return np.log(stems * pdf) - stems * survival


def tallest_survival(uniform, stems):
    """S(h) of the tallest stem drawn by inversion, −ln U / N, from a uniform variate U.

    Parameters
    ----------
    uniform : float or array
        U ∈ (0, 1].
    stems : float or array
        N = λ·A.

    Returns
    -------
    float or array
        The survival at the draw: the draw is h with S(h) equal to it where it is below 1;
        at or above 1 no stem stands (P(none) = e^{−N}).
    """
    return -np.log(uniform) / stems


def footprint_gap_cv2(gap0, crown_area, area):
    """Squared relative spread of the gap fraction a footprint sees over a Poisson stand.

    Parameters
    ----------
    gap0 : float or array
        The expected gap fraction P(0), clipped to [1e-12, 1].
    crown_area : float or array (m²)
        E[π R²], the mean crown area.
    area : float (m²)
        The footprint's effective area (``Instrument.footprint_effective_area_m2``).

    Returns
    -------
    float or array
        CV² = (1 − P)/P · E[π R²]/A: a footprint of A holds about A/E[π R²] independent
        crown-sized patches, each covered with probability 1 − P.
    """
    gap0 = np.clip(gap0, 1e-12, 1.0)
    return (1.0 - gap0) / gap0 * crown_area / area
