"""Parameter vectors of :class:`forward.expected.ExpectedWaveformModel`.

The fields a vector may carry (:data:`VECTOR_FIELDS`), the default free ones, and the
test of which full vectors describe a physical stand (:func:`physical_rows`): finite
values within each field's bounds, shape fractions summing to 1, and height moments the
family supports. Invalid rows are masked by the model, never raised on. Vectors are
built by field name (:func:`vectors_by_name`), never by position;
:func:`params_from_vector` turns a full vector back into a stand, e.g. to realise it.
"""

from dataclasses import replace

import numpy as np

from ..backends import as_float64, jit, resolve
from ..crowns import SHAPE_NAMES
from ..stand_params import StandParams

#: Every quantity a parameter vector may carry, in the order of the model's full vector.
VECTOR_FIELDS = (
    "density",
    "height_mean",
    "height_sd",
    "cohort2_fraction",
    "cohort2_height_mean",
    "cohort2_height_sd",
    "crown_length_ratio",
    "crown_radius_intercept",
    "crown_radius_slope",
    "favd",
    "understory_height",
    "understory_lai",
    "canopy_reflectance",
    "ground_reflectance",
    "ground_elevation",
    "height_cap",
    "apex_density",
    *(f"mix_{name}" for name in SHAPE_NAMES),
)

#: Fields that condition the stand on its tallest tree, with the values that do not.
CONDITIONING_FIELDS = {"height_cap": np.inf, "apex_density": 0.0}

#: Vector fields holding cohort 1's crown-shape fractions (≥ 0, summing to 1).
MIX_FIELDS = tuple(f"mix_{name}" for name in SHAPE_NAMES)

#: The default free parameters of :class:`ExpectedWaveformModel` (its vector layout).
DEFAULT_FREE = (
    "density",
    "height_mean",
    "height_sd",
    "crown_length_ratio",
    "crown_radius_slope",
    "favd",
    "canopy_reflectance",
    "ground_reflectance",
    "ground_elevation",
)

#: Column of each field in a full vector.
FIELD_INDEX = {name: i for i, name in enumerate(VECTOR_FIELDS)}
_I = FIELD_INDEX
_MIX = np.array([_I[name] for name in MIX_FIELDS], np.intp)


def vectors_by_name(columns, fields) -> np.ndarray:
    """Parameter vectors of the fields ``fields``, in their order, from named columns.

    Parameters
    ----------
    columns : dict
        Field name → values per row ((n,) arrays or scalars, broadcast to the rows).
    fields : tuple of str
        The vector layout, e.g. a model's ``parameter_names``.

    Returns
    -------
    array (n, len(fields))

    Raises
    ------
    ValueError
        Where a field has no column or a column names no field: a name slip is an error,
        never a silent shift of columns.
    """
    if columns.keys() != set(fields):
        missing = [name for name in fields if name not in columns]
        extra = sorted(set(columns) - set(fields))
        raise ValueError(f"vector columns: missing {missing}, not in the layout {extra}")
    rows = next((len(v) for v in columns.values() if isinstance(v, np.ndarray) and v.ndim), 1)
    out = np.empty((rows, len(fields)))
    for i, name in enumerate(fields):  # one assignment per column (a sampler's hot path)
        out[:, i] = columns[name]
    return out


def _bounds():
    """Per field of the full vector: lower bound, whether it is allowed, upper bound."""
    lower, upper = np.full(len(_I), -np.inf), np.full(len(_I), np.inf)
    closed = np.ones(len(_I), bool)
    positive = ("height_mean", "height_sd", "crown_length_ratio", "crown_radius_slope", "favd")
    for name in (*positive, "understory_height", "height_cap"):
        lower[_I[name]], closed[_I[name]] = 0.0, False
    non_negative = (
        "density",
        "cohort2_fraction",
        "crown_radius_intercept",
        "understory_lai",
        "apex_density",
    )
    for name in (*non_negative, "canopy_reflectance", "ground_reflectance", *MIX_FIELDS):
        lower[_I[name]] = 0.0
    upper[_I["cohort2_fraction"]] = upper[_I["crown_length_ratio"]] = 1.0
    return lower, closed, upper


_LOWER, _CLOSED, _UPPER = _bounds()


def physical_rows(v, family, truncation, backend="auto"):
    """Which full vectors describe a physical stand.

    Parameters
    ----------
    v : array (n, len(VECTOR_FIELDS))
        Full parameter vectors; NaN and infinite entries make a row invalid, but for an
        infinite ``height_cap`` (no cap) without apex trees.
    family : forward.stand_params.HeightFamily
        Height family of both cohorts.
    truncation : float (sd units)
        Truncation of the ``truncnorm`` family.
    backend : str
        ``"auto"``, ``"numba"`` or ``"numpy"`` (:mod:`forward.backends`): compiled, the
        checks of every field run in one pass over each row, and only the family's own
        validity in numpy; the same answer.

    Returns
    -------
    array of bool (n,)
        Finite values within each field's bounds, shape fractions summing to 1, height
        moments the family supports (cohort 2's only where it has trees).
    """
    if resolve(backend) == "numpy":
        return _physical_rows_numpy(v, family, truncation)
    v = as_float64(v)
    ok = _physical_rows(v, _LOWER, _CLOSED, _UPPER, _MIX, _KERNEL_COLUMNS)
    heights = v[:, _HEIGHT_COLUMNS]  # as the reference takes them: non-finite values as 1
    heights = np.where(np.isfinite(heights), heights, 1.0)
    ok &= family.valid(heights[:, 0], heights[:, 1], truncation)
    two = heights[:, 2] > 0
    if np.any(two):  # cohort 2's distribution matters only where it has trees
        good = family.valid(np.abs(heights[:, 3]) + 1e-9, np.abs(heights[:, 4]), truncation)
        ok &= ~two | good
    return ok


