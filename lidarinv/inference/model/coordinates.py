"""Sampling coordinates that straighten the posterior's ridges.

Only the coordinates the sampler moves in change; the prior stays the one set on the
parameters, through the Jacobian of each map.

**Crown cover and PAI**, which the waveform ties together along an L-shaped ridge: the
joint coordinates (s, v) of :mod:`.cover_pai`.

**Crown length ratio ℓ** against the mean tree height H̄ = top − TOP_SDS·sd. The waveform
fixes the crown-base height of the mean tree, B = (1 − ℓ)·H̄, far better than either
factor: in (top, sd, ℓ) the posterior bends along B = const (ℓ and H̄ strongly
correlated). Sampling the crown base instead of ℓ straightens it. With ℓ's prior on
[ℓ₀, ℓ₁], B lies in [(1 − ℓ₁)·H̄, (1 − ℓ₀)·H̄], and the coordinate

    b = ln(B − B₀) − ln(B₁ − B) + ln(B₁ − B₀) = logit(t) + ln((ℓ₁ − ℓ₀)·H̄),
    t = (ℓ₁ − ℓ)/(ℓ₁ − ℓ₀),

is ln(B − B₀) wherever B stays clear of its upper end (ln B for the default ℓ₁ = 1) and
spans ℝ, so that no move leaves the prior (a plain b = ln B had a wall at B = B₁ which a
quarter of the proposals hit on short stands); |∂ℓ/∂b| = (ℓ₁ − ℓ₀)·t·(1 − t).

**Ground elevation** against the understory. The ground and a low understory (LAI Lu,
height hu) return one blob, a pulse width wide, whose centroid the waveform fixes to about
a centimetre while the ground elevation zg alone spreads several times wider: more or
taller understory lifts the centroid, so zg must sink. In (zg, Lu, hu) the posterior is a
thin curved sheet, its narrowest direction heavy-tailed.
Sampling the centroid c = zg + f(Lu, hu, r) instead of zg flattens it, where f is the
height of the blob's centroid above the ground (single scattering, complete hot spot,
canopy gaps common to both parts, r = ρv/ρg, q = a·Lu):

    f = hu · r · (1 − (1 − e^{−q}) / q) / (r·(1 − e^{−q}) + e^{−q}).

zg = c − f at fixed (Lu, hu, r) has |∂zg/∂c| = 1. The centroid's unbounded map spans the
ground prior's range widened upwards by the largest f (f ≤ hu), so that every ground
elevation in the prior stays reachable.

The top height's own coordinates (against the height sd and the footprint's tallest
stem) are in :mod:`.top_coordinates`.

**The lower storey's top ratio ρ** against the upper storey's top H₁ (a two-storey stand,
:mod:`.two_cohort`). The waveform places the lower storey's return, so it fixes that
storey's own top H₂ = ρ·H₁ far better than either factor: in (H₁, ρ) the posterior bends
along ρ = H₂/H₁. With ρ's prior on [ρ₀, ρ₁], H₂ lies in [ρ₀·H₁, ρ₁·H₁]; with
t = (ρ − ρ₀)/(ρ₁ − ρ₀) and W = (ρ₁ − ρ₀)·H₁ the coordinate

    c = ln(H₂ − ρ₀·H₁) − ln(1 − t^p)/p = ln(t·W) − ln(1 − t^p)/p

is ln(H₂ − ρ₀·H₁) until t^p is no longer small, and spans ℝ with a smooth wall at
ρ₁ (p = 1 is the crown base's logistic form). At fixed c, ∂H₂/∂H₁ = ρ₀ + (ρ₁ − ρ₀)·t^{p+1},
against ρ at fixed ρ: the lower storey's top stays in place as the upper storey's moves.
Its inverse, with y = e^c/W: t = y·(1 + y^p)^{−1/p}, and |∂ρ/∂c| = (ρ₁ − ρ₀)·t·(1 − t^p).
"""

import math

import numpy as np
from scipy.special import expit

from forward.backends import jit, resolve

from .cover_pai import (  # noqa: F401  (re-exported: the cover–PAI maps are coordinates too)
    INTERCEPTION_SLOPE,
    cover_pai_compiled,
    from_cover_pai,
    from_cover_pai_bounded,
    ridge_range,
    to_cover_pai,
    to_cover_pai_bounded,
)
from .prior_table import LOGIT, unit_and_log_slope

#: Ridge-straightening coordinates by name (see :class:`.space.ParameterSpace`).
RIDGE_COORDINATES = (
    "cover-pai",
    "crown-base",
    "ground-centroid",
    "tallest-stem",
    "lower-storey-top",
    "mean-height",
)

