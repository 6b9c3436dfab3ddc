"""Importance sampling from a t fitted to the early chain, judged by Pareto-smoothed weights.

Where the posterior is close enough to a Student t in the sampler's coordinates (most
one-storey shots), a few thousand independent draws from a t fitted to the ensemble's
early steps, weighted by posterior over proposal density, give the reported quantiles
at a fraction of the steps the chain needs to pass the ``"ess-rhat"`` rule
(:mod:`.stopping`). :func:`importance_sample` makes the draws and judges them:

- the weights are Pareto-smoothed and their tail's shape k̂ must be at most
  ``khat_max`` (Vehtari et al. 2024: above 0.7 the estimate is unreliable whatever the
  number of draws; 0.5 is asked here, so the check is not marginal);
- every monitored quantity's bulk ESS (of its rank-normalised draws) and tail ESS (of
  its 5 % and 95 % quantiles' indicators), from the smoothed weights, must reach
  ``ess_min`` (1000, more than the chain's rule asks: see :class:`ImportanceSettings`),
  and its quantiles' Monte Carlo error at most ``quantile_mcse_max`` (0.2 sd).

Where only the ESS or the quantiles' error fall short, more draws are made from the same
t, within a bound on the draws. Where the draws fail even so, the t is fitted again to
their weighted draws (adaptive importance sampling: Cappé et al. 2004) and the try begins
again from the new t alone.

Where they pass, the weighted draws are resampled (systematic resampling) into draws of
equal weight, which the result then uses as it would the chain's; where they fail the
chain simply goes on. An unvisited mode is as invisible to the t as to the chain's R̂:
both see only what the walkers found.

References
----------
Vehtari, A., Simpson, D., Gelman, A., Yao, Y. & Gabry, J. (2024). Pareto smoothed
importance sampling. *J. Mach. Learn. Res.* 25(72), 1–58.
Owen, A. B. (2013). *Monte Carlo theory, methods and examples*, Ch. 9 (self-normalised
importance sampling, its variance and effective sample size).
Cappé, O., Guillin, A., Marin, J.-M. & Robert, C. P. (2004). Population Monte Carlo.
*J. Comput. Graph. Statist.* 13(4), 907–929 (a proposal adapted to its own weighted draws).
Douc, R., Cappé, O. & Moulines, E. (2005). Comparison of resampling schemes for particle
filtering. *ISPA 2005*, 64–69 (systematic resampling).
"""

from dataclasses import dataclass

import numpy as np
from scipy import special, stats

from .stopping import DIAGNOSTICS, REPORTED_QUANTILES

#: Rows of each log-posterior call over the draws (memory stays that of a few walkers'
#: worth of waveforms).
CHUNK_ROWS = 512
#: Quantiles whose indicators give the tail ESS (as ArviZ's ``ess(method="tail")``).
TAIL_QUANTILES = (0.05, 0.95)


