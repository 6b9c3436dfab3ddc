"""Competing explanations of a shot: optima that put the ground at another return.

A lone return can be a bare ground or the top of a dense canopy over a ground lost in the
noise; a low return under a bright layer can be the ground or an understory. The MAP
search polishes several optima in separate basins (:func:`.sampling.start.find_map`);
:func:`competing_grounds` keeps those whose ground lies a pulse width or more from the
MAP's and whose Laplace mass is within :data:`MASS_WINDOW` of the MAP's. The sampler then
starts walkers in each of them, and the result says so, so that a second explanation
shows in the posterior and in the diagnostics instead of being left unexplored.
"""

import numpy as np

from ..sampling.start import MapEstimate, Mode, laplace_covariance

#: Largest log ratio of Laplace masses exp(log p)·√det Σ at which another optimum still
#: counts as an explanation: a posterior odds of 1 : 20 (log 20 ≈ 3).
MASS_WINDOW = np.log(20.0)
#: How the note of grounds that compete at the start begins (the walkers start at each).
COMPETING_GROUNDS_NOTE = "ground ambiguous: the MAP puts it"
#: How the flag of a posterior that keeps both grounds of a two-ground prior begins.
GROUND_MODES_FLAG = "ground ambiguous in the posterior"

#: Pulse area left out in each tail for the width that separates two grounds: the central
#: 80 %, about the full width at half maximum of a Gaussian pulse.
PULSE_TAIL = 0.1


#: Points on which a pulse's CDF is inverted for its central width.
_WIDTH_GRID = 4097


def pulse_width_m(pulse) -> float:
    """Width (m) of a pulse's central part, :data:`PULSE_TAIL` of its area left out in each
    tail: the CDF inverted on a fine grid over the pulse's whole support (a measured pulse's
    sampled span holds its tails and the record's noise around a narrow peak)."""
    low, high = pulse.support(1e-9)
    offsets = np.linspace(low, high, _WIDTH_GRID)
    area = pulse.cdf(offsets)
    below, above = np.interp([PULSE_TAIL, 1.0 - PULSE_TAIL], area, offsets)
    return float(above - below)


def competing_grounds(log_prob, estimate: MapEstimate, space, separation_m) -> list:
    """The MAP and the optima that place the ground elsewhere with a comparable mass.

    Parameters
    ----------
    log_prob : callable
        Vectorised log-density of unbounded coordinates, (k, ndim) → (k,).
    estimate : MapEstimate
        A MAP search with its polished optima.
    space : ParameterSpace
        With a free ``ground_elevation``.
    separation_m : float (m)
        Least ground difference from every mode kept before.

    Returns
    -------
    list of (Mode, float)
        The MAP's mode first, then each competing one, with its ground elevation (m); the
        MAP alone where none competes or the ground is not free.

    References
    ----------
    MacKay, D. J. C. (2003). *Information Theory, Inference, and Learning Algorithms*.
    Cambridge University Press, Ch. 27 (Laplace's method) (the Laplace mass of each basin).
    """
    best = Mode(estimate.u, estimate.log_prob, estimate.covariance)
    if "ground_elevation" not in space.names or estimate.covariance is None:
        return [(best, np.nan)]
    column = space.names.index("ground_elevation")
    ground = lambda u: float(space.from_unbounded(u[None, :])[0][0, column])  # noqa: E731
    kept = [(best, ground(best.u))]
    for u, value in sorted(estimate.optima, key=lambda optimum: -optimum[1]):
        elevation = ground(u)
        if any(abs(elevation - other) < separation_m for _, other in kept):
            continue
        mode = Mode(np.asarray(u, float), value, laplace_covariance(log_prob, u))
        if mode.log_mass >= best.log_mass - MASS_WINDOW:
            kept.append((mode, elevation))
    return kept


def describe(kept) -> str | None:
    """The result's flag for competing grounds, or None for the MAP alone."""
    if len(kept) < 2:
        return None
    best_mass = kept[0][0].log_mass
    others = ", ".join(
        f"{elevation:.2f} m (mass ratio {np.exp(mode.log_mass - best_mass):.2g})"
        for mode, elevation in kept[1:]
    )
    return (
        f"{COMPETING_GROUNDS_NOTE} at {kept[0][1]:.2f} m, other explanations at "
        f"{others}; the walkers started in each (see the ground's posterior)"
    )


#: Posterior share below which a ground of a two-ground prior no longer counts as an
#: explanation: the odds of :data:`MASS_WINDOW`, 1 : 20.
LEAST_SHARE = 1.0 / 21.0


def ground_modes(space, x) -> dict | None:
    """The evidence for each ground of a two-ground prior
    (:class:`..model.priors.TruncatedNormalMixture`), from the posterior samples.

    Parameters
    ----------
    space : ParameterSpace
    x : array (n, ndim)
        Posterior samples (physical units).

    Returns
    -------
    dict or None
        ``grounds`` (m): the analysis's chosen ground, then its alternative;
        ``prior_weights``; ``posterior_probability``: P(the ground is that return | y),
        the posterior mean of each component's responsibility for the sample's ground
        (the prior weights updated by the data's evidence for each). None where the
        ground's prior is not a mixture or the ground is not free.
    """
    if "ground_elevation" not in space.names:
        return None
    prior = space.by_name["ground_elevation"].prior
    if not hasattr(prior, "responsibilities"):
        return None
    ground = np.asarray(x, float)[:, space.names.index("ground_elevation")]
    shares = prior.responsibilities(ground)
    shares = shares[np.all(np.isfinite(shares), axis=1)]
    _, weights = prior.components()
    return {
        "grounds": [float(prior.mean), float(prior.alt_mean)],
        "prior_weights": [float(w) for w in weights],
        "posterior_probability": [float(p) for p in shares.mean(axis=0)],
    }


def describe_modes(modes) -> str | None:
    """The result's flag where both grounds of a two-ground prior keep posterior mass."""
    if modes is None or min(modes["posterior_probability"]) < LEAST_SHARE:
        return None
    (chosen, alternative), (p_chosen, p_alt) = modes["grounds"], modes["posterior_probability"]
    return (
        f"{GROUND_MODES_FLAG}: P = {p_chosen:.2f} at the analysis's ground "
        f"({chosen:.2f} m), {p_alt:.2f} at its alternative ({alternative:.2f} m); the "
        "ground's quantiles span both"
    )
