"""The ridge-straightening sampling coordinates of :mod:`.coordinates`, compiled.

:meth:`.parameters.ParameterSpace.from_unbounded` runs at every sampler half-step on a few
tens of rows, where the numpy maps of :mod:`.coordinates` cost some thirty short-array
calls. Here they take two passes over the rows, with scipy's ``lambertw`` (the PAI bound
of :func:`.coordinates.ridge_range`) called between them. The numpy maps remain the
reference (``tests/test_inference_coordinates.py``).
"""

import math

import numpy as np
from numba import njit
from scipy.special import lambertw

from .compiled import LOGIT, _unit_and_log_slope

# error_model="numpy": x/0 gives ±inf or NaN, as in the numpy maps, instead of raising

#: Column code of a parameter held fixed (its value is passed instead).
FIXED = -1


@njit(cache=True, error_model="numpy")
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


@njit(cache=True, error_model="numpy")
def _log_lc_at_pai(k_slope, w, slope):
    """ln Lc where PAI meets a bound, from ak and W₀(−ak·e^{−ak}); NaN for ak ≤ 1."""
    if not (k_slope > 1.0):
        return math.nan
    return math.log((k_slope + w) / slope)


@njit(cache=True, error_model="numpy")
def _cover_pai(u, x, log_jac, c, a, bounds, slope, w_high, w_low):
    """Cover and PAI into x[:, c], x[:, a] (as :func:`.coordinates.to_cover_pai_bounded`)."""
    c_lo, c_hi, p_lo, p_hi = bounds[0], bounds[1], bounds[2], bounds[3]
    x_hi = -math.log1p(-c_hi)
    x_lo = -math.log1p(-c_lo)
    for r in range(u.shape[0]):
        s, v = u[r, c], u[r, a]
        y = math.exp(s)
        low = math.log(math.log1p(-y / x_hi) / -slope)
        high = _log_lc_at_pai(slope * p_hi / y, w_high[r], slope)
        if y < max(x_lo, slope * p_lo):
            if y < x_lo:
                high = min(high, math.log(-math.log1p(-y / x_lo) / slope))
            if slope * p_lo > y:
                low = max(low, _log_lc_at_pai(slope * p_lo / y, w_low[r], slope))
        if not (low < high):  # NaN bounds included
            x[r, c] = x[r, a] = log_jac[r, c] = math.nan
            log_jac[r, a] = 0.0
            continue
        unit, log_slope = _unit_and_log_slope(v, LOGIT)
        t = low + (high - low) * unit
        lc = math.exp(t)
        crowns = y / -math.expm1(-slope * lc)  # X = −ln(1 − cover)
        x[r, c] = -math.expm1(-crowns)
        x[r, a] = lc * crowns
        log_jac[r, c] = -crowns + 2.0 * math.log(crowns) + t + math.log(high - low) + log_slope
        log_jac[r, a] = 0.0


@njit(cache=True, error_model="numpy")
def _value(x, r, column, fixed):
    return x[r, column] if column != FIXED else fixed


@njit(cache=True, error_model="numpy")
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


def cover_pai_bounded(u, x, log_jac, c, a, cover_bounds, pai_bounds, slope):
    """Write cover and PAI (columns ``c``, ``a`` of x) and their log-Jacobian from the
    joint coordinates (s, v) in the same columns of u, in place."""
    (c_lo, c_hi), (p_lo, p_hi) = cover_bounds, pai_bounds
    sparse_below = max(-math.log1p(-c_lo), slope * p_lo)
    z_high, z_low = _lambert_arguments(u, c, slope, p_hi, p_lo, sparse_below)
    w_high = lambertw(z_high).real
    sparse = np.isfinite(z_low)
    w_low = np.full_like(z_low, np.nan)
    if sparse.any():
        w_low[sparse] = lambertw(z_low[sparse]).real
    bounds = np.array([c_lo, c_hi, p_lo, p_hi], float)
    _cover_pai(u, x, log_jac, c, a, bounds, slope, w_high, w_low)


def crown_and_ground(u, x, log_jac, base, centroid, columns, fixed, top_sds, slope):
    """Write the crown length ratio and the ground elevation from their ridge coordinates
    in place (see :func:`_crown_and_ground`); ``base`` −1 or ``centroid`` None skip one."""
    centroid = np.array([-1.0, 0.0, 1.0] if centroid is None else centroid, float)
    _crown_and_ground(
        u, x, log_jac, -1 if base is None else base, centroid, columns, fixed, top_sds, slope
    )
