"""Sampling coordinates that straighten the posterior's ridges.

Only the coordinates the sampler moves in change; the prior stays the one set on the
parameters, through the Jacobian of each map.

**Crown cover and PAI**, which the waveform ties together. A waveform fixes the canopy's
interception, −ln P̄(0) ≈ X·(1 − exp(−a·Lc)), where X = −ln(1 − cover) = λ·E[crown area]
and Lc = PAI / X is the foliage area per unit of crown-projected area. Few dense crowns
(small X, large Lc) and many sparse ones (large X, small Lc) give the same interception,
so in (cover, PAI) the posterior follows an L-shaped ridge that ensemble moves cross
slowly. The coordinates

    s = ln Y,  Y = X·(1 − exp(−a·Lc)),      t = ln Lc

turn that ridge into a nearly straight line along t at fixed s, with the Jacobian

    |∂(cover, PAI) / ∂(s, t)| = exp(−X)·X²·Lc.

Where the data leave the position along the ridge to the prior, the posterior runs into
the prior's walls: along t at fixed s cover falls and PAI rises, so each bound cuts t
once and the prior's rectangle is an interval [t_lo(s), t_hi(s)] (:func:`ridge_range`).
The sampler moves v, with t = t_lo + (t_hi − t_lo)·σ(v), the logistic map the other
bounded parameters get, and |∂t/∂v| = (t_hi − t_lo)·σ(v)·(1 − σ(v)).

**Crown length ratio ℓ** against the mean tree height H̄ = top − TOP_SDS·sd. The waveform
fixes the crown-base height of the mean tree, B = (1 − ℓ)·H̄, far better than either
factor: in (top, sd, ℓ) the posterior bends along B = const (ℓ and H̄ strongly
correlated). Sampling b = ln B instead of ℓ straightens it; |∂ℓ/∂b| = B / H̄.

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

**Top height** against the footprint's tallest stem H (the latent of a footprint
conditioned on it, :class:`.stand_mapping.StandMapping`). The waveform sees H, and the
stand's top lies above it by a gap whose law, near the top, is close to exponential with
its mode at zero. In (top, H) the posterior is a wedge, top ≥ H, densest along its edge.
Sampling g = ln(top − H) instead of top opens the wedge into a smooth, one-humped density
along g at fixed H; top = H + e^g has |∂top/∂g| = e^g.
"""

import math

import numpy as np
from scipy.special import expit, lambertw

from forward.backends import jit, resolve
from forward.instrument import DEFAULT_EXTINCTION_PER_FAVD
from forward.poisson_stand import cover_from_crown_count, crown_count

from .priors import LOGIT, _unit_and_log_slope

#: Ridge-straightening coordinates by name (see :class:`.space.ParameterSpace`).
RIDGE_COORDINATES = ("cover-pai", "crown-base", "ground-centroid", "tallest-stem")

#: Those used by default: all of them (``studies/sampling_coordinates.py`` measures τ per
#: choice). The tallest stem's gap applies only where that latent is sampled.
DEFAULT_RIDGES = RIDGE_COORDINATES

#: a in 1 − exp(−a·Lc) where no instrument is given: k·G·Ω of the default
#: :class:`forward.instrument.Instrument` (a complete hot spot, spherical leaf angles, no
#: clumping); a shot's space takes its instrument's ``extinction_per_favd``.
INTERCEPTION_SLOPE = DEFAULT_EXTINCTION_PER_FAVD


def from_cover_pai(cover, pai, slope=INTERCEPTION_SLOPE):
    """The joint coordinates (s, t) of cover and PAI.

    Parameters
    ----------
    cover : float or array
    pai : float or array (m²/m²)
    slope : float
        a = k·G·Ω of the instrument.

    Returns
    -------
    s, t : arrays
        s = ln X·(1 − e^{−a·Lc}), t = ln Lc with X = −ln(1 − cover) and Lc = PAI/X; NaN
        where cover ∉ (0, 1) or PAI ≤ 0.
    """
    with np.errstate(divide="ignore", invalid="ignore"):
        x = crown_count(np.asarray(cover, float))
        lc = np.asarray(pai, float) / x
        s = np.log(x) + np.log(-np.expm1(-slope * lc))
        t = np.log(lc)
    bad = ~((cover > 0) & (cover < 1) & (pai > 0))
    return np.where(bad, np.nan, s), np.where(bad, np.nan, t)


def to_cover_pai(s, t, slope=INTERCEPTION_SLOPE):
    """Cover, PAI and the Jacobian from the joint coordinates.

    Parameters
    ----------
    s, t : arrays
    slope : float
        a = k·G·Ω.

    Returns
    -------
    cover, pai, log_jac : arrays
        log|∂(cover, PAI)/∂(s, t)| = −X + 2 ln X + t.
    """
    with np.errstate(over="ignore", divide="ignore", invalid="ignore"):
        lc = np.exp(t)
        x = np.exp(s) / -np.expm1(-slope * lc)
        cover = cover_from_crown_count(x)
        pai = lc * x
        log_jac = -x + 2.0 * np.log(x) + t
    return cover, pai, log_jac