@dataclass(frozen=True)
class ImportanceSettings:
    """When and how the chain's early steps are tried as an importance proposal.

    Parameters
    ----------
    draws : int
        Draws from the fitted t at each try (0: never try), and the draws a result keeps.
    max_draws : int
        Where k̂ passes but a quantity's ESS falls short, batches of ``draws`` more are
        made from the same t, up to this many in all and no more than the chain's own
        evaluations so far rounded up to whole batches (walkers × steps: each t of a try
        that fails costs about what the run has cost so far, at most), unless the ESS so
        far, grown in proportion, would fall short even then. An ESS grows with the
        draws, and a draw costs what a walker's step does.
    steps : tuple of int
        Steps of the chain at which a try is made, on its second half so far.
    ess_min : float
        Least bulk and tail ESS of every monitored quantity, from the weights. More than
        the chain's rule asks (400), because a chain that passes that rule is at least 20
        τ long, and its 128 walkers then hold a bulk ESS of at least 2560. At 1000 the 5 %
        and 95 % quantiles' Monte Carlo error is about 0.07 posterior sd (2.1 sd/√ESS),
        and the largest of the reported quantities' stays under the 0.2 sd asked of them
        (at 400, draws that passed on a one-storey LVIS shot lay up to 0.21 sd from a
        60 τ chain of the same posterior, where chains lay up to 0.18 sd).
    quantile_mcse_max : float
        Largest Monte Carlo error of every monitored quantity's 5/50/95 % quantiles, in
        posterior sd (the rule's own bound where that is smaller). A 95 % quantile in a
        long, thin tail is uncertain from weights as from a chain, but more variable: on a
        GEDI shot whose PAI has a median of 0.12 and a 95 % quantile near 3.3, passing draws
        at an error of 0.34 sd put it at 5.2, where four chains lay within 3.4–3.9.
    refits : int
        Where the draws from the t fall short (k̂, an ESS or a quantile's error), the t is
        fitted again to their weighted draws (their weighted mean, and their weighted
        covariance times ``scale``²: :func:`weighted_proposal`) and the try begins again
        from the new t alone, with the same bound on its draws; this many times at most,
        so that a try that fails makes up to 1 + ``refits`` times that bound. The chain's
        early steps give a t of about the right size, but off-centre or too narrow where
        the walkers are still spreading; the weights say where the posterior lies.
    khat_max : float
        Largest Pareto k̂ of the weights (Vehtari et al. 2024, §3: the estimate is
        reliable below min(1 − 1/log₁₀ S, 0.7), 0.7 for 4096 draws; the stricter 0.5
        leaves a margin for k̂'s own error).
    dof : float
        Degrees of freedom of the t: heavier tails than the posterior's keep the weights
        bounded.
    scale : float
        Factor on the t's scale matrix (the sample covariance of the chain's draws): a
        proposal wider than the posterior.
    """

    draws: int = 4096
    max_draws: int = 65536
    ess_min: float = 1000.0
    quantile_mcse_max: float = 0.2
    steps: tuple = (200, 400, 800, 1600, 3200, 6400, 12800)
    refits: int = 1
    khat_max: float = 0.5
    dof: float = 5.0
    scale: float = 1.1

    def __post_init__(self):
        if self.draws < 0 or self.max_draws < self.draws:
            raise ValueError(
                f"importance draws must be ≥ 0 and at most max_draws, not {self.draws} "
                f"and {self.max_draws}"
            )
        if self.refits < 0:
            raise ValueError(f"importance refits must be ≥ 0, not {self.refits}")
        if not (self.dof > 2 and self.scale > 0 and self.khat_max > 0):
            raise ValueError("importance dof must exceed 2, and its scale and khat_max be > 0")


@dataclass
class ImportanceRun:
    """One try: the draws resampled to equal weight, and how they were judged."""

    u: np.ndarray  # (draws, ndim), resampled, unbounded coordinates
    log_prob: np.ndarray  # (draws,)
    blobs: np.ndarray  # (draws, n_blobs)
    khat: float
    ess: float  # of the smoothed weights, 1 / Σ w²
    coordinate_ess: np.ndarray  # (ndim,), of each coordinate's mean
    quantities: dict  # name → :data:`.stopping.DIAGNOSTICS` (R̂ and τ NaN)
    step: int  # the chain's step the proposal was fitted at
    passed: bool
    shortfalls: list
    made: int  # draws made in all, from every t tried (batches of ``draws``)


def fit_proposal(points, dof, scale):
    """The t fitted to ``points`` (n, ndim): their mean, their covariance times
    ``scale``² as its scale matrix; None where that is singular."""
    points = np.asarray(points, float)
    if points.shape[0] <= points.shape[1] or not np.all(np.isfinite(points)):
        return None
    shape = np.atleast_2d(np.cov(points, rowvar=False)) * scale**2
    return _student_t(points.mean(axis=0), shape, dof)


def weighted_proposal(draws, weights, dof, scale):
    """The t fitted to weighted ``draws`` (n, ndim; ``weights`` summing to 1): their
    weighted mean, their weighted covariance times ``scale``² as its scale matrix; None
    where the weights hold fewer than 2·ndim draws' worth (1 / Σ w²) or the covariance is
    singular."""
    if not (np.all(np.isfinite(weights)) and weights.any()):
        return None
    if 1.0 / np.sum(weights**2) < 2 * draws.shape[1]:
        return None
    held = weights > 0
    mean = weights[held] @ draws[held]
    centred = draws[held] - mean
    shape = (weights[held, None] * centred).T @ centred * scale**2
    return _student_t(mean, shape, dof)


def _student_t(mean, shape, dof):
    """scipy's multivariate t of ``mean`` and scale matrix ``shape``; None where ``shape``
    is singular."""
    try:
        return stats.multivariate_t(mean, shape, df=dof)
    except (np.linalg.LinAlgError, ValueError):
        return None


def weighted_ess(values, weights) -> float:
    """Effective sample size of the self-normalised estimate of E[``values``] (weights
    summing to 1): the posterior variance over the estimate's, Σ w (h − μ)² / Σ w² (h − μ)²
    (Owen 2013, §9.3), at most the weights' own 1 / Σ w² (the variance is itself
    estimated from the weights, and is no better than they are); NaN where ``values`` do
    not vary."""
    mean = np.sum(weights * values)
    spread = (values - mean) ** 2
    error = np.sum(weights**2 * spread)
    if not error > 0:
        return np.nan
    return float(min(np.sum(weights * spread) / error, 1.0 / np.sum(weights**2)))


