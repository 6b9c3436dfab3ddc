"""Real example files shipped with lidarinv: a few shots of public GEDI and LVIS products.

Every sixth shot of three beams of GEDI orbit O01964 (2019-04-18, cerrado savanna, Brazil;
L1B, L2A and L2B) and every eighth shot of one LVIS AfriSAR flight line (2016, Mondah
forest, Gabon; L1B and L2), in the products' own layouts, cut by
``studies/make_example_data.py``. ``lidarinv/data/README.md`` gives their provenance and
the data citations.
"""

from pathlib import Path

DATA = Path(__file__).resolve().parent.parent / "data"

#: Example name → file name in ``lidarinv/data``.
EXAMPLE_FILES = {
    "gedi-l1b": "gedi-l1b.h5",
    "gedi-l2a": "gedi-l2a.h5",
    "gedi-l2b": "gedi-l2b.h5",
    "lvis-l1b": "lvis-l1b.h5",
    "lvis-l2": "lvis-l2.txt",
}


def example_file(name: str) -> Path:
    """Path of a shipped example file (``gedi-l1b``, ``gedi-l2a``, ``gedi-l2b``,
    ``lvis-l1b``, ``lvis-l2``)."""
    try:
        path = DATA / EXAMPLE_FILES[name]
    except KeyError:
        raise ValueError(f"unknown example file {name!r}; known: {list(EXAMPLE_FILES)}") from None
    if not path.exists():
        raise FileNotFoundError(f"example file {path} is missing from this installation")
    return path