#: Those used by default (``studies/sampling_coordinates.py`` measures τ per choice). The
#: tallest stem's gap applies only where that latent is sampled.
DEFAULT_RIDGES = ("cover-pai", "crown-base", "ground-centroid", "tallest-stem")

#: p of the lower storey's coordinate (:func:`lower_top_from_ratio`): its top stays within
#: (ρ₁ − ρ₀)·t^{p+1} of in place as the upper storey's top moves; a larger p keeps it so
#: closer to the prior's upper end, with a steeper wall there.
LOWER_TOP_WALL_POWER = 4.0


def crown_base_from_ratio(ratio, mean_height, bounds=(0.0, 1.0)):
    """The crown-base coordinate of the mean tree.

    Parameters
    ----------
    ratio : array
        Crown length ratio ℓ.
    mean_height : array (m)
        H̄.
    bounds : (float, float)
        ℓ₀, ℓ₁: the support of ℓ's prior, within [0, 1].

    Returns
    -------
    array
        b = logit((ℓ₁ − ℓ)/(ℓ₁ − ℓ₀)) + ln((ℓ₁ − ℓ₀)·H̄); NaN where H̄ ≤ 0 or ℓ ∉ (ℓ₀, ℓ₁).
    """
    ratio, mean_height = np.asarray(ratio, float), np.asarray(mean_height, float)
    lower, upper = bounds
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (upper - ratio) / (upper - lower)
        base = np.log(t) - np.log1p(-t) + np.log((upper - lower) * mean_height)
    bad = ~((ratio > lower) & (ratio < upper) & (mean_height > 0))
    return np.where(bad, np.nan, base)


def ratio_from_crown_base(b, mean_height, bounds=(0.0, 1.0)):
    """Crown length ratio from the crown-base coordinate.

    Parameters
    ----------
    b : array
    mean_height : array (m)
    bounds : (float, float)
        ℓ₀, ℓ₁.

    Returns
    -------
    ratio, log_jac : arrays
        ℓ = ℓ₀ + (ℓ₁ − ℓ₀)·(1 − t), t the logistic of b − ln((ℓ₁ − ℓ₀)·H̄), and log|∂ℓ/∂b|;
        NaN where H̄ ≤ 0.
    """
    mean_height = np.asarray(mean_height, float)
    lower, upper = bounds
    with np.errstate(over="ignore", divide="ignore", invalid="ignore"):
        mean_height = np.where(mean_height > 0, mean_height, np.nan)
        z = b - np.log((upper - lower) * mean_height)
        log_jac = np.log(upper - lower) - np.logaddexp(0.0, -z) - np.logaddexp(0.0, z)
        ratio = np.minimum(lower + (upper - lower) * expit(-z), upper)  # 1 − t = expit(−z)
        return ratio, log_jac


def understory_centroid(lai, height, rho_ratio, slope=INTERCEPTION_SLOPE):
    """Height above the ground of the centroid of the ground-plus-understory return.

    Parameters
    ----------
    lai : array (m²/m²)
        Understory LAI L_u.
    height : array (m)
        Understory height h_u.
    rho_ratio : array
        ρv/ρg.
    slope : float
        a = k·G·Ω.

    Returns
    -------
    array (m)
        f = h_u·r·(1 − (1 − e^{−q})/q)/(r·(1 − e^{−q}) + e^{−q}), q = a·L_u; 0 without
        understory.
    """
    lai, height, rho_ratio = (np.asarray(a, float) for a in (lai, height, rho_ratio))
    q = slope * lai
    with np.errstate(divide="ignore", invalid="ignore"):
        intercepted = -np.expm1(-q)
        moment = np.where(q > 0, 1.0 - intercepted / q, 0.0)
        centroid = height * rho_ratio * moment / (rho_ratio * intercepted + np.exp(-q))
    return np.where(q > 0, centroid, 0.0)