def normal_scores(values, weights) -> np.ndarray:
    """Weighted draws rank-normalised: Φ⁻¹ of each draw's mid-point on the weighted CDF
    (ties share theirs). The bulk ESS of a chain is that of its rank-normalised draws
    (Vehtari et al. 2021); so is that of weighted draws here, which the reported quantiles
    need, and which a long tail does not drag down as it does the mean's."""
    order = np.argsort(values, kind="stable")
    ranked = np.cumsum(weights[order]) - 0.5 * weights[order]
    _, first, counts = np.unique(values[order], return_index=True, return_counts=True)
    shared = np.add.reduceat(ranked, first) / counts  # ties: the mean of their mid-points
    mid = np.empty_like(ranked)
    mid[order] = np.repeat(shared, counts)
    return special.ndtri(np.clip(mid, 1e-12, 1 - 1e-12))


def weighted_quantiles(values, weights, probabilities) -> np.ndarray:
    """Quantiles of weighted draws (the inverse of their weighted CDF)."""
    return np.quantile(values, probabilities, weights=weights, method="inverted_cdf")


def weighted_diagnostics(values, weights) -> dict:
    """:data:`.stopping.DIAGNOSTICS` of one weighted quantity (weights summing to 1).

    The bulk ESS is that of its rank-normalised draws (:func:`normal_scores`); the tail
    ESS, the least of its 5 % and 95 % quantiles' indicators' (as ArviZ's tail ESS); the
    quantile error, the largest over the 5/50/95 % quantiles of half the spread between
    the quantiles at q ± the standard error of the CDF there, in posterior sd (as ArviZ's
    ``mcse(method="quantile")``). R̂ and τ are NaN (τ 0 where the quantity does not vary,
    as :func:`.stopping.quantity_diagnostics` has it)."""
    out = dict.fromkeys(DIAGNOSTICS, np.nan)
    if not np.all(np.isfinite(values)):
        return out
    mean = np.sum(weights * values)
    sd = float(np.sqrt(np.sum(weights * (values - mean) ** 2)))
    if not sd > 0:
        return {**out, "tau": 0.0}  # a quantity that does not vary (as the chain's rule)
    out["ess_bulk"] = weighted_ess(normal_scores(values, weights), weights)
    probabilities = np.asarray(REPORTED_QUANTILES) / 100
    ess_at, errors = {}, []
    for q, at in zip(probabilities, weighted_quantiles(values, weights, probabilities)):
        ess = ess_at[q] = weighted_ess((values <= at).astype(float), weights)
        half = np.sqrt(q * (1 - q) / ess) if ess > 0 else np.inf  # the CDF's standard error
        low, high = weighted_quantiles(values, weights, np.clip([q - half, q + half], 0, 1))
        errors.append(0.5 * (high - low) / sd)
    out["ess_tail"] = min(ess_at[q] for q in TAIL_QUANTILES)
    out["quantile_mcse"] = float(np.max(errors))
    return out


def systematic_resample(weights, rng) -> np.ndarray:
    """Indices of ``weights.size`` draws of equal weight: one uniform offset, then evenly
    spaced points on the weights' cumulative sum (Douc et al. 2005)."""
    n = weights.size
    points = (rng.uniform() + np.arange(n)) / n
    cumulative = np.cumsum(weights)
    return np.minimum(np.searchsorted(cumulative, points * cumulative[-1]), n - 1)


