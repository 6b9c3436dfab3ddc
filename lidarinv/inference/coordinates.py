"""Joint sampling coordinates for crown cover and PAI, which the waveform ties together.

A waveform fixes the canopy's interception, −ln P̄(0) ≈ X·(1 − exp(−a·Lc)), where
X = −ln(1 − cover) = λ·E[crown area] and Lc = PAI / X is the foliage area per unit of
crown-projected area. Few dense crowns (small X, large Lc) and many sparse ones (large X,
small Lc) give the same interception, so in (cover, PAI) the posterior follows an L-shaped
ridge that ensemble moves cross slowly. The coordinates

    s = ln Y,  Y = X·(1 − exp(−a·Lc)),      t = ln Lc

turn that ridge into a nearly straight line along t at fixed s. Only the sampling
coordinates change: the prior stays the one set on cover and PAI, through the Jacobian

    |∂(cover, PAI) / ∂(s, t)| = exp(−X)·X²·Lc.
"""

import numpy as np

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
