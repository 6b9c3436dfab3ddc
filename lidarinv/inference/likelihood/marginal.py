"""The gain, integrated out of the likelihood analytically.

The model mean b + a·W is linear in the gain a. Where no bin's variance depends on a (no
shot noise, a discrepancy fixed by the observation) and every bin is recorded exactly
(nothing censored or saturated), the likelihood of a row θ is Gaussian in a:

    L(θ, a) = L(θ, â)·exp(−½ (a − â)²/s²),   â = Σ W r/v ÷ Σ W²/v,   s² = 1 ÷ Σ W²/v,

with r = y − b and v the variance of each bin. Its integral against the gain prior π:

- for a uniform or (truncated) normal prior, π·L is a Gaussian times a constant,
  integrated exactly over the prior's bounds;
- for a log-uniform or log-normal prior, smooth on the scale of s, it is
  L(θ, â)·s√(2π)·P(z ∈ [z₀, z₁])·E[π(â + s z) | z ∈ [z₀, z₁]], z standard normal and z₀,
  z₁ the prior bounds in units of s about â, the expectation a 24-node Gauss–Legendre
  rule over the bulk of that truncated normal (±9 about its mode).

Both agree with adaptive quadrature within 2e-7, from peaks far narrower than the prior
to ones beyond a prior bound (tests). The sampler then moves in one dimension fewer,
without the curved ridge of the gain against ρv/ρg and cover, and each posterior sample's
gain is drawn afterwards from its conditional density p(a | θ, y) ∝ π(a)·L(θ, a).
"""

import math

import numpy as np
from scipy.special import log_ndtr

from forward.backends import jit

from ..model.prior_table import log_prior_form

HALF_LOG_2PI = 0.5 * math.log(2.0 * math.pi)

_SQRT2 = math.sqrt(2.0)


def baseline_pattern(unit, data):
    """The baseline's pattern over the bins of ``data``: ones unless given."""
    if unit is None:
        return np.ones(data.samples.size)
    return np.ascontiguousarray(unit, dtype=np.float64)


def gain_marginal_obstacle(data, shot_factor, discrepancy_scale) -> str | None:
    """Why the gain cannot be integrated out exactly for this likelihood.

    Parameters
    ----------
    data : WindowData
    shot_factor : float (DN)
        g, shot-noise variance per unit signal.
    discrepancy_scale : float
        η of a discrepancy proportional to each row's model (a·W).

    Returns
    -------
    str or None
        The reason, or None if it can.
    """
    if shot_factor > 0:
        return "shot noise makes each bin's variance depend on the gain"
    if discrepancy_scale > 0:
        return "a discrepancy proportional to the model makes the variance depend on the gain"
    if not np.all(data.exact):
        return "the window holds censored or saturated samples"
    return None


class GainMarginal:
    """The gain integrated out against its prior, from per-row least-squares fits.

    Parameters
    ----------
    prior : a prior of :mod:`.priors` (gain, DN per unit reflectance)
    nodes : int
        Gauss–Legendre nodes of the expectation over a log-scale prior.
    span : float
        Half-width (in sd) of the Gaussian's bulk that the rule and the draws cover.
    grid : int
        Points of the inverse-CDF grid used by :meth:`draw`.
    """

    def __init__(self, prior, nodes=24, span=9.0, grid=257):
        self.prior = prior
        form = prior.form()
        self.lower, self.upper = float(form.lower), float(form.upper)
        self._form = np.array(
            [form.lower, form.upper, form.log_scale, form.w_mean, form.w_sd, form.log_norm],
            float,
        )
        x, w = np.polynomial.legendre.leggauss(nodes)
        self._nodes, self._log_weights = 0.5 * (x + 1.0), np.log(0.5 * w)
        self.span, self.grid = float(span), int(grid)

    def log_likelihood(self, fit) -> np.ndarray:
        """Marginal log-likelihood per row of least-squares fits.

        Parameters
        ----------
        fit : array (n, 4)
            :func:`linear_fit` of the rows.

        Returns
        -------
        array (n,)
            −½χ²(â) − ½Σ ln(2πv) + log ∫ π(a)·exp(−½ (a − â)²/s²) da.
        """
        return self._integrate(fit)[0]

    def _integrate(self, fit):
        return gain_log_likelihood(fit, self._nodes, self._log_weights, self.span, self._form)

    def draw(self, fit, rng) -> np.ndarray:
        """One gain per row from its conditional density.

        Parameters
        ----------
        fit : array (n, 4)
            :func:`linear_fit` of the rows.
        rng : numpy.random.Generator

        Returns
        -------
        array (n,) (DN per unit reflectance)
            Draws from p(a | θ, y) ∝ π(a)·exp(−½ (a − â)²/s²) by inverse CDF on a grid of
            :attr:`grid` points across the bulk of the Gaussian (within the prior's bounds);
            from the prior where the model carries no signal.
        """
        fit = np.atleast_2d(fit)
        _, moments = self._integrate(fit)
        mean, sd = moments[:, 0], moments[:, 1]
        informative = sd > 0
        sd = np.where(informative, sd, 1.0)
        z_lower, z_upper = (self.lower - mean) / sd, (self.upper - mean) / sd
        mode = np.clip(0.0, z_lower, z_upper)
        lo = np.maximum(z_lower, mode - self.span)
        hi = np.minimum(z_upper, mode + self.span)
        z = lo[:, None] + (hi - lo)[:, None] * np.linspace(0.0, 1.0, self.grid)
        a = mean[:, None] + sd[:, None] * z
        best, s = fit[:, 1, None], 1.0 / np.sqrt(np.where(informative, fit[:, 0], 1.0))[:, None]
        log_density = self.prior.log_pdf(a) - 0.5 * ((a - best) / s) ** 2
        density = np.exp(log_density - np.max(log_density, axis=1, keepdims=True))
        steps = 0.5 * (density[:, 1:] + density[:, :-1]) * np.diff(a, axis=1)
        cdf = np.concatenate([np.zeros((a.shape[0], 1)), np.cumsum(steps, axis=1)], axis=1)
        target = rng.uniform(size=a.shape[0]) * cdf[:, -1]
        k = np.clip(np.sum(cdf < target[:, None], axis=1) - 1, 0, self.grid - 2)
        rows = np.arange(a.shape[0])
        width = cdf[rows, k + 1] - cdf[rows, k]
        frac = np.where(width > 0, (target - cdf[rows, k]) / np.where(width > 0, width, 1.0), 0.0)
        out = a[rows, k] + frac * (a[rows, k + 1] - a[rows, k])
        if not informative.all():
            out[~informative] = self.prior.sample(rng, int(np.sum(~informative)))
        return out


