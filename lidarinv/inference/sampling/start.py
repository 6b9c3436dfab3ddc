"""The sampler's start: the MAP search and the walkers' initial ball.

:func:`find_map` maximises the log-posterior in unbounded coordinates from many prior
draws, its L-BFGS-B runs batched in lockstep (:mod:`.batched_minimize`);
:func:`laplace_covariance` gives the covariance at an optimum, :func:`distinct_modes` the
optima in separate basins, and :func:`initial_ball` the walkers around them.
"""

from dataclasses import dataclass, field

import numpy as np

from .batched_minimize import minimize_in_lockstep

#: Large finite objective for the optimiser where the log-density is −inf.
_PENALTY = 1e12

#: Screened starts closer than this (unbounded units, where a prior spans about ±3) to a
#: better one are not polished: they would most likely end in the same optimum.
POLISH_SPACING = 0.25

#: How the note of a MAP search that ended at its iteration limit begins.
MAP_NOT_CONVERGED_NOTE = "MAP optimiser did not report convergence"


@dataclass
class MapEstimate:
    """Best optimiser result in unbounded coordinates, with a Laplace covariance."""

    u: np.ndarray
    log_prob: float
    converged: bool
    evaluations: int
    covariance: np.ndarray | None = None
    optima: list = field(default_factory=list)  # (u, log_prob) of every polished optimum


@dataclass
class Mode:
    """One basin of the posterior: an optimum, its log-posterior and Laplace covariance.

    References
    ----------
    MacKay, D. J. C. (2003). *Information Theory, Inference, and Learning Algorithms*.
    Cambridge University Press, Ch. 27 (Laplace's method).
    """

    u: np.ndarray
    log_prob: float
    covariance: np.ndarray

    @property
    def log_mass(self) -> float:
        """log of the Laplace mass exp(log p)·√det Σ (up to a constant)."""
        return self.log_prob + 0.5 * np.linalg.slogdet(self.covariance)[1]


def _batched_objective(log_prob, step=1e-5):
    """−log p and its forward-difference gradients at points U (k, ndim), from one batched
    call of k·(ndim + 1) rows."""
    counter = {"n": 0}

    def objective(points):
        k, ndim = points.shape
        rows = (points[:, None, :] + step * np.vstack([np.zeros(ndim), np.eye(ndim)])).reshape(
            -1, ndim
        )
        values = log_prob(rows).reshape(k, ndim + 1)
        counter["n"] += rows.shape[0]
        f = np.where(np.isfinite(values), -values, _PENALTY)
        grad = (f[:, 1:] - f[:, :1]) / step
        return f[:, 0], np.where(np.isfinite(grad), grad, 0.0)

    return objective, counter