def ridge_range(s, cover_bounds, pai_bounds, slope=INTERCEPTION_SLOPE):
    """The range of t = ln Lc at interception s = ln Y over which cover and PAI stay within
    their priors' bounds.

    Parameters
    ----------
    s : float or array
    cover_bounds, pai_bounds : (float, float)
    slope : float
        a = k·G·Ω.

    Returns
    -------
    t_lo, t_hi : arrays
        NaN where no t does.

    Notes
    -----
    Along t at fixed s, X = Y/(1 − e^{−a·Lc}) falls, so cover falls, and PAI = Lc·X
    rises: each bound cuts t once. PAI = p at Lc = u/a with u = ak + W₀(−ak·e^{−ak}),
    k = p/Y (W₀ the principal branch of Lambert's W), which exists for ak > 1.
    """
    y = np.exp(np.array(s, float, ndmin=1))
    (c_lo, c_hi), (p_lo, p_hi) = cover_bounds, pai_bounds
    with np.errstate(divide="ignore", invalid="ignore"):
        # cover ≤ c_hi: X ≤ −ln(1 − c_hi); PAI ≤ p_hi
        low = np.log(np.log1p(-y / crown_count(c_hi)) / -slope)
        high = _log_lc_at_pai(p_hi / y, slope)
        # cover ≥ c_lo (X ≥ x_lo) and PAI ≥ p_lo bind only where Y < x_lo or Y < a·p_lo
        x_lo = crown_count(c_lo)
        sparse = y < max(x_lo, slope * p_lo)
        if sparse.any():
            ys = y[sparse]
            below = np.where(ys < x_lo, np.log(-np.log1p(-ys / x_lo) / slope), np.inf)
            above = np.where(slope * p_lo > ys, _log_lc_at_pai(p_lo / ys, slope), -np.inf)
            high[sparse] = np.minimum(high[sparse], below)
            low[sparse] = np.maximum(low[sparse], above)
        empty = ~(low < high)
    low[empty] = high[empty] = np.nan
    return low.reshape(np.shape(s)), high.reshape(np.shape(s))


def _log_lc_at_pai(k, slope):
    """ln Lc where Lc/(1 − e^{−a·Lc}) = k (m²/m² per unit interception); NaN for ak ≤ 1."""
    ak = slope * np.asarray(k, float)
    with np.errstate(over="ignore", invalid="ignore"):
        u = ak + lambertw(-ak * np.exp(-ak)).real
        return np.where(ak > 1, np.log(u / slope), np.nan)


def to_cover_pai_bounded(s, v, cover_bounds, pai_bounds, slope=INTERCEPTION_SLOPE):
    """Cover, PAI and the Jacobian from s and the ridge position v.

    Parameters
    ----------
    s, v : arrays
    cover_bounds, pai_bounds : (float, float)
    slope : float

    Returns
    -------
    cover, pai, log_jac : arrays
        t = t_lo + (t_hi − t_lo)·σ(v) over :func:`ridge_range`, then :func:`to_cover_pai`;
        log|∂(cover, PAI)/∂(s, v)|. NaN where s admits no t.
    """
    low, high = ridge_range(s, cover_bounds, pai_bounds, slope)
    with np.errstate(over="ignore", divide="ignore", invalid="ignore"):
        t = low + (high - low) * expit(v)
        cover, pai, log_jac = to_cover_pai(s, t, slope)
        log_jac = log_jac + np.log(high - low) - np.logaddexp(0.0, v) - np.logaddexp(0.0, -v)
    return cover, pai, log_jac


def from_cover_pai_bounded(cover, pai, cover_bounds, pai_bounds, slope=INTERCEPTION_SLOPE):
    """(s, v) of cover and PAI within the bounds: the inverse of :func:`to_cover_pai_bounded`.

    Parameters
    ----------
    cover, pai : arrays
    cover_bounds, pai_bounds : (float, float)
    slope : float

    Returns
    -------
    s, v : arrays
        NaN outside the bounds.
    """
    s, t = from_cover_pai(cover, pai, slope)
    low, high = ridge_range(s, cover_bounds, pai_bounds, slope)
    with np.errstate(divide="ignore", invalid="ignore"):
        fraction = (t - low) / (high - low)
        v = np.log(fraction) - np.log1p(-fraction)
    inside = (cover >= cover_bounds[0]) & (cover <= cover_bounds[1])
    inside &= (pai >= pai_bounds[0]) & (pai <= pai_bounds[1])
    return np.where(inside, s, np.nan), np.where(inside, v, np.nan)