@jit
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
    """Weighted least-squares fit of the gain per row (compiled).

    Parameters
    ----------
    signal : array (n, bins)
        Model waveforms W.
    baseline, noise_sigma : array (n,) (DN)
    fixed : array (bins,) (DN²)
        Variance added to σn² in each bin (independent of the gain).
    data : WindowData
        Every bin exactly recorded.
    unit : array (bins,), optional
        The baseline's pattern, ones by default.

    Returns
    -------
    array (n, 4)
        Σ W²/v (the gain's precision), the best gain â = Σ W r/v ÷ Σ W²/v (r = y − b·unit),
        the χ² at â, and Σ ln(2π v), v = σn² + ``fixed``.
    """
    return _linear_fit(
        np.ascontiguousarray(signal, dtype=np.float64),
        np.ascontiguousarray(baseline, dtype=np.float64),
        np.ascontiguousarray(noise_sigma, dtype=np.float64),
        np.ascontiguousarray(fixed, dtype=np.float64),
        np.ascontiguousarray(data.samples, dtype=np.float64),
        baseline_pattern(unit, data),
    )


@jit
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


@jit
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
            out[r] += -log_norm - 0.5 * gap - math.log(root) + HALF_LOG_2PI
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
            terms[i] = weights[i] + log_prior_form(
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
        out[r] += math.log(s) + HALF_LOG_2PI + top_t + math.log(sum_t) - top_w - math.log(sum_w)
        moments[r, 0], moments[r, 1] = best, s
        log_mass[r] = _log_gaussian_mass(z_lo, z_hi)
    return out, moments, log_mass


def gain_log_likelihood(fit, unit, log_weights, span, form):
    """Log-likelihood with the gain integrated out against a prior (compiled).

    Parameters
    ----------
    fit : array (n, 4)
        :func:`linear_fit` of the rows.
    unit : array (k,)
        Nodes of the quadrature over a log-scale prior, as fractions of q's bulk.
    log_weights : array (k,)
    span : float
        Half-width (sd) of q's bulk about its mode.
    form : array (6,)
        The prior's (lower, upper, log_scale, w_mean, w_sd, log_norm)
        (:class:`lidarinv.inference.model.prior_table.PriorForm`).

    Returns
    -------
    log_likelihood : array (n,)
        −½χ²(â) − ½Σ ln(2πv) + log ∫ π(a)·exp(−½ (a − â)²/s²) da, s = (Σ W²/v)^−½.
    moments : array (n, 2)
        The Gaussian q (mean, sd) the integral was taken over; (0, 0) where the model
        carries no signal (Σ W²/v = 0: the prior integrates to one).

    Notes
    -----
    For a uniform or normal prior the integrand is a Gaussian q times a constant,
    integrated exactly over the prior's bounds. For a log-scale prior, q is N(â, s²) and
    the integral s√(2π)·P_q(bounds)·E_q[π]. P_q from erfc, and through
    :func:`scipy.special.log_ndtr` where the bounds lie so far in a tail that erfc
    underflows.
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
    """log(Φ(upper) − Φ(lower)) for lower < upper, accurate far into either tail.

    Parameters
    ----------
    lower, upper : arrays

    Returns
    -------
    array
    """
    flip = lower > 0  # both in the upper tail: use the mirror image
    a, b = np.where(flip, -upper, lower), np.where(flip, -lower, upper)
    log_a, log_b = log_ndtr(a), log_ndtr(b)
    with np.errstate(divide="ignore"):
        return log_b + np.log1p(-np.exp(log_a - log_b))