def find_map(log_prob, space, rng, settings, seeds=None) -> MapEstimate:
    """Maximise ``log_prob`` (of unbounded coordinates): the best ``starts`` of
    ``candidates`` prior draws run ``screen_iterations`` of L-BFGS-B each, and the best
    ``polish`` of those run on to convergence; the runs of each stage go in lockstep,
    their evaluations batched (:mod:`.batched_minimize`).

    Parameters
    ----------
    log_prob : callable
        Vectorised log-density of unbounded coordinates, (k, ndim) → (k,).
    space : ParameterSpace
        Draws candidates from the priors and maps them to unbounded coordinates.
    rng : numpy.random.Generator
    settings : SamplerSettings
        ``candidates``, ``starts``, ``screen_iterations`` and ``polish``.
    seeds : array (k, ndim), optional
        Unbounded points screened beside the prior draws' best ``starts`` (e.g. a nested
        model's optimum); rows with a non-finite coordinate are left out.

    Returns
    -------
    MapEstimate
        The best optimum, its Laplace covariance and every polished optimum.
    """
    draws = space.to_unbounded(space.sample_prior(rng, settings.candidates))
    draws = draws[np.all(np.isfinite(draws), axis=1)]
    scores = log_prob(draws)
    if not np.any(np.isfinite(scores)):
        raise ValueError("no prior draw has a finite posterior: check the priors and the data")
    order = np.argsort(-np.where(np.isfinite(scores), scores, -np.inf))
    objective, counter = _batched_objective(log_prob)
    best = MapEstimate(draws[order[0]], float(scores[order[0]]), False, draws.shape[0])
    starts = draws[order[: settings.starts]]
    if seeds is not None:
        seeds = np.atleast_2d(np.asarray(seeds, float))
        starts = np.vstack([starts, seeds[np.all(np.isfinite(seeds), axis=1)]])
    screened = minimize_in_lockstep(
        objective,
        starts,
        method="L-BFGS-B",
        options={"maxiter": settings.screen_iterations},
    )
    screened.sort(key=lambda result: result.fun)
    chosen = _spread_out(screened, settings.polish, POLISH_SPACING)
    polished = minimize_in_lockstep(
        objective, [result.x for result in chosen], method="L-BFGS-B", options={"maxiter": 400}
    )
    optima = []
    for start, result in zip(chosen, polished, strict=True):
        # a polish that ends worse than it began (a line search lost outside the support
        # ends ABNORMAL at the penalty) keeps its start
        result = result if result.fun <= start.fun else start
        value = -float(result.fun)
        if result.fun < _PENALTY:
            optima.append((result.x, value))
        if value > best.log_prob and result.fun < _PENALTY:
            best = MapEstimate(result.x, value, bool(result.success), 0)
    best.evaluations = draws.shape[0] + counter["n"]
    best.covariance = laplace_covariance(log_prob, best.u)
    best.optima = optima
    return best


def local_optimum(log_prob, u, iterations=400) -> float:
    """The highest ``log_prob`` an L-BFGS-B run from ``u`` reaches (batched gradients).

    Parameters
    ----------
    log_prob : callable
        Vectorised log-density of unbounded coordinates, (k, ndim) → (k,).
    u : array (ndim,)
    iterations : int

    Returns
    -------
    float
        The larger of ``log_prob(u)`` and the optimum's; −inf where neither is finite.
    """
    objective, _ = _batched_objective(log_prob)
    start = np.asarray(u, float)
    result = minimize_in_lockstep(
        objective, [start], method="L-BFGS-B", options={"maxiter": iterations}
    )[0]
    best = max(-float(result.fun), float(log_prob(start[None, :])[0]))
    return best if best > -_PENALTY else -np.inf


def _spread_out(results, count, spacing):
    """The first ``count`` of ``results`` (best first) that lie more than ``spacing``
    (unbounded units) from every one taken before them."""
    taken = []
    for result in results:
        if all(np.linalg.norm(result.x - other.x) > spacing for other in taken):
            taken.append(result)
        if len(taken) == count:
            break
    return taken


def distinct_modes(log_prob, estimate: MapEstimate, window, separation=3.0) -> list:
    """The MAP and the other optima in distinct basins.

    Parameters
    ----------
    log_prob : callable
        Vectorised log-density of unbounded coordinates.
    estimate : MapEstimate
    window : float
        Optima within this of the MAP's log-posterior are considered; 0 keeps the MAP only.
    separation : float
        Least Mahalanobis distance (under the Laplace covariance of each kept mode) from
        every mode kept before.

    Returns
    -------
    list of Mode
        Best first.
    """
    modes = [Mode(estimate.u, estimate.log_prob, estimate.covariance)]
    if window <= 0:
        return modes
    for u, value in sorted(estimate.optima, key=lambda optimum: -optimum[1]):
        if value < estimate.log_prob - window:
            break
        if all(_mahalanobis(u, mode) > separation for mode in modes):
            modes.append(Mode(u, value, laplace_covariance(log_prob, u)))
    return modes