def lower_top_from_ratio(ratio, top, bounds, power=LOWER_TOP_WALL_POWER):
    """The lower storey's top coordinate.

    Parameters
    ----------
    ratio : array
        The lower storey's top over the upper storey's, ρ.
    top : array (m)
        The upper storey's top height H₁.
    bounds : (float, float)
        ρ₀, ρ₁: the support of ρ's prior, within [0, 1].
    power : float
        p > 0, the sharpness of the wall at ρ₁.

    Returns
    -------
    array
        c = ln(t·(ρ₁ − ρ₀)·H₁) − ln(1 − t^p)/p, t = (ρ − ρ₀)/(ρ₁ − ρ₀): ln(H₂ − ρ₀·H₁)
        away from ρ₁ (H₂ = ρ·H₁ in m); NaN where H₁ ≤ 0 or ρ ∉ (ρ₀, ρ₁).
    """
    ratio, top = np.asarray(ratio, float), np.asarray(top, float)
    lower, upper = bounds
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (ratio - lower) / (upper - lower)
        c = np.log(t * (upper - lower) * top) - np.log1p(-(t**power)) / power
    bad = ~((ratio > lower) & (ratio < upper) & (top > 0))
    return np.where(bad, np.nan, c)


def ratio_from_lower_top(c, top, bounds, power=LOWER_TOP_WALL_POWER):
    """The lower storey's top ratio from its coordinate: the inverse of
    :func:`lower_top_from_ratio`.

    Parameters
    ----------
    c : array
    top : array (m)
        H₁.
    bounds : (float, float)
        ρ₀, ρ₁.
    power : float
        p.

    Returns
    -------
    ratio, log_jac : arrays
        ρ = ρ₀ + (ρ₁ − ρ₀)·t, t = y·(1 + y^p)^{−1/p} with y = e^c/((ρ₁ − ρ₀)·H₁), and
        log|∂ρ/∂c| = ln((ρ₁ − ρ₀)·t·(1 − t^p)); NaN where H₁ ≤ 0.
    """
    top = np.asarray(top, float)
    lower, upper = bounds
    with np.errstate(over="ignore", divide="ignore", invalid="ignore"):
        top = np.where(top > 0, top, np.nan)
        z = c - np.log((upper - lower) * top)  # ln y
        soft = np.logaddexp(0.0, power * z) / power  # ln(1 + y^p)/p = −ln(1 − t^p)/p
        log_t = z - soft
        ratio = np.minimum(lower + (upper - lower) * np.exp(log_t), upper)
        return ratio, np.log(upper - lower) + log_t - power * soft


#: Column code of a parameter held fixed in a ridge map's inputs (its value is passed).
FIXED = -1


def ridges_from_unbounded(
    u, x, log_jac, joint, base, centroid, inputs, top_sds, slope, *, storey=None, backend="auto"
):
    """Overwrite the ridge coordinates' columns of x and log_jac with physical values.

    Parameters
    ----------
    u : array (n, k)
        Unbounded coordinates.
    x, log_jac : arrays (n, k)
        Values and log|dx/du| per column from the priors' maps; the ridge columns are
        overwritten in place.
    joint : tuple or None
        (cover column, PAI column, cover bounds, PAI bounds) of the cover–PAI coordinates.
    base : tuple or None
        (column, ℓ₀, ℓ₁) of the crown-base coordinate: the crown length ratio's column and
        its prior's support.
    centroid : tuple or None
        (ground column, lower, stretch) of the ground-centroid coordinate.
    inputs : (array of int, array of float)
        Columns of x holding top height, height sd, understory LAI, understory height and
        ρv/ρg, each a column or :data:`FIXED` with its value in the second array.
    top_sds : float
        Mean tree height = top − ``top_sds``·sd.
    slope : float
        a = k·G·Ω of the instrument (:func:`to_cover_pai`).
    storey : tuple or None
        (column, ρ₀, ρ₁, p) of the lower storey's top coordinate: the top ratio's column,
        its prior's support and the wall's power (:func:`ratio_from_lower_top`).
    backend : str
        ``"auto"``, ``"numba"`` or ``"numpy"`` (:func:`forward.backends.resolve`).

    Notes
    -----
    Cover and PAI from (s, v) by :func:`to_cover_pai_bounded`; ℓ = 1 − e^b/H̄ by
    :func:`ratio_from_crown_base`; z_g = c − f(L_u, h_u, r) by :func:`understory_centroid`;
    the lower storey's top ratio by :func:`ratio_from_lower_top`.
    """
    columns, fixed = inputs
    if resolve(backend) == "numba":
        if joint is not None:
            c, a, cover_bounds, pai_bounds = joint
            cover_pai_compiled(u, x, log_jac, c, a, cover_bounds, pai_bounds, slope)
        if base is not None or centroid is not None:
            _crown_and_ground_compiled(
                u, x, log_jac, base, centroid, columns, fixed, top_sds, slope
            )
        if storey is not None:
            _lower_top(u, x, log_jac, np.array(storey, float), columns[0], fixed[0])
        return
    top, sd, lai, height, ratio = (
        x[:, col] if col != FIXED else value for col, value in zip(columns, fixed)
    )
    if joint is not None:
        c, a, cover_bounds, pai_bounds = joint
        x[:, c], x[:, a], log_jac[:, c] = to_cover_pai_bounded(
            u[:, c], u[:, a], cover_bounds, pai_bounds, slope
        )
        log_jac[:, a] = 0.0
    if base is not None:
        r, lower, upper = base
        x[:, r], log_jac[:, r] = ratio_from_crown_base(u[:, r], top - top_sds * sd, (lower, upper))
    if storey is not None:
        k, lower, upper, power = storey
        x[:, k], log_jac[:, k] = ratio_from_lower_top(u[:, k], top, (lower, upper), power)
    if centroid is not None:
        g, lower, stretch = centroid
        level = lower + (x[:, g] - lower) * stretch
        x[:, g] = level - understory_centroid(lai, height, ratio, slope)
        log_jac[:, g] += np.log(stretch)


