"""Compiled per-row terms of the log-posterior: the Gaussian likelihood and RH metrics.

The sampler calls the log-posterior with a few rows at a time, so numpy's per-call cost,
not arithmetic, sets the price of these terms. The kernels here compute, row by row, what
:func:`.likelihood.log_likelihood` (exactly recorded bins) with
:func:`.likelihood.model_moments`, and :func:`.posterior.rh_from_waveform`, compute with
numpy; those stay as the references they are tested against.
"""

import math

import numpy as np
from numba import njit
from scipy.special import log_ndtr

_HALF_LOG_2PI = 0.5 * math.log(2.0 * math.pi)
_SQRT2 = math.sqrt(2.0)


@njit(cache=True)
def _gaussian_exact(signal, gain, baseline, noise_sigma, shot_factor, scale, fixed, y, exact, unit):
    n, bins = signal.shape
    out = np.zeros(n)
    for r in range(n):
        a, b, s2 = gain[r], baseline[r], noise_sigma[r] ** 2
        total = 0.0
        for j in range(bins):
            if not exact[j]:
                continue
            w = a * signal[r, j]
            variance = s2 + shot_factor * w + fixed[j] + (scale * w) ** 2
            resid = y[j] - b * unit[j] - w
            total -= 0.5 * (resid * resid / variance + math.log(variance)) + _HALF_LOG_2PI
        out[r] = total
    return out


def gaussian_exact(signal, gain, baseline, noise_sigma, shot_factor, scale, fixed, data, unit=None):
    """Log-likelihood (n,) of the exactly recorded bins of ``data`` (a WindowData).

    The mean is b·``unit`` + a·W and the variance σn² + g·a·W + ``fixed`` + (``scale``·a·W)²:
    the model of :func:`.likelihood.model_moments` with either discrepancy of
    :mod:`.discrepancy` (``fixed`` (bins,) DN², or η = ``scale``; pass zeros or 0 for
    the one not used). ``unit`` (bins,) is the baseline's pattern, ones by default; in a
    rotated basis (:mod:`.correlated`) it is the rotated ones.
    """
    return _gaussian_exact(
        np.ascontiguousarray(signal, dtype=np.float64),
        np.ascontiguousarray(gain, dtype=np.float64),
        np.ascontiguousarray(baseline, dtype=np.float64),
        np.ascontiguousarray(noise_sigma, dtype=np.float64),
        float(shot_factor),
        float(scale),
        np.ascontiguousarray(fixed, dtype=np.float64),
        np.ascontiguousarray(data.samples, dtype=np.float64),
        np.ascontiguousarray(data.exact),
        _unit(unit, data),
    )


def _unit(unit, data):
    """The baseline's pattern over the bins of ``data``: ones unless given."""
    if unit is None:
        return np.ones(data.samples.size)
    return np.ascontiguousarray(unit, dtype=np.float64)


@njit(cache=True)
def _linear_fit(signal, baseline, noise_sigma, fixed, y, unit):
    n, bins = signal.shape
    out = np.empty((n, 4))
    inverse = np.empty(bins)  # 1/v per bin, and Σ ln(2πv): recomputed only when σn changes
    s2 = log_var = math.nan
    for r in range(n):
        if not noise_sigma[r] ** 2 == s2:
            s2 = noise_sigma[r] ** 2
            log_var = 0.0
            plain = 0  # bins with noise only, whose logarithms are all the same
            for j in range(bins):
                inverse[j] = 1.0 / (s2 + fixed[j])
                if fixed[j] == 0.0:
                    plain += 1
                else:
                    log_var += math.log(2.0 * math.pi * (s2 + fixed[j]))
            log_var += plain * math.log(2.0 * math.pi * s2)
        ww = wr = 0.0
        for j in range(bins):
            ww += signal[r, j] * signal[r, j] * inverse[j]
            wr += signal[r, j] * (y[j] - baseline[r] * unit[j]) * inverse[j]
        a = wr / ww if ww > 0.0 else 0.0
        chi2 = 0.0
        for j in range(bins):  # a second pass: no cancellation between large sums
            resid = y[j] - baseline[r] * unit[j] - a * signal[r, j]
            chi2 += resid * resid * inverse[j]
        out[r, 0], out[r, 1], out[r, 2], out[r, 3] = ww, a, chi2, log_var
    return out


