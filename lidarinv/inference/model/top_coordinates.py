"""Sampling coordinates of the top height and the height sd.

Like :mod:`.coordinates`, only the coordinates the sampler moves in change; the prior
stays the one set on the parameters, through the Jacobian of each map.

**Height sd** against the top height. The normal height family needs a positive mean
height, sd < top/TOP_SDS; sd's unbounded map is rescaled at each top to end there
(:func:`height_sd_capped`), so that no move leaves that support either.

**Top height** against the footprint's tallest stem H (the latent of a footprint
conditioned on it, :class:`.stand.StandMapping`). The waveform sees H, and the
stand's top lies above it by a gap whose law, near the top, is close to exponential with
its mode at zero. In (top, H) the posterior is a wedge, top ≥ H, densest along its edge.
Sampling g = ln(top − H) instead of top opens the wedge into a smooth, one-humped density
along g at fixed H; top = H + e^g has |∂top/∂g| = e^g.

**Top height** against the height sd. The waveform places the bulk of the crowns, near the
mean height μ = top − TOP_SDS·sd, better than the top of the height distribution's
thin upper tail: in (top, sd) the posterior runs along top = μ + TOP_SDS·sd, and in the
sampler's coordinates, where sd's logistic map stretches its lower end, that line bends.
The ``mean-height`` coordinate samples, instead of the top,

    m = ln μ − ln(1 − (μ/μ₁)^p)/p,   μ₁ = top₁ − TOP_SDS·sd,

the lower storey's top map of :mod:`.coordinates` with ρ₀ = 0, ρ₁ = 1 and H₁ = μ₁ (top₁
the upper end of the top's prior): m is ln μ until μ nears μ₁, and at fixed m,
∂μ/∂sd = −TOP_SDS·(μ/μ₁)^{p+1} against −TOP_SDS at fixed top, so that the mean height
stays nearly in place as sd moves. The sd's own map is capped at top₁/TOP_SDS (not at
the row's top, which now follows from the sd). The map spans μ ∈ (0, μ₁), that is
top < top₁ and a positive mean height; rows with a top below the prior's lower end (a mean
height under a metre for the default prior) lie outside the prior, whose density there is
zero. top = μ + TOP_SDS·sd has |∂(top, sd)/∂(m, sd)| = |∂μ/∂m|.
"""

import numpy as np

from .coordinates import LOWER_TOP_WALL_POWER, lower_top_from_ratio, ratio_from_lower_top


def _sd_map_scale(top, w_lower, w_upper, log_scale, top_sds):
    """k of :func:`height_sd_capped`; NaN where the top admits no sd of the prior."""
    with np.errstate(divide="ignore", invalid="ignore"):
        cap = np.asarray(top, float) / top_sds
        w_cap = np.log(cap) if log_scale else cap
        k = (np.minimum(w_upper, w_cap) - w_lower) / (w_upper - w_lower)
    return np.where(k > 0, k, np.nan)


def height_sd_capped(sd, top, w_lower, w_upper, log_scale, top_sds):
    """Rescale the height sd's unbounded map to end at the largest sd a top admits.

    Parameters
    ----------
    sd : array (m)
        sd from its prior's map, within the prior's support.
    top : array (m)
        Top height.
    w_lower, w_upper : float
        The prior's support in its map's scale w (sd, or ln sd for a log-scale prior).
    log_scale : bool
    top_sds : float
        The mean height top − ``top_sds``·sd must stay positive.

    Returns
    -------
    sd, log_jac : arrays
        w' = w₀ + (w − w₀)·k, k = (min(w₁, w(top/top_sds)) − w₀)/(w₁ − w₀), and the
        log-Jacobian to add to the prior map's: ln k, plus w' − w on a log scale;
        NaN where the top admits no sd of the prior (k ≤ 0).
    """
    sd = np.asarray(sd, float)
    k = _sd_map_scale(top, w_lower, w_upper, log_scale, top_sds)
    with np.errstate(divide="ignore", invalid="ignore"):
        w = np.log(sd) if log_scale else sd
        w_new = w_lower + (w - w_lower) * k
        log_jac = np.log(k) + (w_new - w if log_scale else 0.0)
        return (np.exp(w_new) if log_scale else w_new), log_jac


def height_sd_uncapped(sd, top, w_lower, w_upper, log_scale, top_sds):
    """The inverse of :func:`height_sd_capped`: sd in the prior's own map."""
    sd = np.asarray(sd, float)
    k = _sd_map_scale(top, w_lower, w_upper, log_scale, top_sds)
    with np.errstate(divide="ignore", invalid="ignore"):
        w = np.log(sd) if log_scale else sd
        w_old = w_lower + (w - w_lower) / k
        return np.exp(w_old) if log_scale else w_old


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


def top_from_mean_height(m, sd, top_upper, top_sds, power=LOWER_TOP_WALL_POWER):
    """Top height from the mean-height coordinate and the height sd.

    Parameters
    ----------
    m : array
    sd : array (m)
    top_upper : float (m)
        top₁, the upper end of the top's prior.
    top_sds : float
        μ = top − ``top_sds``·sd.
    power : float
        p, the wall's sharpness at μ₁ = top₁ − ``top_sds``·sd.

    Returns
    -------
    top, log_jac : arrays
        top = μ + ``top_sds``·sd with μ = μ₁·t, t from :func:`ratio_from_lower_top` (ρ₀ = 0,
        ρ₁ = 1, H₁ = μ₁), and log|∂top/∂m| = log|∂μ/∂m|; NaN where μ₁ ≤ 0.
    """
    sd = np.asarray(sd, float)
    ceiling = top_upper - top_sds * sd
    share, log_jac = ratio_from_lower_top(m, ceiling, (0.0, 1.0), power)
    with np.errstate(invalid="ignore", divide="ignore"):
        return share * ceiling + top_sds * sd, log_jac + np.log(ceiling)


def mean_height_from_top(top, sd, top_upper, top_sds, power=LOWER_TOP_WALL_POWER):
    """The mean-height coordinate: the inverse of :func:`top_from_mean_height`.

    Parameters
    ----------
    top, sd : arrays (m)
    top_upper : float (m)
    top_sds : float
    power : float

    Returns
    -------
    array
        m; NaN where the mean height is not positive or the top reaches top₁.
    """
    ceiling = top_upper - top_sds * np.asarray(sd, float)
    with np.errstate(invalid="ignore", divide="ignore"):
        share = (np.asarray(top, float) - top_sds * np.asarray(sd, float)) / ceiling
    return lower_top_from_ratio(share, ceiling, (0.0, 1.0), power)
