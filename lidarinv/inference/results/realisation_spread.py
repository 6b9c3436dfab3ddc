"""How far another draw of the discrepancy's realisations would move the reported quantiles.

The simulated discrepancy covariance (:mod:`..passes.realisations`) is an estimate from
K random stands, and the posterior it defines moves with them: a shot prepared with
another seed reports other quantiles, by more than the sampler's own Monte Carlo error
when K is small. :func:`realisation_spread` measures that share of the answer's
randomness without sampling again. Each bootstrap resample of the K residuals (drawn
with replacement) defines the covariance a new draw of K stands might have given; the
posterior samples, reweighted by the likelihood ratio of that covariance to the one
sampled, give that posterior's quantiles (importance sampling; the covariances differ
little, so the weights stay even). The spread of the quantiles over the resamples,
in posterior sd, is the quantity's ``realisation_spread``.

It holds the realisations' share of the preparation's randomness; the MAP search's
share (the point the draws surround) is not in it.
"""

import time
from dataclasses import dataclass

import numpy as np

from ..likelihood.following import FollowingCovariance
from ..passes.realisations import discrepancy_covariance
from .reported import REPORTED

#: The reported quantiles (%) whose spread is measured.
SPREAD_QUANTILES = (5.0, 50.0, 95.0)

#: How the note of quantiles that another draw of the realisations would move begins.
SEED_SPREAD_NOTE = "another draw of the discrepancy's"
#: How the note of a bootstrap of the realisations that could not run begins.
SPREAD_NOT_MEASURED_NOTE = "realisation spread not measured"


@dataclass(frozen=True)
class DiscrepancyDraws:
    """The realisations a shot's discrepancy covariance was made from.

    Attributes
    ----------
    residuals : array (K, bins) (DN)
        The realisation residuals (:func:`..passes.realisations.realisation_residuals`).
    shrinkage : float
        γ of :func:`..passes.realisations.discrepancy_covariance`.
    diagonal : array (bins,) (DN²)
        Variances added to the simulated covariance (the instrument model's error).
    """

    residuals: np.ndarray
    shrinkage: float
    diagonal: np.ndarray

    def covariance(self, rows=None) -> np.ndarray:
        """The covariance of the residuals ``rows`` (all of them by default), (bins, bins)
        (DN²)."""
        residuals = self.residuals if rows is None else self.residuals[rows]
        return discrepancy_covariance(residuals, self.shrinkage) + np.diag(self.diagonal)


@dataclass(frozen=True)
class RealisationSpread:
    """:func:`realisation_spread`'s outcome.

    Attributes
    ----------
    spread : dict of name → float
        The largest sd over the resamples of the quantity's 5, 50 and 95 % quantiles, in
        posterior sd.
    weight_fraction : float
        The smallest effective sample size of a resample's weights, as a fraction of the
        samples reweighted: near 1 where the resampled covariances define nearly the same
        posterior, small where the estimate is unreliable.
    """

    spread: dict
    weight_fraction: float


def realisation_spread(
    log_posterior, draws: DiscrepancyDraws, x, columns: dict, rng, resamples=16, samples=512
) -> RealisationSpread:
    """The spread of the reported quantiles over bootstrap resamples of the realisations.

    Parameters
    ----------
    log_posterior : LogPosterior
        The posterior sampled, whose likelihood holds ``draws.covariance()``.
    draws : DiscrepancyDraws
    x : array (n, ndim)
        Posterior samples (physical units).
    columns : dict of name → array (n,)
        The reported quantities of the same samples.
    rng : numpy.random.Generator
    resamples : int
        Bootstrap resamples B ≥ 2.
    samples : int
        Posterior samples reweighted (picked at random).

    Returns
    -------
    RealisationSpread
    """
    if resamples < 2:
        raise ValueError(f"the spread needs at least 2 resamples, got {resamples}")
    pick = rng.choice(x.shape[0], size=min(int(samples), x.shape[0]), replace=False)
    terms = log_posterior.evaluate(x[pick], keep_signal=True)
    kept = np.isfinite(terms.log_likelihood)
    if kept.sum() < 2:
        return RealisationSpread(dict.fromkeys(columns, np.nan), np.nan)
    pick, signal = pick[kept], terms.signal[kept]
    values = log_posterior.space.values(x[pick])
    likelihood = log_posterior.likelihood
    count = draws.residuals.shape[0]
    columns = {name: np.asarray(column, float) for name, column in columns.items()}
    picked = {name: column[pick] for name, column in columns.items()}
    probabilities = np.array(SPREAD_QUANTILES) / 100
    quantiles = {name: [] for name in columns}
    fractions = []
    for _ in range(int(resamples)):
        rows = rng.integers(0, count, count)
        resampled = resampled_likelihood(likelihood, draws, rows)
        log_ratio = resampled.log_likelihood(signal, values)[0] - terms.log_likelihood[kept]
        weights = np.exp(log_ratio - np.max(log_ratio))
        fractions.append(np.sum(weights) ** 2 / np.sum(weights**2) / weights.size)
        for name, v in picked.items():
            finite = np.isfinite(v) & np.isfinite(weights)
            if finite.sum() < 2 or not np.sum(weights[finite]) > 0:  # nothing to weigh
                quantiles[name].append(np.full(len(SPREAD_QUANTILES), np.nan))
                continue
            quantiles[name].append(
                np.quantile(
                    v[finite],
                    probabilities,
                    weights=weights[finite],
                    method="inverted_cdf",
                )
            )
    spread = {}
    for name, column in columns.items():
        sd = np.std(column[np.isfinite(column)]) if np.isfinite(column).any() else 0.0
        moved = np.std(quantiles[name], axis=0, ddof=1)
        spread[name] = float(np.max(moved) / sd) if sd > 0 else np.nan
    return RealisationSpread(spread, float(np.min(fractions)))


