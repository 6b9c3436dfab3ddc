"""Built-in example stands and scenes, in one place.

Parameterised stands (:class:`~forward.stand_params.StandParams`): a generic conifer
stand (:func:`example_stand`), the stands of :data:`EXAMPLE_STANDS` (e.g. ``gedi-mixed``,
the stand of ``lidarinv invert --example``) and the stands of Sun & Ranson (2000)
(:mod:`forward.paper_stands`). Explicit scenes (:class:`~forward.scene.ExampleScene`, a
stem map with its instrument and footprints) are chosen through the :data:`EXAMPLES`
registry (``lidarinv simulate --example``).
"""

import numpy as np

from .allometry import SPECIES_ALLOMETRY
from .instrument import instrument_preset
from .paper_stands import SUCCESSIONAL, successional_scene
from .scene import ExampleScene
from .stand import Stand
from .stand_params import StandParams

#: Values of a generic conifer stand (600 stems/ha, heights 15 ± 3 m) for examples and
#: tests; every other field keeps its :class:`StandParams` default.
EXAMPLE_VALUES = {
    "density": 600.0,
    "height_mean": 15.0,
    "height_sd": 3.0,
    "crown_length_ratio": 0.5,
    "crown_radius_slope": 0.12,
    "favd": 0.8,
}


def example_stand(**changes) -> StandParams:
    """A generic conifer stand (:data:`EXAMPLE_VALUES`) with changes.

    Parameters
    ----------
    **changes
        StandParams fields replacing the example's.

    Returns
    -------
    StandParams
    """
    return StandParams(**{**EXAMPLE_VALUES, **changes})


#: Parameterised example stands by name: ``gedi-mixed`` is a mixed cone/ellipsoid stand
#: with an understory, truncated-normal heights 16 ± 3 m (truncated at ±2 sd), seen by
#: GEDI in ``lidarinv invert --example gedi-mixed``.
EXAMPLE_STANDS = {
    "gedi-mixed": StandParams(
        density=600.0,
        height_mean=16.0,
        height_sd=3.0,
        height_family="truncnorm",
        height_truncation=2.0,
        shape_mix={"cone": 0.6, "ellipsoid": 0.4},
        favd=0.6,
        understory_height=1.0,
        understory_lai=0.3,
        canopy_reflectance=0.45,
        ground_reflectance=0.3,
    ),
}


def jack_pine(shape="hemi-ellipsoid", seed=1993) -> ExampleScene:
    """The BOREAS southern old jack pine stand of Sun & Ranson (2000), Sec. IV–V.

    From the paper: a 1 ha (100 m × 100 m) plot with 1900 trees, heights in a narrow range
    of 12–15 m, FAVD 0.8 m²/m³, G = 0.5, nine 10 m footprints in the south-west corner,
    a 4 ns pulse and 0.112 m bins (the ``slicer`` preset), hemi-ellipsoid crowns in Fig. 5.
    Our choices: stems placed as a Poisson pattern with a fixed seed, DBH ~ N(15, 2.5) cm
    clipped to [11.5, 24] cm, the ``jack pine`` allometry of :mod:`forward.allometry` (it puts
    about 165 m³ of cone or 330 m³ of ellipsoid crown in a 10 m footprint, against the
    paper's 180 and 310 m³), the nine footprint centres on a 10 m grid from (15, 15) m,
    ρv = 0.45 and ρg = 0.3.

    Parameters
    ----------
    shape : str
        The crown shape of every tree.
    seed : int
        Seed of the stem map.

    Returns
    -------
    ExampleScene

    References
    ----------
    Sun, G. & Ranson, K. J. (2000). Modeling lidar returns from forest canopies. *IEEE
    Trans. Geosci. Remote Sens.* 38(6), 2617–2626.
    """
    rng = np.random.default_rng(seed)
    n = 1900
    dbh = np.clip(rng.normal(15.0, 2.5, n), 11.5, 24.0)
    allometry = SPECIES_ALLOMETRY["jack pine"]
    height = allometry.height(dbh)
    stand = Stand.from_arrays(
        x=rng.uniform(0.0, 100.0, n),
        y=rng.uniform(0.0, 100.0, n),
        height=height,
        crown_length=allometry.crown_length(height),
        crown_radius=allometry.crown_radius(height),
        favd=0.8,
        shape=shape,
        dbh=dbh,
        species=np.full(n, "jack pine", dtype=object),
    )
    grid = 15.0 + 10.0 * np.arange(3)
    centers = np.array([(x, y) for y in grid for x in grid])
    return ExampleScene(
        stand=stand,
        instrument=instrument_preset("slicer"),
        centers=centers,
        description="BOREAS SSA old jack pine, 1 ha, 1900 trees (Sun & Ranson 2000)",
    )


#: Example name → factory returning an :class:`~forward.scene.ExampleScene`.
EXAMPLES = {
    "jack-pine": jack_pine,
    **{f"successional-{age}": (lambda age=age: successional_scene(age)) for age in SUCCESSIONAL},
}


def example(name: str) -> ExampleScene:
    """The built-in example scene ``name``.

    Parameters
    ----------
    name : str
        A key of :data:`EXAMPLES`.

    Returns
    -------
    ExampleScene

    Raises
    ------
    ValueError
        For an unknown name, naming the known ones.
    """
    try:
        return EXAMPLES[name]()
    except KeyError:
        raise ValueError(f"unknown example {name!r}; examples are {sorted(EXAMPLES)}") from None
