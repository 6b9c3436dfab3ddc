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
bounded parameters get, and |∂t/∂v| = (t_hi − t_lo)·σ(v)·(1 − σ(v)). On six GEDI shots
(``studies/sampling_coordinates.py``, 8000 steps) PAI's τ fell by 10–23 % and the largest
τ from a median of 65 to 56 steps.

**Crown length ratio ℓ** against the mean tree height H̄ = top − TOP_SDS·sd. The waveform
fixes the crown-base height of the mean tree, B = (1 − ℓ)·H̄, far better than either
factor: in (top, sd, ℓ) the posterior bends along B = const (ℓ against H̄ correlates at
0.94 on a GEDI shot). Sampling b = ln B instead of ℓ straightens it; |∂ℓ/∂b| = B / H̄.

**Ground elevation** against the understory. The ground and a low understory (LAI Lu,
height hu) return one blob, a pulse width wide, whose centroid the waveform fixes to about
a centimetre while the ground elevation zg alone spreads several times wider: more or
taller understory lifts the centroid, so zg must sink. In (zg, Lu, hu) the posterior is a
thin curved sheet, its narrowest direction heavy-tailed (kurtosis 5 to 16 on GEDI shots).
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

import numpy as np
from scipy.special import expit, lambertw

#: Ridge-straightening coordinates by name (see :class:`.parameters.ParameterSpace`).
RIDGE_COORDINATES = ("cover-pai", "crown-base", "ground-centroid", "tallest-stem")

#: Those used by default: all three. On six GEDI shots (``studies/sampling_coordinates.py``)
#: the ground centroid halved the median largest τ (184 → 99 steps); the crown base then
#: shortened the slowest shots' τ, now in the crown parameters (worst 193 → 134). The
#: tallest stem's gap applies only where that latent is sampled.
DEFAULT_RIDGES = RIDGE_COORDINATES

#: a in 1 − exp(−a·Lc): G·Ω for a spherical leaf-angle distribution and no clumping.
INTERCEPTION_SLOPE = 0.5


def from_cover_pai(cover, pai, slope=INTERCEPTION_SLOPE):
    """(s, t) from cover (1) and PAI (m²/m²); NaN where cover ∉ (0, 1) or PAI ≤ 0."""
    with np.errstate(divide="ignore", invalid="ignore"):
        x = -np.log1p(-np.asarray(cover, float))
        lc = np.asarray(pai, float) / x
        s = np.log(x) + np.log(-np.expm1(-slope * lc))
        t = np.log(lc)
    bad = ~((cover > 0) & (cover < 1) & (pai > 0))
    return np.where(bad, np.nan, s), np.where(bad, np.nan, t)


def to_cover_pai(s, t, slope=INTERCEPTION_SLOPE):
    """Cover, PAI and log|∂(cover, PAI)/∂(s, t)| from the joint coordinates."""
    with np.errstate(over="ignore", divide="ignore", invalid="ignore"):
        lc = np.exp(t)
        x = np.exp(s) / -np.expm1(-slope * lc)
        cover = -np.expm1(-x)
        pai = lc * x
        log_jac = -x + 2.0 * np.log(x) + t
    return cover, pai, log_jac


