"""Built-in example scenes, chosen through the :data:`EXAMPLES` registry."""

from dataclasses import dataclass, field

import numpy as np

from .allometry import SPECIES_ALLOMETRY
from .instrument import Instrument, instrument_preset
from .scene import Ground
from .stand import Stand


@dataclass(frozen=True)
class ExampleScene:
    """A stand with the instrument and footprints it is meant to be seen with.

    Attributes
    ----------
    stand : Stand
    instrument : Instrument
    centers : array (n, 2) (m)
        Footprint centres in stand coordinates.
    ground : Ground
    canopy_reflectance : float
        ρv.
    description : str
    """

    stand: Stand
    instrument: Instrument
    centers: np.ndarray
    ground: Ground = field(default_factory=Ground)
    canopy_reflectance: float = 0.45
    description: str = ""


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


#: Example name → factory returning an :class:`ExampleScene`.
EXAMPLES = {
    "jack-pine": jack_pine,
    # successional stands of forward.paper_stands (imported lazily: it imports this module)
    **{
        f"successional-{age}": (
            lambda age=age: __import__(
                "forward.paper_stands", fromlist=["successional_scene"]
            ).successional_scene(age)
        )
        for age in (5, 20, 60, 200)
    },
}


def example(name: str) -> ExampleScene:
    """The built-in example ``name``."""
    try:
        return EXAMPLES[name]()
    except KeyError:
        raise ValueError(f"unknown example {name!r}; examples are {sorted(EXAMPLES)}") from None
