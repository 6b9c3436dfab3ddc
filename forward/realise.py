"""Random explicit stands drawn from :class:`~forward.stand_params.StandParams`.

Stem positions come from a point-pattern registry, :data:`POINT_PATTERNS`:

- ``poisson``: a homogeneous Poisson process (the case the expected model is exact for);
- ``thomas``: a Thomas cluster process: Poisson parents, a Poisson number of offspring
  per parent, Gaussian displacements of sd ``cluster_sd`` (m), wrapped periodically;
- ``hardcore``: a regular pattern by sequential inhibition: a Poisson number of stems
  placed one by one, each at least ``min_distance`` (m, periodic) from those before.

Every pattern has the intensity ``params.density`` stems/ha. Heights, shapes and crowns are
drawn independently of the positions (independent marks).
"""

import numpy as np

from .crowns import SHAPE_NAMES
from .height_families import HEIGHT_DISTRIBUTIONS
from .scene import Ground, UniformUnderstory
from .stand import Stand


def _poisson(rng, n_mean, width, length):
    n = rng.poisson(n_mean)
    return rng.uniform(0.0, width, n), rng.uniform(0.0, length, n)


def _thomas(rng, n_mean, width, length, cluster_size=5.0, cluster_sd=3.0):
    if cluster_size <= 0 or cluster_sd <= 0:
        raise ValueError("thomas pattern needs cluster_size > 0 and cluster_sd > 0 (m)")
    parents = rng.poisson(n_mean / cluster_size)
    px, py = rng.uniform(0.0, width, parents), rng.uniform(0.0, length, parents)
    counts = rng.poisson(cluster_size, parents)
    x = np.repeat(px, counts) + rng.normal(0.0, cluster_sd, counts.sum())
    y = np.repeat(py, counts) + rng.normal(0.0, cluster_sd, counts.sum())
    return np.mod(x, width), np.mod(y, length)


def _hardcore(rng, n_mean, width, length, min_distance=1.5, max_tries=200):
    if min_distance < 0:
        raise ValueError("hardcore pattern needs min_distance ≥ 0 (m)")
    n = rng.poisson(n_mean)
    xs, ys = np.empty(n), np.empty(n)
    placed = 0
    for _ in range(n):
        for _ in range(max_tries):
            x, y = rng.uniform(0.0, width), rng.uniform(0.0, length)
            dx = np.abs(xs[:placed] - x)
            dy = np.abs(ys[:placed] - y)
            dx = np.minimum(dx, width - dx)
            dy = np.minimum(dy, length - dy)
            if not placed or np.min(dx * dx + dy * dy) >= min_distance**2:
                xs[placed], ys[placed] = x, y
                placed += 1
                break
        else:
            raise ValueError(
                f"hardcore pattern: could not place stem {placed + 1} of {n} with "
                f"min_distance {min_distance} m; the density is too high for it"
            )
    return xs, ys


#: Point patterns by name: ``pattern(rng, n_mean, width, length, **options) -> (x, y)``.
POINT_PATTERNS = {"poisson": _poisson, "thomas": _thomas, "hardcore": _hardcore}


def draw_heights(params, n, rng):
    """Heights and shapes of trees drawn from a stand's cohorts.

    Parameters
    ----------
    params : StandParams
    n : int
    rng : numpy.random.Generator

    Returns
    -------
    height : array (n,) (m)
        Each tree's cohort drawn by its weight, then its height from the cohort's
        distribution by inverse CDF (the family's closed-form quantile function; for the
        truncated-normal and Weibull families the very draws scipy's ``rvs`` makes from
        the same generator, without its overhead).
    shape : array of int8 (n,)
        Shape codes drawn from the cohort's mix.
    """
    family = HEIGHT_DISTRIBUTIONS[params.height_family]
    cohorts = params.cohort_laws()
    weights = np.array([w for w, _, _, _ in cohorts])
    which = rng.choice(len(cohorts), size=n, p=weights / weights.sum())
    height = np.empty(n)
    shape = np.empty(n, np.int8)
    for c, (_, mean, sd, mix) in enumerate(cohorts):
        sel = which == c
        k = int(sel.sum())
        if k:
            height[sel] = family.ppf(rng.uniform(size=k), mean, sd, params.height_truncation)
            shape[sel] = rng.choice(len(SHAPE_NAMES), size=k, p=mix / mix.sum())
    return height, shape


def realise(params, area, rng, pattern="poisson", origin=(0.0, 0.0), **options) -> Stand:
    """Draw one explicit stand from ``params``.

    Parameters
    ----------
    params : StandParams
    area : float or (float, float) (m)
        Side of a square plot, or its (width, length).
    rng : numpy.random.Generator
    pattern : str
        Key of :data:`POINT_PATTERNS`.
    origin : (float, float) (m)
        Lower-left corner of the plot.
    **options
        Pattern options (``cluster_size``, ``cluster_sd``, ``min_distance``).

    Returns
    -------
    Stand
        Shapes, crown length, crown radius and FAVD follow the parameters. The uniform
        understory and the ground are not part of a stem map: see :func:`scene_extras`.
    """
    if not isinstance(rng, np.random.Generator):
        raise TypeError("rng must be a numpy.random.Generator")
    width, length = (float(area), float(area)) if np.ndim(area) == 0 else map(float, area)
    if not (width > 0 and length > 0):
        raise ValueError(f"plot sides must be positive, got {area} m")
    try:
        draw = POINT_PATTERNS[pattern]
    except KeyError:
        raise ValueError(
            f"unknown point pattern {pattern!r}; known: {sorted(POINT_PATTERNS)}"
        ) from None
    x, y = draw(rng, params.density_per_m2 * width * length, width, length, **options)
    height, shape = draw_heights(params, x.size, rng)
    return Stand(
        x=x + origin[0],
        y=y + origin[1],
        height=height,
        crown_length=params.crown_length(height),
        crown_radius=params.crown_radius(height),
        shape=shape,
        favd=params.favd_by_shape()[shape],
    )


def scene_extras(params):
    """What the explicit engine needs of a stand beyond its stem map.

    Parameters
    ----------
    params : StandParams

    Returns
    -------
    ground : Ground
        Flat, with the stand's ground reflectance.
    understory : UniformUnderstory or None
        None where the understory LAI is 0.
    canopy_reflectance : float
        ρv.
    """
    understory = (
        UniformUnderstory(params.understory_height, params.understory_lai)
        if params.understory_lai > 0
        else None
    )
    return Ground(reflectance=params.ground_reflectance), understory, params.canopy_reflectance