def crown_base_from_ratio(ratio, mean_height):
    """The log crown-base height of the mean tree.

    Parameters
    ----------
    ratio : array
        Crown length ratio ℓ.
    mean_height : array (m)
        H̄.

    Returns
    -------
    array
        b = ln((1 − ℓ)·H̄); NaN where H̄ ≤ 0 or ℓ ∉ [0, 1).
    """
    ratio, mean_height = np.asarray(ratio, float), np.asarray(mean_height, float)
    with np.errstate(divide="ignore", invalid="ignore"):
        base = np.log((1.0 - ratio) * mean_height)
    bad = ~((ratio >= 0) & (ratio < 1) & (mean_height > 0))
    return np.where(bad, np.nan, base)


def ratio_from_crown_base(b, mean_height):
    """Crown length ratio from the log crown-base height.

    Parameters
    ----------
    b : array
    mean_height : array (m)

    Returns
    -------
    ratio, log_jac : arrays
        ℓ = 1 − e^b/H̄ and log|∂ℓ/∂b|; NaN where H̄ ≤ 0.
    """
    mean_height = np.asarray(mean_height, float)
    with np.errstate(over="ignore", divide="ignore", invalid="ignore"):
        mean_height = np.where(mean_height > 0, mean_height, np.nan)
        relative = np.exp(b) / mean_height
        return 1.0 - relative, np.log(relative)


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


def top_from_stem_gap(tallest, log_gap):
    """Top height from the tallest stem and the log gap above it.

    Parameters
    ----------
    tallest : array (m)
        H.
    log_gap : array
        g.

    Returns
    -------
    top, log_jac : arrays
        top = H + e^g (m) and log|∂top/∂g| = g.
    """
    return tallest + np.exp(log_gap), np.asarray(log_gap, float)


def stem_gap_from_top(top, tallest):
    """The log gap above the tallest stem: the inverse of :func:`top_from_stem_gap`.

    Parameters
    ----------
    top, tallest : arrays (m)

    Returns
    -------
    array
        g = ln(top − H); NaN where top ≤ H.
    """
    gap = np.asarray(top, float) - tallest
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(gap > 0, np.log(gap), np.nan)


#: Column code of a parameter held fixed in a ridge map's inputs (its value is passed).
FIXED = -1


