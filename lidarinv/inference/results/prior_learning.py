"""What the waveform taught the sampler about each parameter: its posterior against its prior.

Some parameters leave the waveform flat (the crown shape often does): their posterior
marginal is then their prior, and their quantiles say nothing about the stand. Each
sampled parameter's posterior samples are compared with draws of the prior the sampler
used, the free parameters' priors restricted to the posterior's support (valid stands, the
FAVD range), by

- the posterior contraction 1 − var(posterior)/var(prior): 0 where the data left the
  spread as it was, 1 where they pinned the parameter;
- the two-sample Kolmogorov–Smirnov distance D = max |F_posterior − F_prior|: the largest
  shift, in probability, of any quantile.

A parameter is *prior-dominated* where D is within its Monte Carlo noise (the two-sample
test's 5 % critical distance at the posterior's effective sample size) or below
:data:`PRIOR_DOMINATED_DISTANCE`.

References
----------
Schad, D. J., Betancourt, M. & Vasishth, S. (2021). Toward a principled Bayesian workflow
in cognitive science. *Psychological Methods* 26(1), 103–126 (posterior contraction).
"""

import numpy as np
from scipy import special, stats

#: Prior draws the posterior marginals are compared with.
PRIOR_DRAWS = 2048
#: A posterior whose every quantile lies within this probability of the prior's (KS
#: distance) is prior-dominated: the prior's median, for one, stays between the posterior's
#: 40 % and 60 % quantiles.
PRIOR_DOMINATED_DISTANCE = 0.1
#: Level of the two-sample KS critical distance taken as the Monte Carlo noise of D.
NOISE_LEVEL = 0.05


def support_prior_draws(log_posterior, space, rng, size=PRIOR_DRAWS) -> np.ndarray:
    """Draws of the prior the sampler used, in physical units.

    Parameters
    ----------
    log_posterior : LogPosterior
        Its support (valid stands, the FAVD range) restricts the priors.
    space : ParameterSpace
    rng : numpy.random.Generator
    size : int
        Draws before the restriction.

    Returns
    -------
    array (k, ndim)
        The free parameters' prior draws (:meth:`.ParameterSpace.sample_prior`) inside
        the posterior's support, k ≤ ``size``.
    """
    x = space.sample_prior(rng, size)
    inside = np.isfinite(log_posterior.evaluate(x).log_posterior)
    return x[inside]


def prior_learning(samples, prior, names, ess=None) -> dict:
    """How far the posterior of each parameter moved from its prior.

    Parameters
    ----------
    samples : array (m, k)
        Posterior samples, one column per name.
    prior : array (p, k)
        Prior draws (:func:`support_prior_draws`), the same columns.
    names : sequence of str
        The k parameters.
    ess : dict of name → float, optional
        The posterior's effective sample size per parameter (the number of samples where
        missing or not positive and finite).

    Returns
    -------
    dict of name → dict
        ``prior_sd`` and ``posterior_sd`` (the parameter's units), ``contraction``,
        ``ks_distance``, ``ks_noise`` (the 5 % critical distance at the effective sizes)
        and ``prior_dominated`` (bool); parameters with fewer than two finite samples or
        prior draws, or a prior of no spread, are left out.
    """
    samples, prior = np.atleast_2d(samples), np.atleast_2d(prior)
    if samples.shape[1] != len(names) or prior.shape[1] != len(names):
        raise ValueError(
            f"samples {samples.shape} and prior draws {prior.shape} must have one column "
            f"per parameter ({len(names)})"
        )
    ess = ess or {}
    critical = special.kolmogi(NOISE_LEVEL)  # the asymptotic two-sample coefficient c(α)
    out = {}
    for j, name in enumerate(names):
        post, before = samples[:, j], prior[:, j]
        post, before = post[np.isfinite(post)], before[np.isfinite(before)]
        prior_var = np.var(before) if before.size > 1 else 0.0
        if post.size < 2 or not prior_var > 0:
            continue
        effective = float(ess.get(name, np.nan))
        if not (np.isfinite(effective) and effective > 0):
            effective = post.size
        effective = min(effective, post.size)
        # the statistic alone: the asymptotic p-value spares the exact one's cost
        distance = float(stats.ks_2samp(post, before, method="asymp").statistic)
        noise = float(critical * np.sqrt(1.0 / max(effective, 1.0) + 1.0 / before.size))
        out[name] = {
            "prior_sd": float(np.sqrt(prior_var)),
            "posterior_sd": float(np.std(post)),
            "contraction": float(1.0 - np.var(post) / prior_var),
            "ks_distance": distance,
            "ks_noise": noise,
            "prior_dominated": bool(distance <= max(noise, PRIOR_DOMINATED_DISTANCE)),
        }
    return out


def prior_dominated(learning) -> list:
    """The parameters :func:`prior_learning` found prior-dominated, in its order.

    Parameters
    ----------
    learning : dict
        :func:`prior_learning`'s result (empty or missing for results without one).

    Returns
    -------
    list of str
    """
    return [name for name, row in (learning or {}).items() if row.get("prior_dominated")]


def describe_prior_dominated(learning) -> str | None:
    """The summary's line on the prior-dominated parameters, None where there are none.

    Parameters
    ----------
    learning : dict
        :func:`prior_learning`'s result.

    Returns
    -------
    str or None
    """
    names = prior_dominated(learning)
    if not names:
        return None
    cells = ", ".join(
        f"{name} (KS {learning[name]['ks_distance']:.2f}, "
        f"contraction {learning[name]['contraction']:.2f})"
        for name in names
    )
    return f"posterior ≈ prior (these quantiles are the prior's): {cells}"