def ridge_range(s, cover_bounds, pai_bounds, slope=INTERCEPTION_SLOPE):
    """(t_lo, t_hi): the range of t = ln Lc at interception s = ln Y over which cover and
    PAI stay within their priors' bounds; NaN where no t does.

    Along t at fixed s, X = Y/(1 − e^{−a·Lc}) falls, so cover falls, and PAI = Lc·X
    rises: each bound cuts t once. PAI = p at Lc = u/a with u = ak + W₀(−ak·e^{−ak}),
    k = p/Y (W₀ the principal branch of Lambert's W), which exists for ak > 1.
    """
    y = np.exp(np.array(s, float, ndmin=1))
    (c_lo, c_hi), (p_lo, p_hi) = cover_bounds, pai_bounds
    with np.errstate(divide="ignore", invalid="ignore"):
        # cover ≤ c_hi: X ≤ −ln(1 − c_hi); PAI ≤ p_hi
        low = np.log(np.log1p(y / np.log1p(-c_hi)) / -slope)
        high = _log_lc_at_pai(p_hi / y, slope)
        # cover ≥ c_lo (X ≥ x_lo) and PAI ≥ p_lo bind only where Y < x_lo or Y < a·p_lo
        x_lo = -np.log1p(-c_lo)
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
    """Cover, PAI and log|∂(cover, PAI)/∂(s, v)| from s and the ridge position v:
    t = t_lo + (t_hi − t_lo)·σ(v) over :func:`ridge_range`, then :func:`to_cover_pai`.
    NaN where s admits no t."""
    low, high = ridge_range(s, cover_bounds, pai_bounds, slope)
    with np.errstate(over="ignore", divide="ignore", invalid="ignore"):
        t = low + (high - low) * expit(v)
        cover, pai, log_jac = to_cover_pai(s, t, slope)
        log_jac = log_jac + np.log(high - low) - np.logaddexp(0.0, v) - np.logaddexp(0.0, -v)
    return cover, pai, log_jac


def from_cover_pai_bounded(cover, pai, cover_bounds, pai_bounds, slope=INTERCEPTION_SLOPE):
    """(s, v) of cover and PAI within the bounds: the inverse of
    :func:`to_cover_pai_bounded`; NaN outside them."""
    s, t = from_cover_pai(cover, pai, slope)
    low, high = ridge_range(s, cover_bounds, pai_bounds, slope)
    with np.errstate(divide="ignore", invalid="ignore"):
        fraction = (t - low) / (high - low)
        v = np.log(fraction) - np.log1p(-fraction)
    inside = (cover >= cover_bounds[0]) & (cover <= cover_bounds[1])
    inside &= (pai >= pai_bounds[0]) & (pai <= pai_bounds[1])
    return np.where(inside, s, np.nan), np.where(inside, v, np.nan)


def crown_base_from_ratio(ratio, mean_height):
    """b = ln((1 − ℓ)·H̄) from the crown length ratio (1) and mean tree height (m);
    NaN where H̄ ≤ 0 or ℓ ∉ [0, 1)."""
    ratio, mean_height = np.asarray(ratio, float), np.asarray(mean_height, float)
    with np.errstate(divide="ignore", invalid="ignore"):
        base = np.log((1.0 - ratio) * mean_height)
    bad = ~((ratio >= 0) & (ratio < 1) & (mean_height > 0))
    return np.where(bad, np.nan, base)


def ratio_from_crown_base(b, mean_height):
    """Crown length ratio ℓ = 1 − exp(b)/H̄ and log|∂ℓ/∂b|; NaN where H̄ ≤ 0."""
    mean_height = np.asarray(mean_height, float)
    with np.errstate(over="ignore", divide="ignore", invalid="ignore"):
        mean_height = np.where(mean_height > 0, mean_height, np.nan)
        relative = np.exp(b) / mean_height
        return 1.0 - relative, np.log(relative)


def understory_centroid(lai, height, rho_ratio, slope=INTERCEPTION_SLOPE):
    """Height (m) above the ground of the centroid of the ground-plus-understory return,
    for understory LAI (m²/m²), height (m) and ρv/ρg (1); 0 without understory."""
    lai, height, rho_ratio = (np.asarray(a, float) for a in (lai, height, rho_ratio))
    q = slope * lai
    with np.errstate(divide="ignore", invalid="ignore"):
        intercepted = -np.expm1(-q)
        moment = np.where(q > 0, 1.0 - intercepted / q, 0.0)
        centroid = height * rho_ratio * moment / (rho_ratio * intercepted + np.exp(-q))
    return np.where(q > 0, centroid, 0.0)


def top_from_stem_gap(tallest, log_gap):
    """Top height (m) = H + e^g from the tallest stem's height H (m) and the log gap g,
    and log|∂top/∂g| = g."""
    return tallest + np.exp(log_gap), np.asarray(log_gap, float)


def stem_gap_from_top(top, tallest):
    """g = ln(top − H), the inverse of :func:`top_from_stem_gap` (NaN where top ≤ H)."""
    gap = np.asarray(top, float) - tallest
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(gap > 0, np.log(gap), np.nan)