def importance_sample(
    log_posterior, points, monitor, rule, settings, rng, step, budget=None
) -> ImportanceRun:
    """Draws from a t fitted to ``points`` (fitted again to its weighted draws where they
    fall short, ``settings.refits`` times at most), weighted, smoothed and judged.

    Parameters
    ----------
    log_posterior : callable
        Vectorised (n, ndim) → (n, 1 + n_blobs), unbounded coordinates.
    points : array (n, ndim)
        The chain's draws the proposal is fitted to.
    monitor : callable
        (chain (steps, walkers, ndim), blobs) → dict of name → (steps, walkers): the
        quantities judged (those the stopping rule judges).
    rule : .stopping.StopRule
        Its ``quantile_mcse_max`` is asked of every quantity, and its ``ess_min`` where
        more than ``settings.ess_min``.
    settings : ImportanceSettings
    rng : numpy.random.Generator
    step : int
        The chain's step, recorded.
    budget : int, optional
        Most draws from each t, if fewer than ``settings.max_draws`` (the chain's
        evaluations so far), rounded up to whole batches of ``settings.draws``.

    Returns
    -------
    ImportanceRun or None
        None where the t cannot be fitted (a singular covariance).
    """
    proposal = fit_proposal(points, settings.dof, settings.scale)
    if proposal is None:
        return None
    limit = max(settings.draws, min(settings.max_draws, budget or settings.max_draws))
    made = 0
    for refit in range(settings.refits + 1):
        u, evaluated, judged = _draws_from(proposal, log_posterior, monitor, rule, settings, rng,
                                           limit)  # fmt: skip
        made += len(u)
        weights, khat, shortfalls = judged[0], judged[1], judged[-1]
        if not shortfalls or refit == settings.refits:
            break
        proposal = weighted_proposal(u, weights, settings.dof, settings.scale)
        if proposal is None:
            break
    keep = systematic_resample(weights, rng)[
        np.sort(rng.choice(len(u), settings.draws, replace=False))
    ]  # as many draws as one batch, whatever the batches made
    return ImportanceRun(
        u[keep], evaluated[keep, 0], evaluated[keep, 1:], khat,
        float(1.0 / np.sum(weights**2)) if weights.any() else 0.0, *judged[2:4], step,
        not shortfalls, shortfalls, made,
    )  # fmt: skip


def _draws_from(proposal, log_posterior, monitor, rule, settings, rng, limit):
    """Batches of draws from one t, judged, until they pass, k̂ fails, ``limit`` draws are
    made, or the ESS so far, grown in proportion, could not reach the asked one within
    ``limit``: the draws, their log-posterior and blobs, and :func:`_judge`'s verdict."""
    batches, rows, log_q = [], [], []
    while True:  # more draws from the same t while only their number falls short
        batch = np.atleast_2d(proposal.rvs(settings.draws, random_state=rng))
        batches.append(batch)
        rows += [log_posterior(batch[i : i + CHUNK_ROWS]) for i in range(0, len(batch), CHUNK_ROWS)]
        log_q.append(proposal.logpdf(batch))
        u, evaluated = np.vstack(batches), np.vstack(rows)
        judged = _judge(u, evaluated, np.concatenate(log_q), monitor, rule, settings)
        khat, shortfalls = judged[1], judged[-1]
        if not shortfalls or not khat <= settings.khat_max or len(u) >= limit:
            return u, evaluated, judged
        if _least_ess(judged[3]) * limit / len(u) < settings.ess_min:
            return u, evaluated, judged  # even the limit would fall short


def _least_ess(quantities) -> float:
    """The least bulk or tail ESS of the quantities that vary (0 if one is not finite)."""
    values = [min(d["ess_bulk"], d["ess_tail"]) for d in quantities.values() if d["tau"] != 0]
    values = [v if np.isfinite(v) else 0.0 for v in values]
    return min(values, default=np.inf)


def _judge(u, evaluated, log_q, monitor, rule, settings):
    """The smoothed weights of draws ``u`` (log-posterior and blobs ``evaluated``, proposal
    log-density ``log_q``), their k̂, each coordinate's ESS, the monitored quantities'
    diagnostics, and what falls short."""
    import arviz as az  # imported on first use: it is slow to import

    log_prob, blobs = evaluated[:, 0], evaluated[:, 1:]
    finite = np.isfinite(log_prob)
    weights, khat = np.zeros(len(u)), np.inf
    if finite.sum() >= 10:  # PSIS fits its tail to the largest fifth of at least these
        smoothed, khat = az.psislw(log_prob[finite] - log_q[finite], reff=1.0)
        weights[finite] = np.exp(smoothed - np.max(smoothed))
        weights /= weights.sum()
        khat = float(khat)
    if not khat <= settings.khat_max:  # NaN too
        return weights, khat, np.full(u.shape[1], np.nan), {}, [
            f"importance weights' Pareto k̂ {khat:.2f} > {settings.khat_max:g}"
        ]  # fmt: skip
    held = weights > 0  # draws outside the support weigh nothing (their blobs are NaN)
    draws = monitor(u[held, None, :], blobs[held, None, :])
    quantities = {name: weighted_diagnostics(v[:, 0], weights[held]) for name, v in draws.items()}
    coordinate_ess = np.array([weighted_ess(u[held, i], weights[held]) for i in range(u.shape[1])])
    bound = min(settings.quantile_mcse_max, rule.quantile_mcse_max or np.inf)
    shortfalls = rule.importance_shortfalls(quantities, max(rule.ess_min, settings.ess_min), bound)
    return weights, khat, coordinate_ess, quantities, shortfalls