#: The heights compared with the products, measured beside the monitored quantities.
COMPARED_HEIGHTS = ("rh98_product", "rh98_footprint")

#: A quantity whose quantiles another draw of the realisations would move by more than
#: this (posterior sd) is flagged: the answer depends on the seed more than on the data's
#: resolution of it, and a larger ``RealisationSettings.count`` is needed.
FLAG_SPREAD_SD = 0.5


def resampled_likelihood(likelihood, draws: DiscrepancyDraws, rows):
    """The likelihood under the covariance of the residuals ``rows``; one that follows
    each row's stand (:mod:`..likelihood.following`) follows it from those residuals too."""
    resampled = likelihood.with_fixed_discrepancy(draws.covariance(rows))
    following = getattr(likelihood, "following", None)  # absent from other likelihoods
    if following is None:
        return resampled
    return resampled.with_following(
        FollowingCovariance.of(
            draws.residuals[rows], draws.shrinkage, following.pilot_signal, draws.diagonal,
            likelihood.whitening,
        )
    )  # fmt: skip


def add_realisation_spread(result, problem, draws: DiscrepancyDraws, rng, resamples) -> None:
    """Measure :func:`realisation_spread` for a result's reported quantities and record it.

    Measured for the quantities the stopping rule monitored (the reported ones) and
    :data:`COMPARED_HEIGHTS`. Adds ``diagnostics["realisation_spread"]`` (``spread``: name
    → posterior sd, ``weight_fraction``, ``resamples``) and its wall time to
    ``diagnostics["seconds"]``, and a flag where a quantity's spread exceeds
    :data:`FLAG_SPREAD_SD`.

    Parameters
    ----------
    result : InversionResult
    problem : InversionProblem
        The problem sampled.
    draws : DiscrepancyDraws
    rng : numpy.random.Generator
    resamples : int
    """
    clock = time.perf_counter()
    names = [*result.diagnostics.get("quantities", {}), *REPORTED, *COMPARED_HEIGHTS]
    names = [n for n in dict.fromkeys(names) if n in result.quantity_names]
    x = result.samples[:, : problem.space.ndim]
    columns = {name: result.column(name) for name in names}
    found = realisation_spread(problem.log_posterior, draws, x, columns, rng, resamples)
    result.diagnostics["realisation_spread"] = {
        "spread": found.spread,
        "weight_fraction": found.weight_fraction,
        "resamples": int(resamples),
    }
    result.diagnostics.setdefault("seconds", {})["realisation_spread"] = time.perf_counter() - clock
    moved = {n: v for n, v in found.spread.items() if v > FLAG_SPREAD_SD}
    if moved:
        worst, simulated = max(moved, key=moved.get), draws.residuals.shape[0]
        asked = problem.settings.realisations.count
        remedy = (
            "raise RealisationSettings.count"
            if simulated >= asked
            else f"the first {simulated} of {asked} seemed enough before sampling: set "
            "RealisationSettings.first_fraction = 1"
        )
        result.flags.append(
            f"{SEED_SPREAD_NOTE} {simulated} realisations may move {worst}'s quantiles "
            f"by {moved[worst]:.2f} posterior sd (bootstrap): the answer depends on the "
            f"seed; {remedy}"
        )


def describe_spread(found, counts=None) -> str:
    """The summary's line on how far another draw of the realisations moves the quantiles
    (``found``: ``diagnostics["realisation_spread"]``), with how many were simulated of
    how many asked (``counts``: ``diagnostics["realisations"]``) where known."""
    cells = ", ".join(f"{name} {v:.2f}" for name, v in found["spread"].items())
    how_many = ""
    if counts is not None:
        how_many = f"{counts['simulated']} of {counts['asked']} "
    return (
        f"spread of the 5/50/95 % quantiles over the discrepancy's {how_many}realisations "
        f"(posterior sd, {found['resamples']} bootstrap resamples, weights' effective "
        f"fraction ≥ {found['weight_fraction']:.2f}): {cells}"
    )


def largest_spread(diagnostics) -> float:
    """The largest realisation spread of a result (posterior sd); NaN where not measured."""
    spread = diagnostics.get("realisation_spread", {}).get("spread", {})
    known = [v for v in spread.values() if v is not None and np.isfinite(v)]
    return float(max(known)) if known else np.nan