def ridges_from_unbounded(
    u, x, log_jac, joint, base, centroid, inputs, top_sds, slope, *, backend="auto"
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
    base : int or None
        Column of the crown-base coordinate (the crown length ratio's).
    centroid : tuple or None
        (ground column, lower, stretch) of the ground-centroid coordinate.
    inputs : (array of int, array of float)
        Columns of x holding top height, height sd, understory LAI, understory height and
        ρv/ρg, each a column or :data:`FIXED` with its value in the second array.
    top_sds : float
        Mean tree height = top − ``top_sds``·sd.
    slope : float
        a = k·G·Ω of the instrument (:func:`to_cover_pai`).
    backend : str
        ``"auto"``, ``"numba"`` or ``"numpy"`` (:func:`forward.backends.resolve`).

    Notes
    -----
    Cover and PAI from (s, v) by :func:`to_cover_pai_bounded`; ℓ = 1 − e^b/H̄ by
    :func:`ratio_from_crown_base`; z_g = c − f(L_u, h_u, r) by :func:`understory_centroid`.
    """
    if resolve(backend) == "numba":
        if joint is not None:
            c, a, cover_bounds, pai_bounds = joint
            _cover_pai_compiled(u, x, log_jac, c, a, cover_bounds, pai_bounds, slope)
        if base is not None or centroid is not None:
            columns, fixed = inputs
            _crown_and_ground_compiled(
                u, x, log_jac, base, centroid, columns, fixed, top_sds, slope
            )
        return
    columns, fixed = inputs
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
        x[:, base], log_jac[:, base] = ratio_from_crown_base(u[:, base], top - top_sds * sd)
    if centroid is not None:
        g, lower, stretch = centroid
        level = lower + (x[:, g] - lower) * stretch
        x[:, g] = level - understory_centroid(lai, height, ratio, slope)
        log_jac[:, g] += np.log(stretch)


# The ridge maps compiled (the twins of the numpy maps above, in two passes over the rows
# with scipy's lambertw between them). error_model="numpy": x/0 gives ±inf or NaN, as in
# the numpy maps, instead of raising.

_crown_count = jit(crown_count)
_cover_from_crown_count = jit(cover_from_crown_count)


@jit(error_model="numpy")
def _lambert_arguments(u, column, slope, p_hi, p_lo, sparse_below):
    """−ak·e^{−ak} with ak = a·p/Y for the PAI bounds p_hi (every row) and p_lo (rows
    whose interception Y = exp(s) lies below ``sparse_below``; NaN elsewhere)."""
    n = u.shape[0]
    high, low = np.empty(n), np.full(n, np.nan)
    for r in range(n):
        y = math.exp(u[r, column])
        ak = slope * p_hi / y
        high[r] = -ak * math.exp(-ak)
        if y < sparse_below:
            ak = slope * p_lo / y
            low[r] = -ak * math.exp(-ak)
    return high, low


@jit(error_model="numpy")
def _log_lc_at_pai_row(k_slope, w, slope):
    """ln Lc where PAI meets a bound, from ak and W₀(−ak·e^{−ak}); NaN for ak ≤ 1."""
    if not (k_slope > 1.0):
        return math.nan
    return math.log((k_slope + w) / slope)


@jit(error_model="numpy")
def _cover_pai(u, x, log_jac, c, a, bounds, slope, w_high, w_low):
    """Cover and PAI into x[:, c], x[:, a] (as :func:`to_cover_pai_bounded`)."""
    c_lo, c_hi, p_lo, p_hi = bounds[0], bounds[1], bounds[2], bounds[3]
    x_hi = _crown_count(c_hi)
    x_lo = _crown_count(c_lo)
    for r in range(u.shape[0]):
        s, v = u[r, c], u[r, a]
        y = math.exp(s)
        low = math.log(math.log1p(-y / x_hi) / -slope)
        high = _log_lc_at_pai_row(slope * p_hi / y, w_high[r], slope)
        if y < max(x_lo, slope * p_lo):
            if y < x_lo:
                high = min(high, math.log(-math.log1p(-y / x_lo) / slope))
            if slope * p_lo > y:
                low = max(low, _log_lc_at_pai_row(slope * p_lo / y, w_low[r], slope))
        if not (low < high):  # NaN bounds included
            x[r, c] = x[r, a] = log_jac[r, c] = math.nan
            log_jac[r, a] = 0.0
            continue
        unit, log_slope = _unit_and_log_slope(v, LOGIT)
        t = low + (high - low) * unit
        lc = math.exp(t)
        crowns = y / -math.expm1(-slope * lc)  # X = −ln(1 − cover)
        x[r, c] = _cover_from_crown_count(crowns)
        x[r, a] = lc * crowns
        log_jac[r, c] = -crowns + 2.0 * math.log(crowns) + t + math.log(high - low) + log_slope
        log_jac[r, a] = 0.0


@jit(error_model="numpy")
def _value(x, r, column, fixed):
    return x[r, column] if column != FIXED else fixed


@jit(error_model="numpy")
def _crown_and_ground(u, x, log_jac, base, centroid, columns, fixed, top_sds, slope):
    """Crown length ratio from the crown base (``base`` ≥ 0: its column) and ground
    elevation from the ground-plus-understory centroid (``centroid``: column, lower,
    stretch; column < 0 for none). ``columns``/``fixed``: top height, height sd,
    understory LAI, understory height, ρv/ρg, each a column of x or FIXED and a value."""
    g = int(centroid[0])
    for r in range(u.shape[0]):
        if base >= 0:
            top = _value(x, r, columns[0], fixed[0])
            mean = top - top_sds * _value(x, r, columns[1], fixed[1])
            mean = mean if mean > 0.0 else math.nan
            relative = math.exp(u[r, base]) / mean
            x[r, base] = 1.0 - relative
            log_jac[r, base] = math.log(relative)
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


def _cover_pai_compiled(u, x, log_jac, c, a, cover_bounds, pai_bounds, slope):
    """Write cover and PAI (columns ``c``, ``a`` of x) and their log-Jacobian from the
    joint coordinates (s, v) in the same columns of u, in place (scipy's lambertw between
    the kernel's two passes)."""
    (c_lo, c_hi), (p_lo, p_hi) = cover_bounds, pai_bounds
    sparse_below = max(crown_count(c_lo), slope * p_lo)
    z_high, z_low = _lambert_arguments(u, c, slope, p_hi, p_lo, sparse_below)
    w_high = lambertw(z_high).real
    sparse = np.isfinite(z_low)
    w_low = np.full_like(z_low, np.nan)
    if sparse.any():
        w_low[sparse] = lambertw(z_low[sparse]).real
    bounds = np.array([c_lo, c_hi, p_lo, p_hi], float)
    _cover_pai(u, x, log_jac, c, a, bounds, slope, w_high, w_low)


def _crown_and_ground_compiled(u, x, log_jac, base, centroid, columns, fixed, top_sds, slope):
    """Write the crown length ratio and the ground elevation from their ridge coordinates
    in place (:func:`_crown_and_ground`); ``base`` None or ``centroid`` None skip one."""
    centroid = np.array([-1.0, 0.0, 1.0] if centroid is None else centroid, float)
    _crown_and_ground(
        u, x, log_jac, -1 if base is None else base, centroid, columns, fixed, top_sds, slope
    )