# The crown-base, ground-centroid and lower-storey maps compiled (twins of the numpy maps).
# error_model="numpy": x/0 gives ±inf or NaN, as in the numpy maps, instead of raising.


@jit(error_model="numpy")
def _value(x, r, column, fixed):
    return x[r, column] if column != FIXED else fixed


@jit(error_model="numpy")
def _crown_and_ground(u, x, log_jac, base, centroid, columns, fixed, top_sds, slope):
    """Crown length ratio from the crown base (``base``: column, ℓ₀, ℓ₁; column < 0 for
    none) and ground elevation from the ground-plus-understory centroid (``centroid``:
    column, lower, stretch; column < 0 for none). ``columns``/``fixed``: top height, height
    sd, understory LAI, understory height, ρv/ρg, each a column of x or FIXED and a value."""
    g, c = int(centroid[0]), int(base[0])
    width = base[2] - base[1]
    for r in range(u.shape[0]):
        if c >= 0:
            top = _value(x, r, columns[0], fixed[0])
            mean = top - top_sds * _value(x, r, columns[1], fixed[1])
            mean = mean if mean > 0.0 else math.nan
            z = u[r, c] - math.log(width * mean)
            rest, log_slope = unit_and_log_slope(-z, LOGIT)  # 1 − t, ln t(1 − t)
            x[r, c] = min(base[1] + width * rest, base[2])
            log_jac[r, c] = math.log(width) + log_slope
        if g >= 0:
            lai = _value(x, r, columns[2], fixed[2])
            height = _value(x, r, columns[3], fixed[3])
            ratio = _value(x, r, columns[4], fixed[4])
            q = slope * lai
            lift = 0.0
            if q > 0.0:
                intercepted = -math.expm1(-q)
                moment = 1.0 - intercepted / q
                lift = height * ratio * moment / (ratio * intercepted + math.exp(-q))
            lower, stretch = centroid[1], centroid[2]
            x[r, g] = lower + (x[r, g] - lower) * stretch - lift
            log_jac[r, g] += math.log(stretch)


def _crown_and_ground_compiled(u, x, log_jac, base, centroid, columns, fixed, top_sds, slope):
    """Write the crown length ratio and the ground elevation from their ridge coordinates
    in place (:func:`_crown_and_ground`); ``base`` None or ``centroid`` None skip one."""
    centroid = np.array([-1.0, 0.0, 1.0] if centroid is None else centroid, float)
    base = np.array([-1.0, 0.0, 1.0] if base is None else base, float)
    _crown_and_ground(u, x, log_jac, base, centroid, columns, fixed, top_sds, slope)


@jit(error_model="numpy")
def _lower_top(u, x, log_jac, storey, top_column, top_fixed):
    """The lower storey's top ratio from its coordinate (:func:`ratio_from_lower_top`) in
    place; ``storey``: column, ρ₀, ρ₁, p; the upper top a column of x or FIXED and a value."""
    k, lower, upper, power = int(storey[0]), storey[1], storey[2], storey[3]
    width = upper - lower
    for r in range(u.shape[0]):
        top = _value(x, r, top_column, top_fixed)
        top = top if top > 0.0 else math.nan
        z = u[r, k] - math.log(width * top)
        a = power * z  # ln(1 + e^a) without overflow, NaN kept
        soft = (a + math.log1p(math.exp(-a)) if a > 0.0 else math.log1p(math.exp(a))) / power
        log_t = z - soft
        ratio = lower + width * math.exp(log_t)
        x[r, k] = upper if ratio > upper else ratio
        log_jac[r, k] = math.log(width) + log_t - power * soft
