"""Crown shapes: solids of revolution about the stem, chosen through a registry.

Every shape is described in normalised coordinates: ``rho = r / Rc`` is the radial
distance from the stem over the crown radius and ``s = (z - base) / Lc`` the height above
the crown base over the crown length, with the base at ``h - Lc`` and the top at ``h``.
Because all four shapes are convex, a vertical column at ``rho < 1`` crosses the crown in
one interval ``[s_low(rho), s_high(rho)]``. A new shape is one more ``CrownShape`` entry.
"""

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class CrownShape:
    """One crown geometry.

    Attributes
    ----------
    name : str
        Registry key, as on the conventions page.
    extent : callable
        ``extent(rho) -> (s_low, s_high)``: the crown interval of a column at normalised
        radius ``rho`` in [0, 1], as fractions of the crown length above the base.
    section : callable
        ``section(s) -> a``: horizontal cross-section area at normalised height ``s`` in
        [0, 1], as a fraction of pi·Rc².
    volume_fraction : float
        Crown volume over pi·Rc²·Lc.

    References
    ----------
    Sun, G. & Ranson, K. J. (2000). Modeling lidar returns from forest canopies. *IEEE
    Trans. Geosci. Remote Sens.* 38(6), 2617–2626 (Sec. V: crowns as cones, ellipsoids and
    hemi-ellipsoids of uniform foliage).
    """

    name: str
    extent: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]
    section: Callable[[np.ndarray], np.ndarray]
    volume_fraction: float


# The extents are written with arithmetic and ufuncs only, so that they accept scalars as
# well as arrays and compile unchanged under numba (forward.explicit.column_kernel_numba).
def _cone_extent(rho):
    return 0.0 * rho, 1.0 - rho


def _ellipsoid_extent(rho):
    half = 0.5 * np.sqrt(np.maximum(1.0 - rho * rho, 0.0))
    return 0.5 - half, 0.5 + half


def _hemi_ellipsoid_extent(rho):
    return 0.0 * rho, np.sqrt(np.maximum(1.0 - rho * rho, 0.0))


def _cylinder_extent(rho):
    return 0.0 * rho, 0.0 * rho + 1.0


def _inside(s):
    return (s >= 0.0) & (s <= 1.0)


CROWN_SHAPES: dict[str, CrownShape] = {
    shape.name: shape
    for shape in (
        CrownShape(
            "cone",
            _cone_extent,
            lambda s: np.where(_inside(s), (1.0 - s) ** 2, 0.0),
            1.0 / 3.0,
        ),
        CrownShape(
            "ellipsoid",
            _ellipsoid_extent,
            lambda s: np.where(_inside(s), 1.0 - (2.0 * s - 1.0) ** 2, 0.0),
            2.0 / 3.0,
        ),
        CrownShape(
            "hemi-ellipsoid",
            _hemi_ellipsoid_extent,
            lambda s: np.where(_inside(s), 1.0 - s * s, 0.0),
            2.0 / 3.0,
        ),
        CrownShape(
            "cylinder",
            _cylinder_extent,
            lambda s: np.where(_inside(s), 1.0, 0.0),
            1.0,
        ),
    )
}

#: Shape names in code order: a stand stores shapes as indices into this tuple.
SHAPE_NAMES: tuple[str, ...] = tuple(CROWN_SHAPES)


def shape_codes(names) -> np.ndarray:
    """Integer codes of crown shape names.

    Parameters
    ----------
    names : array of str
        Names from :data:`SHAPE_NAMES`.

    Returns
    -------
    array of int8
        Indices into :data:`SHAPE_NAMES`.

    Raises
    ------
    ValueError
        Naming the unknown shapes.
    """
    names = np.asarray(names, dtype=str)
    lookup = {name: code for code, name in enumerate(SHAPE_NAMES)}
    unknown = sorted(set(names.tolist()) - set(lookup))
    if unknown:
        raise ValueError(f"unknown crown shape(s) {unknown}; known shapes are {list(SHAPE_NAMES)}")
    return np.array([lookup[name] for name in names.tolist()], dtype=np.int8)


def crown_interval(codes, rho, base, length):
    """Absolute heights (m) where columns cross their crowns.

    Parameters
    ----------
    codes : array of int
        Shape code of each (tree, column) pair.
    rho : array
        Normalised radial distance r / Rc of the column from the stem, in [0, 1).
    base, length : array
        Crown base height and crown length (m).

    Returns
    -------
    z_low, z_high : arrays (m)
    """
    s_low = np.empty_like(rho)
    s_high = np.empty_like(rho)
    for code, name in enumerate(SHAPE_NAMES):
        mask = codes == code
        if mask.any():
            s_low[mask], s_high[mask] = CROWN_SHAPES[name].extent(rho[mask])
    return base + s_low * length, base + s_high * length


def crown_radius(height, intercept, slope):
    """Crown radius of trees from their height: the linear crown allometry.

    Written with arithmetic only, so that it takes scalars or arrays and compiles
    unchanged under numba (:func:`forward.backends.jit`): the stand parameters, the
    species allometries and the expected model's kernels all call it.

    Parameters
    ----------
    height : float or array (m)
        Tree height h.
    intercept : float or array (m)
        Crown-radius intercept r0.
    slope : float or array (m/m)
        Crown radius per metre of height r1.

    Returns
    -------
    float or array (m)
        Rc = r0 + r1·h.

    References
    ----------
    Sun, G. & Ranson, K. J. (2000). Modeling lidar returns from forest canopies. *IEEE
    Trans. Geosci. Remote Sens.* 38(6), 2617–2626 (Table II: crown width from tree height).
    """
    return intercept + slope * height


def crown_volume(codes, crown_radius, crown_length):
    """Crown volume of each tree.

    Parameters
    ----------
    codes : array of int
        Shape codes (:func:`shape_codes`).
    crown_radius, crown_length : array (m)

    Returns
    -------
    array (m³)
        v_s·π·Rc²·Lc, v_s the shape's volume fraction of its cylinder.
    """
    fractions = np.array([CROWN_SHAPES[name].volume_fraction for name in SHAPE_NAMES])
    return fractions[codes] * np.pi * crown_radius**2 * crown_length