def linear_fit(signal, baseline, noise_sigma, fixed, data, unit=None) -> np.ndarray:
    """Weighted least-squares fit of the gain a in y = b·``unit`` + a·W + ε, per row.

    Every bin of ``data`` (a WindowData) must be exactly recorded; the variance of bin j
    is σn² + ``fixed``[j] (DN²), which does not depend on a; ``unit`` as in
    :func:`gaussian_exact`. Returns (n, 4) columns:
    Σ W²/v (1/DN² per unit reflectance², the gain's precision), the best gain â, the χ²
    at â, and Σ ln(2π v).
    """
    return _linear_fit(
        np.ascontiguousarray(signal, dtype=np.float64),
        np.ascontiguousarray(baseline, dtype=np.float64),
        np.ascontiguousarray(noise_sigma, dtype=np.float64),
        np.ascontiguousarray(fixed, dtype=np.float64),
        np.ascontiguousarray(data.samples, dtype=np.float64),
        _unit(unit, data),
    )


@njit(cache=True)
def _log_prior_form(x, lower, upper, log_scale, w_mean, w_sd, log_norm):
    """log p(x) of a prior in the common form of :class:`.priors.PriorForm`."""
    if not (lower <= x <= upper):
        return -math.inf
    log_x = math.log(x) if log_scale else 0.0
    y = ((log_x if log_scale else x) - w_mean) / w_sd  # 0 for the uniform kinds (sd = ∞)
    return -log_x - 0.5 * y * y - log_norm


@njit(cache=True)
def _prior_log_pdf(x, lower, upper, log_scale, w_mean, w_sd, log_norm):
    n, k = x.shape
    out = np.empty((n, k))
    for r in range(n):
        for c in range(k):
            out[r, c] = _log_prior_form(
                x[r, c], lower[c], upper[c], log_scale[c], w_mean[c], w_sd[c], log_norm[c]
            )
    return out


@njit(cache=True)
def normal_cdf(x):
    """Φ(x), the standard normal CDF, from erfc (accurate in both tails)."""
    return 0.5 * math.erfc(-x / _SQRT2)


#: Codes of the unbounded maps in the compiled kernel (:data:`.priors.UNBOUNDED_MAPS`).
LOGIT, PROBIT = 0, 1

_LOG_SQRT_2PI = 0.5 * math.log(2.0 * math.pi)


@njit(cache=True)
def _unit_and_log_slope(t, kind):
    """f(t) ∈ [0, 1] and log f′(t) of the logistic (``LOGIT``) or normal (``PROBIT``) CDF,
    without overflow either side."""
    if kind == PROBIT:
        return normal_cdf(t), -0.5 * t * t - _LOG_SQRT_2PI
    if t >= 0.0:
        e = math.exp(-t)
        return 1.0 / (1.0 + e), -t - 2.0 * math.log1p(e)
    e = math.exp(t)
    return e / (1.0 + e), t - 2.0 * math.log1p(e)


@njit(cache=True)
def _prior_from_unbounded(u, w_lower, span, log_scale, lower, upper, kind):
    n, k = u.shape
    x = np.empty((n, k))
    log_jac = np.empty((n, k))
    for r in range(n):
        for c in range(k):
            unit, log_slope = _unit_and_log_slope(u[r, c], kind)
            w = w_lower[c] + span[c] * unit
            jac = math.log(span[c]) + log_slope
            value = w
            if log_scale[c]:
                value = math.exp(w)
                jac += w
            x[r, c] = min(max(value, lower[c]), upper[c])  # exp(log upper) may round above
            log_jac[r, c] = jac
    return x, log_jac