def _mahalanobis(u, mode: Mode) -> float:
    d = np.asarray(u) - mode.u
    return float(np.sqrt(d @ np.linalg.solve(mode.covariance, d)))


def laplace_covariance(log_prob, u, step=1e-3, max_variance=4.0) -> np.ndarray:
    """Inverse of the negative Hessian of ``log_prob`` at ``u``, from one batched call.

    Parameters
    ----------
    log_prob : callable
        Vectorised log-density, (k, ndim) → (k,).
    u : array (ndim,)
    step : float
        Central-difference step (unbounded units).
    max_variance : float
        Largest variance of any direction (a prior spans a few units).

    Returns
    -------
    array (ndim, ndim)
        Positive definite: eigenvalues clipped; 1e-4·I where a difference is not finite.

    References
    ----------
    MacKay, D. J. C. (2003). *Information Theory, Inference, and Learning Algorithms*.
    Cambridge University Press, Ch. 27 (Laplace's method).
    Tierney, L. & Kadane, J. B. (1986). Accurate approximations for posterior moments and
    marginal densities. *J. Am. Statist. Assoc.* 81(393), 82–86.
    """
    n = u.size
    eye = step * np.eye(n)
    i, j = np.triu_indices(n, 1)
    rows = [u[None, :], u + eye, u - eye]
    rows += [u + eye[i] + eye[j], u + eye[i] - eye[j], u - eye[i] + eye[j], u - eye[i] - eye[j]]
    values = log_prob(np.vstack(rows))
    if not np.all(np.isfinite(values)):
        return np.eye(n) * 1e-4
    f0, plus, minus = values[0], values[1 : n + 1], values[n + 1 : 2 * n + 1]
    pp, pm, mp, mm = np.split(values[2 * n + 1 :], 4)
    hessian = np.empty((n, n))
    hessian[np.diag_indices(n)] = (plus - 2 * f0 + minus) / step**2
    hessian[i, j] = hessian[j, i] = (pp - pm - mp + mm) / (4 * step**2)
    eigenvalues, vectors = np.linalg.eigh(-hessian)
    variances = np.clip(1.0 / np.maximum(eigenvalues, 1e-12), 1e-10, max_variance)
    return (vectors * variances) @ vectors.T


def initial_ball(log_prob, modes, ball, n_walkers, rng):
    """Walkers drawn around the modes.

    Parameters
    ----------
    log_prob : callable
    modes : list of Mode
    ball : float
        Scale of each mode's Laplace covariance.
    n_walkers : int
    rng : numpy.random.Generator

    Returns
    -------
    array (n_walkers, ndim)
        Draws from N(mode, ball²·Σ), each mode's share in proportion to its Laplace mass
        (largest remainders), all with finite log-probability (the spread halves for
        redrawn walkers until all are finite).
    """
    log_mass = np.array([mode.log_mass for mode in modes])
    share = np.exp(log_mass - log_mass.max())
    share *= n_walkers / share.sum()
    counts = np.floor(share).astype(int)
    remainder = np.argsort(counts - share)[: n_walkers - counts.sum()]  # largest remainders
    counts[remainder] += 1
    owner = np.repeat(np.arange(len(modes)), counts)
    factors = [
        ball * np.linalg.cholesky(mode.covariance + 1e-12 * np.eye(mode.u.size)) for mode in modes
    ]
    centres = np.array([mode.u for mode in modes])[owner]

    def draw(rows, scale):
        noise = rng.standard_normal((rows.size, centres.shape[1]))
        spread = np.einsum("kij,kj->ki", np.array(factors)[owner[rows]], noise)
        return centres[rows] + scale * spread

    walkers, scale = draw(np.arange(n_walkers), 1.0), 1.0
    for _ in range(50):
        bad = ~np.isfinite(log_prob(walkers))
        if not bad.any():
            return walkers
        scale /= 2
        walkers[bad] = draw(np.flatnonzero(bad), scale)
    walkers[bad] = centres[bad]
    return walkers
