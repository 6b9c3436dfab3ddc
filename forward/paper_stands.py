"""The stands of Sun & Ranson (2000) as parameterised stands.

Jack pine (Sec. IV–V-A)
    From the paper: 1900 trees/ha, heights 12–15 m, FAVD 0.8 m²/m³, G = 0.5, 10 m
    footprints, a 4 ns pulse and 0.112 m bins (the ``slicer`` preset). Our choices: a
    normal height distribution of mean 13.5 m and sd 0.75 m truncated at ±2 sd (so
    12–15 m), crown length 0.45·h and crown radius 0.1 + 0.095·h m (the ``jack pine``
    allometry of :mod:`forward.allometry`), ρv = 0.45, ρg = 0.3. These put about 183 m³
    of cone and 365 m³ of ellipsoid crown in a 10 m footprint (paper: 180 and 310 m³).
    With FAVD 0.8 the crown LAI is then 1.9 (cones) to 3.7 (ellipsoids), around the
    measured 2.17, the same compromise the paper makes.

Successional stands, ages 5, 20, 60 and 200 years (Sec. III, V-B, VI-B)
    From the text: 25 m footprints and a 10 ns pulse; conifers as cones and deciduous
    trees as ellipsoids; heights from 2 m to about 25 m with a few large trees and many
    small ones (Fig. 8); the 5-year stand is dense and bimodal, with almost all conifers
    below 3 m and all deciduous trees above 3.5 m; the 20- and 60-year stands have a few
    emergent trees above a lower tier that holds more crown volume, and the 20-year stand
    has the most deciduous trees; conifers gain with age; in the 200-year stand the upper
    tier dominates, holds the largest crown volume of all stands, and occults the lower.
    Table I's numbers (trees per plot, MH, MaxH) are not in the text we have, so every
    number below is our choice, made to reproduce those statements: two cohorts per
    stand (truncated normal heights), densities, cohort heights and shape mixes in
    :data:`SUCCESSIONAL`, FAVD 0.8, crown length 0.55·h, crown radius 0.3 + 0.09·h m,
    ρv = 0.45, ρg = 0.3, 1 ns bins.
"""

import numpy as np

from .instrument import instrument_preset
from .realise import realise, scene_extras
from .scene import ExampleScene
from .stand_params import StandParams

#: The BOREAS old jack pine stand as :class:`StandParams` values (see above), less the shape.
JACK_PINE = {
    "density": 1900.0,
    "height_family": "truncnorm",
    "height_mean": 13.5,
    "height_sd": 0.75,
    "height_truncation": 2.0,
    "crown_length_ratio": 0.45,
    "crown_radius_intercept": 0.1,
    "crown_radius_slope": 0.095,
    "favd": 0.8,
    "canopy_reflectance": 0.45,
    "ground_reflectance": 0.3,
}


def jack_pine_params(shape="hemi-ellipsoid") -> StandParams:
    """The BOREAS old jack pine stand, one crown shape for all trees.

    Parameters
    ----------
    shape : str or dict
        Crown shape (or mix).

    Returns
    -------
    StandParams
        :data:`JACK_PINE` with the shape.
    """
    return StandParams(shape_mix=shape, **JACK_PINE)


def jack_pine_instrument():
    """SLICER as simulated by the paper.

    Returns
    -------
    Instrument
        4 ns pulse, 0.112 m bins, 10 m footprint (the ``slicer`` preset).
    """
    return instrument_preset("slicer")


#: Age (years) → (density stems/ha, upper cohort fraction, upper (mean, sd) m,
#: lower (mean, sd) m, deciduous fraction of the upper cohort, of the lower cohort).
#: Deciduous trees are ellipsoids and conifers cones. Our calibration (see above).
SUCCESSIONAL = {
    5: (9000.0, 0.35, (5.2, 0.6), (2.0, 0.5), 1.0, 0.0),
    20: (4000.0, 0.06, (15.0, 2.0), (6.5, 1.5), 0.8, 0.7),
    60: (2400.0, 0.07, (20.0, 1.5), (8.5, 1.5), 0.5, 0.4),
    200: (1200.0, 0.6, (21.0, 1.5), (8.0, 2.0), 0.3, 0.3),
}


def _deciduous_mix(fraction):
    """Shape mix of a cohort with ``fraction`` deciduous trees (ellipsoids), rest cones."""
    return {"ellipsoid": fraction, "cone": 1.0 - fraction}


def successional_params(age, shape=None) -> StandParams:
    """The successional stand of an age.

    Parameters
    ----------
    age : int
        5, 20, 60 or 200 (years).
    shape : str, optional
        One crown shape for both cohorts (the paper's Fig. 10); by default conifers are
        cones and deciduous trees ellipsoids.

    Returns
    -------
    StandParams
        Cohort 1 is the upper tier, cohort 2 the lower (:data:`SUCCESSIONAL`).

    Raises
    ------
    ValueError
        For another age.
    """
    try:
        density, upper, (m1, s1), (m2, s2), deciduous1, deciduous2 = SUCCESSIONAL[int(age)]
    except KeyError:
        raise ValueError(
            f"no successional stand of age {age}; ages are {sorted(SUCCESSIONAL)}"
        ) from None
    mix1, mix2 = _deciduous_mix(deciduous1), _deciduous_mix(deciduous2)
    if shape is not None:
        mix1 = mix2 = shape
    return StandParams(
        density=density,
        height_family="truncnorm",
        height_mean=m1,
        height_sd=s1,
        shape_mix=mix1,
        cohort2_fraction=1.0 - upper,
        cohort2_height_mean=m2,
        cohort2_height_sd=s2,
        cohort2_shape_mix=mix2,
        height_truncation=2.5,
        crown_length_ratio=0.55,
        crown_radius_intercept=0.3,
        crown_radius_slope=0.09,
        favd=0.8,
    )


def successional_instrument():
    """The instrument of the successional stands.

    Returns
    -------
    Instrument
        10 ns Gaussian pulse, 25 m (1/e²) footprint, 1 ns bins.
    """
    return instrument_preset("lvis", pulse_fwhm_ns=10.0, footprint_diameter_m=25.0)


def successional_scene(age, shape=None, seed=None, plot_m=60.0):
    """An explicit realisation of a successional stand.

    Stems are a Poisson pattern on a ``plot_m`` square (larger than the paper's 30 m ZELIG
    plot, so that the Gaussian footprint sees no empty margin), one footprint at its centre.

    Parameters
    ----------
    age : int
        5, 20, 60 or 200 (years).
    shape : str, optional
        As :func:`successional_params`.
    seed : int, optional
        Seed of the stem map; 2000 + age by default.
    plot_m : float (m)
        Side of the plot.

    Returns
    -------
    forward.scene.ExampleScene
    """
    params = successional_params(age, shape)
    rng = np.random.default_rng(2000 + int(age) if seed is None else seed)
    stand = realise(params, plot_m, rng)
    ground, _, rho_v = scene_extras(params)
    return ExampleScene(
        stand=stand,
        instrument=successional_instrument(),
        centers=np.array([[plot_m / 2, plot_m / 2]]),
        ground=ground,
        canopy_reflectance=rho_v,
        description=f"{age}-year successional stand, Howland ME (Sun & Ranson 2000, Fig. 9)",
    )