def prior_log_pdf(x, lower, upper, log_scale, w_mean, w_sd, log_norm) -> np.ndarray:
    """Log densities (n, k) of the columns of x under priors in the common form of
    :class:`.priors.PriorForm` (one entry per column); −inf outside each support and for
    NaN."""
    return _prior_log_pdf(
        np.ascontiguousarray(x, dtype=np.float64), lower, upper, log_scale, w_mean, w_sd, log_norm
    )


def prior_from_unbounded(u, w_lower, span, log_scale, lower, upper, kind=LOGIT):
    """Values (n, k) and log|dx/du| (n, k) of unbounded coordinates u (n, k): w = w_lower +
    span·f(u) with f the logistic (``kind=LOGIT``) or normal (``PROBIT``) CDF, x = w or
    exp(w) for log-scale columns, within [lower, upper]."""
    return _prior_from_unbounded(
        np.ascontiguousarray(u, dtype=np.float64), w_lower, span, log_scale, lower, upper, kind
    )


@njit(cache=True)
def _log_gaussian_mass(lo, hi):
    """log(Φ(hi) − Φ(lo)), lo < hi, from complementary error functions (no cancellation in
    either tail); −inf where the mass underflows, beyond about 37 sd."""
    if lo > 0.0:  # mirror, so that lo ≤ 0
        lo, hi = -hi, -lo
    if hi <= 0.0:
        mass = 0.5 * (math.erfc(-hi / _SQRT2) - math.erfc(-lo / _SQRT2))
    else:
        mass = 1.0 - 0.5 * math.erfc(hi / _SQRT2) - 0.5 * math.erfc(-lo / _SQRT2)
    return math.log(mass) if mass > 0.0 else -math.inf


@njit(cache=True)
def _gain_log_likelihood(fit, unit, log_weights, span, form):
    lower, upper, log_scale, w_mean, w_sd, log_norm = form
    n, k = fit.shape[0], unit.size
    out = np.empty(n)
    moments = np.zeros((n, 2))
    log_mass = np.zeros(n)  # log P_q(bounds)
    terms = np.empty(k)
    weights = np.empty(k)
    for r in range(n):
        precision, best = fit[r, 0], fit[r, 1]
        out[r] = -0.5 * (fit[r, 2] + fit[r, 3])
        if not precision > 0.0:
            continue  # the model carries no signal: the prior integrates to one
        s = 1.0 / math.sqrt(precision)
        if log_scale < 0.5:  # uniform or normal prior: a product of two Gaussians, exactly
            prior_precision = 1.0 / (w_sd * w_sd)  # 0 for the uniform kind
            both = precision + prior_precision
            mean = (best * precision + w_mean * prior_precision) / both
            gap = (best - w_mean) ** 2 / (s * s + w_sd * w_sd) if prior_precision > 0 else 0.0
            root = math.sqrt(both)
            out[r] += -log_norm - 0.5 * gap - math.log(root) + _HALF_LOG_2PI
            moments[r, 0], moments[r, 1] = mean, 1.0 / root
            log_mass[r] = _log_gaussian_mass((lower - mean) * root, (upper - mean) * root)
            continue
        # log-scale prior, smooth on the scale of s: E[π] under N(â, s²), a quadrature rule
        z_lo, z_hi = (lower - best) / s, (upper - best) / s
        mode = min(max(0.0, z_lo), z_hi)
        lo, hi = max(z_lo, mode - span), min(z_hi, mode + span)
        top_w = top_t = -math.inf
        for i in range(k):
            z = lo + (hi - lo) * unit[i]
            weights[i] = log_weights[i] - 0.5 * z * z
            terms[i] = weights[i] + _log_prior_form(
                best + s * z, lower, upper, True, w_mean, w_sd, log_norm
            )
            top_w, top_t = max(top_w, weights[i]), max(top_t, terms[i])
        if top_t == -math.inf:
            out[r] = -math.inf
            continue
        sum_w = sum_t = 0.0
        for i in range(k):
            sum_w += math.exp(weights[i] - top_w)
            sum_t += math.exp(terms[i] - top_t)
        out[r] += math.log(s) + _HALF_LOG_2PI + top_t + math.log(sum_t) - top_w - math.log(sum_w)
        moments[r, 0], moments[r, 1] = best, s
        log_mass[r] = _log_gaussian_mass(z_lo, z_hi)
    return out, moments, log_mass


