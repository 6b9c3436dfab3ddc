"""The footprint's tallest stem as a latent of the stand model.

A footprint conditioned on its tallest stem within the disc of radius R =
:data:`TALLEST_STEM_RADIUS_SIGMAS`·σf (area A) holds that stem, of height H and at
squared distance r² = V·R² from the beam centre, and a stand stopped at H. Given the
stand, N ~ Poisson(λA) stems stand on the disc and H is the tallest of them:
P(H ≤ h) = exp(−λA·S(h)) (:mod:`forward.poisson_stand`). The functions here give that
law for a height family, draws from it, and the stem itself in an explicit stand.
"""

import numpy as np

from forward.footprint import gaussian_footprint_weight
from forward.poisson_stand import tallest_log_density, tallest_survival

#: The latent parameter of a footprint conditioned on its tallest stem: that stem's height
#: H (m), whose law given the stand is the Poisson order statistic
#: (:func:`mixture_log_density`); H below the stand's lowest tree stands for a disc without a
#: stem.
TALLEST_STEM = "tallest_stem_height"

#: Depth (m) of the range of H just below the stand's lowest tree that stands for a disc
#: without a stem, which spreads the chance of none, e^{−λA}, uniformly over it. Joined to
#: the support, it lets the sampler pass between a short stem and none.
NO_STEM_DEPTH_M = 1.0

#: The latent position of that stem: its squared distance from the footprint centre over
#: the disc's squared radius, uniform a priori; it sets the stem's footprint weight.
TALLEST_STEM_POSITION = "tallest_stem_position"

#: The latent parameters of a footprint conditioned on its tallest stem.
TALLEST_STEM_LATENTS = (TALLEST_STEM, TALLEST_STEM_POSITION)

#: Radius (in footprint σ) of the disc whose tallest stem conditions the footprint: the
#: 1/e² radius, holding 1 − e⁻² of the footprint's weight.
TALLEST_STEM_RADIUS_SIGMAS = 2.0

#: The position V whose footprint weight exp(−2V) is the disc's mean, (1 − e⁻²)/2: where V
#: is held there, the realisation covariance carries the spread of the stem's weight.
TALLEST_STEM_MEAN_POSITION = -0.5 * np.log(0.5 * (1.0 - np.exp(-2.0)))


def disc_area(footprint_sigma_m) -> float:
    """Area A = π·(:data:`TALLEST_STEM_RADIUS_SIGMAS`·σf)² (m²) of the tallest stem's disc.

    Parameters
    ----------
    footprint_sigma_m : float (m)
        σf.

    Returns
    -------
    float (m²)
    """
    radius = TALLEST_STEM_RADIUS_SIGMAS * float(footprint_sigma_m)
    return np.pi * radius**2


def stem_density_per_ha(position, footprint_sigma_m):
    """The stem's weight in the footprint, as stems per hectare of a uniform stand.

    Parameters
    ----------
    position : array
        V, the stem's squared distance from the centre over the disc's squared radius.
    footprint_sigma_m : float (m)
        σf.

    Returns
    -------
    array (stems/ha)
        1e4·w(r), w the Gaussian footprint weight (:func:`forward.footprint.
        gaussian_footprint_weight`) at r² = V·R²: on average over V, the disc's weight
        1 − e⁻² over A.
    """
    radius = TALLEST_STEM_RADIUS_SIGMAS * float(footprint_sigma_m)
    return 1e4 * gaussian_footprint_weight(position * radius**2, float(footprint_sigma_m))


def arguments_and_lowest(family, mean, sd, truncation):
    """The height family's arguments and its lowest tree's height per row.

    Parameters
    ----------
    family : forward.stand_params.HeightFamily
    mean, sd : array (m)
        Height mean and sd per row.
    truncation : float (sd units)

    Returns
    -------
    args : tuple
        The family's fast-path arguments.
    lowest : array (m)
    """
    args = family.arguments(mean, sd, truncation)
    return args, family.fast("ppf", np.zeros_like(mean), *args)