def _physical_rows_numpy(v, family, truncation):
    """The numpy reference of :func:`physical_rows`."""
    finite = np.isfinite(v)
    uncapped = v[:, _I["height_cap"]] == np.inf
    finite[:, _I["height_cap"]] |= uncapped
    ok = finite.all(axis=1) & ~(uncapped & (v[:, _I["apex_density"]] > 0))
    v = np.where(finite, v, 1.0)
    above = (v > _LOWER) | ((v == _LOWER) & _CLOSED)
    ok &= np.all(above & (v <= _UPPER), axis=1)
    ok &= np.abs(v[:, _MIX].sum(axis=1) - 1.0) < 1e-6
    ok &= family.valid(v[:, _I["height_mean"]], v[:, _I["height_sd"]], truncation)
    two = v[:, _I["cohort2_fraction"]] > 0
    if np.any(two):  # cohort 2's distribution matters only where it has trees
        mean, sd = v[:, _I["cohort2_height_mean"]], v[:, _I["cohort2_height_sd"]]
        good = (mean > 0) & (sd > 0)
        good &= family.valid(np.abs(mean) + 1e-9, np.abs(sd), truncation)
        ok &= ~two | good
    return ok


#: Columns the kernel of :func:`physical_rows` reads by name: the cap, the apex density,
#: cohort 2's share, mean and sd.
_KERNEL_COLUMNS = np.array(
    [_I[name] for name in ("height_cap", "apex_density", "cohort2_fraction",
                           "cohort2_height_mean", "cohort2_height_sd")], np.intp,
)  # fmt: skip
#: Columns the family's validity reads: cohort 1's mean and sd, then cohort 2's share, mean
#: and sd.
_HEIGHT_COLUMNS = np.array([_I["height_mean"], _I["height_sd"], *_KERNEL_COLUMNS[2:]], np.intp)


@jit
def _physical_rows(v, lower, closed, upper, mix, columns):
    """The kernel of :func:`physical_rows` but for the family's validity: finite values
    within bounds (an infinite cap without apex trees allowed), shape fractions summing to
    1, and cohort 2's positive mean and sd where it has trees."""
    n, fields = v.shape
    cap, apex, share, mean2, sd2 = columns[0], columns[1], columns[2], columns[3], columns[4]
    ok = np.ones(n, np.bool_)
    for r in range(n):
        good = True
        for j in range(fields):
            x = v[r, j]
            if not np.isfinite(x):
                if j == cap and x == np.inf:
                    good = good and not (v[r, apex] > 0)
                else:
                    good = False
                    x = 1.0
            above = x > lower[j] or (x == lower[j] and closed[j])
            good = good and above and x <= upper[j]
        total = 0.0
        for k in range(mix.size):
            x = v[r, mix[k]]
            total += x if np.isfinite(x) else 1.0
        good = good and abs(total - 1.0) < 1e-6
        x = v[r, share]
        if (x if np.isfinite(x) else 1.0) > 0:
            m, s = v[r, mean2], v[r, sd2]
            m, s = (m if np.isfinite(m) else 1.0), (s if np.isfinite(s) else 1.0)
            good = good and m > 0 and s > 0
        ok[r] = good
    return ok


def params_from_vector(full, template: StandParams) -> tuple[StandParams, float]:
    """The stand and the ground elevation of one full vector.

    Parameters
    ----------
    full : array (len(VECTOR_FIELDS),)
    template : StandParams
        Its fixed settings (height family, truncation, FAVD ratios) are kept.

    Returns
    -------
    params : StandParams
    ground_elevation : float (m)
        The inverse of :meth:`forward.expected.ExpectedWaveformModel.full_vector`.

    Raises
    ------
    ValueError
        For a vector conditioned on its tallest tree, which has no stem-map counterpart.
    """
    full = np.asarray(full, float)
    if full.shape != (len(VECTOR_FIELDS),):
        raise ValueError(f"a full vector has {len(VECTOR_FIELDS)} values, got shape {full.shape}")
    values = dict(zip(VECTOR_FIELDS, full.tolist()))
    for name, neutral in CONDITIONING_FIELDS.items():
        if values.pop(name) != neutral:
            raise ValueError(f"a stand with {name} ≠ {neutral} has no stem-map counterpart")
    ground = values.pop("ground_elevation")
    mix = tuple(values.pop(name) for name in MIX_FIELDS)
    return replace(template, shape_mix=mix, **values), ground