def gain_log_likelihood(fit, unit, log_weights, span, form):
    """Log-likelihood (n,) with the gain integrated out against a prior, from the rows'
    :func:`linear_fit`, and the Gaussian q (mean, sd) (n, 2) the integral was taken over.

    The value is −½χ²(â) − ½Σ ln(2πv) + log ∫ π(a)·exp(−½ (a − â)²/s²) da, with
    s = (Σ W²/v)^−½. For a uniform or normal prior the integrand is a Gaussian q times a
    constant, integrated exactly over the prior's bounds. For a log-scale prior, q is
    N(â, s²) and the integral s√(2π)·P_q(bounds)·E_q[π], the expectation a rule with nodes
    ``unit`` (fractions of q's bulk within the bounds, ±``span`` sd about its mode) and
    log weights ``log_weights``. P_q from erfc, and through :func:`scipy.special.log_ndtr`
    where the bounds lie so far in a tail that erfc underflows. ``form`` is the prior's
    (lower, upper, log_scale, w_mean, w_sd, log_norm) of :class:`.priors.PriorForm`. Rows
    whose model carries no signal (Σ W²/v = 0) get q = (0, 0) and no integral (the
    prior's is one).
    """
    form = np.asarray(form, dtype=np.float64)  # no copy for a float64 array
    partial, moments, log_mass = _gain_log_likelihood(
        np.ascontiguousarray(fit, dtype=np.float64),
        np.ascontiguousarray(unit, dtype=np.float64),
        np.ascontiguousarray(log_weights, dtype=np.float64),
        float(span),
        form,
    )
    far = np.isneginf(log_mass)
    if far.any():
        mean, sd = moments[far, 0], moments[far, 1]
        log_mass[far] = log_gaussian_mass((form[0] - mean) / sd, (form[1] - mean) / sd)
    return partial + log_mass, moments


def log_gaussian_mass(lower, upper) -> np.ndarray:
    """log(Φ(upper) − Φ(lower)) for lower < upper, accurate far into either tail."""
    flip = lower > 0  # both in the upper tail: use the mirror image
    a, b = np.where(flip, -upper, lower), np.where(flip, -lower, upper)
    log_a, log_b = log_ndtr(a), log_ndtr(b)
    with np.errstate(divide="ignore"):
        return log_b + np.log1p(-np.exp(log_a - log_b))


@njit(cache=True)
def _relative_heights(signal, start, dz, ground, levels):
    n, bins = signal.shape
    out = np.full((n, levels.size), np.nan)
    cum = np.empty(bins)
    for r in range(n):
        acc = 0.0
        for j in range(bins):
            acc += max(signal[r, j], 0.0)
            cum[j] = acc
        if not acc > 0.0:
            continue
        for i in range(levels.size):
            target = levels[i] * acc
            k = 0
            while k < bins - 1 and cum[k] < target:
                k += 1
            below = cum[k - 1] if k > 0 else 0.0
            step = cum[k] - below
            frac = (target - below) / step if step > 0.0 else 0.0
            frac = min(max(frac, 0.0), 1.0)
            out[r, i] = start + (k + frac) * dz - ground[r]
    return out


def relative_heights(signal, axis, ground, levels=(0.5, 0.98)) -> np.ndarray:
    """Compiled :func:`.posterior.rh_from_waveform`: heights above ``ground`` (m) below
    which each fraction of the energy lies, (n, levels); NaN for rows without energy."""
    dz = float(axis[1] - axis[0])
    return _relative_heights(
        np.ascontiguousarray(signal, dtype=np.float64),
        float(axis[0]) - 0.5 * dz,
        dz,
        np.ascontiguousarray(ground, dtype=np.float64),
        np.asarray(levels, dtype=np.float64),
    )
