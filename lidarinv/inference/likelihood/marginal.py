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

import numpy as np

from . import compiled


def gain_marginal_obstacle(data, shot_factor, discrepancy_scale) -> str | None:
    """Why the gain cannot be integrated out exactly for this likelihood, or None if it can.

    Parameters
    ----------
    data : WindowData
    shot_factor : float (DN)
        g, shot-noise variance per unit signal.
    discrepancy_scale : float
        η of a discrepancy proportional to each row's model (a·W).
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
        """Marginal log-likelihood per row of ``fit`` (:func:`.compiled.linear_fit`):
        −½χ²(â) − ½Σ ln(2πv) + log ∫ π(a)·exp(−½ (a − â)²/s²) da."""
        return self._integrate(fit)[0]

    def _integrate(self, fit):
        return compiled.gain_log_likelihood(
            fit, self._nodes, self._log_weights, self.span, self._form
        )

    def draw(self, fit, rng) -> np.ndarray:
        """One gain per row from p(a | θ, y) ∝ π(a)·exp(−½ (a − â)²/s²): inverse CDF on a
        grid of :attr:`grid` points across the bulk of the Gaussian the integral was
        taken over (within the prior's bounds)."""
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