def mixture_log_density(family, laws, lowest, stems, tallest) -> np.ndarray:
    """Log density (1/m) of the tallest stem's height H on a disc of Poisson(N) stems
    whose heights follow a mixture of laws (one per cohort).

    Parameters
    ----------
    family : forward.stand_params.HeightFamily
    laws : list of (array, tuple)
        Each cohort's share of the stems and its family arguments per row
        (:func:`arguments_and_lowest`); the shares sum to 1.
    lowest : array (m)
        The stand's lowest tree per row.
    stems : array
        N = λA, the expected stems on the disc.
    tallest : array (m)
        H.

    Returns
    -------
    array (1/m)
        ln N·f(H) − N·S(H) (:func:`forward.poisson_stand.tallest_log_density`) with the
        mixture's density f = Σ sₖ·fₖ and survival S = Σ sₖ·Sₖ (sₖ the shares) on its
        support; the chance of no stem, e^{−N}, spread over the :data:`NO_STEM_DEPTH_M`
        below ``lowest``; −inf elsewhere.
    """
    some = tallest >= lowest
    height = np.where(some, tallest, lowest)
    pdf = sum(share * family.fast("pdf", height, *args) for share, args in laws)
    survival = sum(share * family.fast("sf", height, *args) for share, args in laws)
    with np.errstate(divide="ignore"):
        law = tallest_log_density(stems, pdf, survival)
    none = np.where(tallest >= lowest - NO_STEM_DEPTH_M, -np.log(NO_STEM_DEPTH_M), -np.inf)
    return np.where(some, law, none - stems)


def condition(family, laws, lowest, stems, tallest, position, footprint_sigma_m) -> dict:
    """A footprint conditioned on its tallest stem: the expected model's fields and the
    stem's derived quantities.

    Parameters
    ----------
    family : forward.stand_params.HeightFamily
    laws : list of (array, tuple)
        Each cohort's share of the stems and its family arguments per row.
    lowest : array (m)
        The stand's lowest tree per row.
    stems : array
        N = λA, the expected stems on the disc.
    tallest : array (m)
        H; below ``lowest`` for a disc without a stem.
    position : array
        V (:func:`stem_density_per_ha`).
    footprint_sigma_m : float (m)

    Returns
    -------
    dict
        ``fields``: ``height_cap`` (every cohort stops at H; with no stem, at once) and
        ``apex_density`` (the stem's footprint weight, stems/ha); ``tallest_stem``, H or 0
        where the disc holds none (m); ``tallest_stem_log_density``
        (:func:`mixture_log_density`, 1/m).
    """
    some = tallest >= lowest
    weight = stem_density_per_ha(position, footprint_sigma_m)
    return {
        "fields": {
            "height_cap": np.where(some, tallest, 1e-6),
            "apex_density": np.where(some, weight, 0.0),
        },
        "tallest_stem": np.where(some, tallest, 0.0),
        "tallest_stem_log_density": mixture_log_density(family, laws, lowest, stems, tallest),
    }


def draw_tallest(family, mean, sd, truncation, stems, uniform):
    """The tallest of Poisson(``stems``) stems, one draw per row by inversion.

    Parameters
    ----------
    family : forward.stand_params.HeightFamily
    mean, sd : array (m)
    truncation : float (sd units)
    stems : array
        N, the expected stems on the area.
    uniform : array
        U ~ Uniform(0, 1] per row.

    Returns
    -------
    height : array (m)
        h with S(h) = −ln U / N (:func:`forward.poisson_stand.tallest_survival`); the
        family's lowest height where no stem stands.
    some : array of bool
        Whether any stem stands (−ln U / N < 1).
    """
    with np.errstate(divide="ignore"):
        tail = tallest_survival(uniform, stems)
    some = tail < 1.0
    args = family.arguments(mean, sd, truncation)
    return family.fast("isf", np.minimum(tail, 1.0), *args), some


def tallest_stem_within(stand, centre, footprint_sigma_m) -> tuple[float, float]:
    """The tallest stem of an explicit stand within the footprint's disc.

    Parameters
    ----------
    stand : forward.stand.Stand
    centre : (float, float) (m)
        The beam centre in stand coordinates.
    footprint_sigma_m : float (m)
        σf; the disc has the radius R = :data:`TALLEST_STEM_RADIUS_SIGMAS`·σf.

    Returns
    -------
    height : float (m)
        The tallest stem's height; 0 if the disc holds none.
    position : float
        Its squared distance from ``centre`` over R² (V); NaN if none.
    """
    radius = TALLEST_STEM_RADIUS_SIGMAS * footprint_sigma_m
    r2 = ((stand.x - centre[0]) ** 2 + (stand.y - centre[1]) ** 2) / radius**2
    inside = np.flatnonzero(r2 <= 1.0)
    if inside.size == 0:
        return 0.0, np.nan
    tallest = inside[np.argmax(stand.height[inside])]
    return float(stand.height[tallest]), float(r2[tallest])
