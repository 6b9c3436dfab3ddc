"""Where a mixture of height laws leaves a given share of its stems above: numpy and compiled.

The stems of a stand of several cohorts (:mod:`.two_cohort`) above a height h are the
share Σ_k f_k S_k(h) of all its stems, with f_k the cohorts' shares and S_k their height
laws' survival functions. :func:`mixture_cut` solves Σ_k f_k S_k(h) = ``tail`` for h: the
cut of the dominant stems (the 100 tallest a hectare) and the tallest stem of a footprint.
The upper cohort's own cut, S₁(h₀) = tail/f₁, in closed form, is the answer wherever the
other cohorts have no stems above it (the usual case for the tallest stems); the other
rows are bisected on [h₀, the tallest cohort's top].

The numpy reference bisects every such row at once, one call of the family's survival
function a step. The compiled kernel (truncated-normal heights) bisects the same bracket
row by row, so that a batch of rows costs one call instead of
:data:`BISECTION_STEPS`: a sampler evaluating two-storey stands asks for the dominant
height at every call of the log-posterior. Both take ``backend=``
(:mod:`forward.backends`).
"""

import numpy as np

from forward.backends import as_float64, jit, resolve

from .prior_table import normal_cdf

#: Bisection steps of the cuts: a 60 m span to 4 µm.
BISECTION_STEPS = 24
#: Rows whose closed-form cut misses ``tail`` by more than this (relative) are bisected.
CUT_TOLERANCE = 1e-9


def cohort_row(args, index):
    """The family's arguments ``args`` (nested tuples of arrays and scalars) at ``index``
    of their arrays' leading axis: a cohort of stacked arguments, or some rows."""
    if isinstance(args, tuple):
        return tuple(cohort_row(a, index) for a in args)
    return args[index] if np.ndim(args) else args


def mixture_sum(fast, which, h, shares, args):
    """Σ_k f_k·F_k(h) of the family's function ``which`` (``fast``), every cohort in one
    call: ``args`` stacked on a leading cohort axis, ``shares`` one array per cohort."""
    values = fast(which, h, *args)
    return sum(f * values[k] for k, f in enumerate(shares))


def mixture_cut(family, laws, tail, *, backend="auto"):
    """The height h where the mixture's survival Σ f_k S_k(h) equals ``tail``.

    Parameters
    ----------
    family : forward.height_families.HeightFamily
    laws : (tuple of array (n,), tuple)
        The cohorts' shares, upper cohort first, and their height laws' arguments
        (``family.arguments``) stacked on a leading cohort axis.
    tail : array (n,)
        Share of the stems above the cut.
    backend : str
        ``"auto"``, ``"numba"`` or ``"numpy"``; compiled for ``truncnorm`` heights only.

    Returns
    -------
    array (n,) (m)
        The cut; 0 where ``tail`` ≥ 1 (every stem is above it).
    """
    fast = family.fast
    shares, args = laws
    f1 = shares[0]
    cut = fast("isf", np.clip(tail / np.maximum(f1, 1e-300), 0.0, 1.0), *cohort_row(args, 0))
    if resolve(backend) == "numba" and family.name == "truncnorm":
        (low, high), loc, scale = args
        top = np.max(fast("isf", 1e-12, *args), axis=0)
        cut = _truncnorm_cut(
            *map(as_float64, (np.stack(shares), low, high, loc, scale, tail, cut, top))
        )
    else:
        cut = _bisected_cut(fast, shares, args, tail, cut)
    return np.where(tail < 1.0, cut, 0.0)


def _bisected_cut(fast, shares, args, tail, cut):
    """The reference: the closed-form ``cut`` where it holds, else bisected (in place)."""
    rows = np.flatnonzero(
        np.abs(mixture_sum(fast, "sf", cut, shares, args) - tail) > CUT_TOLERANCE * tail
    )
    if rows.size:
        part = tuple(f[rows] for f in shares), cohort_row(args, (slice(None), rows))
        low = np.where(tail[rows] < shares[0][rows], cut[rows], 0.0)
        high = np.max(fast("isf", 1e-12, *part[1]), axis=0)
        for _ in range(BISECTION_STEPS):
            mid = 0.5 * (low + high)
            above = mixture_sum(fast, "sf", mid, *part) > tail[rows]
            low, high = np.where(above, mid, low), np.where(above, high, mid)
        cut[rows] = 0.5 * (low + high)
    return cut


@jit
def _truncnorm_mixture_sf(shares, low, high, cdf_low, cdf_high, loc, scale, row, h):
    """Σ_k f_k S_k(h) of truncated normals (standardised bounds ``low``, ``high``, and Φ
    of them) at one row, as the family's ``fast("sf")`` computes each S_k."""
    total = 0.0
    for k in range(shares.shape[0]):
        y = min(max((h - loc[k, row]) / scale[k, row], low[k, row]), high[k, row])
        survival = (cdf_high[k, row] - normal_cdf(y)) / (cdf_high[k, row] - cdf_low[k, row])
        total += shares[k, row] * min(max(survival, 0.0), 1.0)
    return total


@jit
def _truncnorm_cut(shares, low, high, loc, scale, tail, cut, top):
    """The kernel of :func:`mixture_cut` for truncated-normal heights: each row's
    closed-form ``cut`` where it holds, else bisected on [cut or 0, ``top``]."""
    out = cut.copy()
    cdf_low, cdf_high = np.empty_like(low), np.empty_like(high)
    for k in range(low.shape[0]):
        for row in range(low.shape[1]):
            cdf_low[k, row], cdf_high[k, row] = normal_cdf(low[k, row]), normal_cdf(high[k, row])
    laws = (shares, low, high, cdf_low, cdf_high, loc, scale)
    for row in range(tail.size):
        target = tail[row]
        miss = abs(_truncnorm_mixture_sf(*laws, row, cut[row]) - target)
        if not miss > CUT_TOLERANCE * target:  # NaN rows stay as they are, as in numpy
            continue
        below = cut[row] if target < shares[0, row] else 0.0
        above = top[row]
        for _ in range(BISECTION_STEPS):
            mid = 0.5 * (below + above)
            if _truncnorm_mixture_sf(*laws, row, mid) > target:
                below = mid
            else:
                above = mid
        out[row] = 0.5 * (below + above)
    return out
