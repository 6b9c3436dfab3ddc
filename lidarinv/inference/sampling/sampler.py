"""MAP initialisation and the emcee run with an autocorrelation-time stopping rule."""

import time
from dataclasses import dataclass, field

import emcee
import numpy as np
from tqdm.auto import tqdm

from .adaptation import fit_moves, record_fit, refit_on_resume, worth_refitting
from .chains import BatchedSampler, sample_in_chunks
from .lockstep import minimize_in_lockstep
from .moves import MOVES

#: Large finite objective for the optimiser where the log-density is −inf.
_PENALTY = 1e12

#: Screened starts closer than this (unbounded units, where a prior spans about ±3) to a
#: better one are not polished: they would most likely end in the same optimum.
POLISH_SPACING = 0.25


@dataclass(frozen=True)
class SamplerSettings:
    """Settings of the ensemble sampler.

    Parameters
    ----------
    n_walkers : int
        Walkers (raised to 2·ndim + 2 if smaller). The ``ensemble-t`` move fits each
        half's proposal to the other half, so it gains from more walkers than DE does:
        64 rather than 32 (README, "Sampling").
    max_steps : int
        Cap on steps; a run that hits it unconverged is flagged.
    check_every : int
        Steps between convergence checks, at least (100: with τ of a few tens, 50 τ is
        soon reached, and sparser checks overshoot it).
    check_growth : float
        Steps between checks as a fraction of the chain so far, when that is more than
        ``check_every`` (each check costs time in proportion to the chain's length, so
        checks grow sparser as it grows: the total stays in proportion to the chain).
    tau_multiple : float
        The chain must be at least this many integrated autocorrelation times long.
    tau_tolerance : float
        Largest relative change of τ between checks for τ to count as stable.
    burn_taus : float
        Burn-in discarded before τ is estimated and from the results: this many times the
        previous estimate of the largest τ, and never more than a third of the chain.
    tau_resolution : int
        Each check estimates τ on the chain thinned by the previous estimate of the
        smallest τ over this (emcee's ``thin``; τ comes back in steps). Steps a tenth of
        τ apart carry the same information: on a 16 000-step GEDI chain the estimates
        agree within 0.3 % at 1/25 of the cost (65 ms instead of 1.6 s a check).
    candidates : int
        Prior draws scored to pick the optimiser's starts.
    starts : int
        Optimiser starts (the best candidates), each run for ``screen_iterations``.
    screen_iterations : int
        L-BFGS iterations of each start before the best are polished.
    polish : int
        Screened starts, the best ones at least :data:`POLISH_SPACING` apart, run on to
        convergence. The best few of many
        prior draws often share one basin, and a wrong basin is one the ensemble never
        leaves: with 512 draws and 4 starts, 7 of 100 inverse-crime recovery shots ended
        more than 5 below the true parameters' log-posterior; with these defaults, 3.
    ball : float
        Scale of the initial balls: walkers start from N(mode, ball²·Σ) with Σ the Laplace
        covariance at the mode.
    mode_window : float
        Polished optima within this much of the best log-posterior, and in distinct
        basins, each start some walkers (in proportion to their Laplace mass
        exp(log p)·√det Σ); 0 (the default) starts every walker around the MAP. Walkers
        then cross between basins only by rare DE jumps, so long runs seldom converge:
        one GEDI shot started in 3 basins reached τ ≈ 1000 by 20 000 steps, against 205
        (converged) from one. On the recovery study (195 explicit stands, 2500 steps) a
        window of 5 started 43 % of the shots in several basins and left coverage and
        errors unchanged within noise (README, "Sampling").
    moves : tuple of (str, float)
        Move mixture: names from :data:`MOVES` and their weights. DE moves along the
        ensemble's differences; ``ensemble-t`` (:mod:`.moves`) draws independent
        proposals from a Student t fitted to the other half of the ensemble, nearly fresh
        draws where the posterior is close to Gaussian in the sampler's coordinates. On
        the speed study's six 10-free GEDI shots the five that converge took 15–25 s
        (largest τ 53–110) with 32 walkers and DE/snooker/stretch 0.7/0.1/0.2, and
        10–24 s (τ 25–85) with 64 walkers and DE/ensemble-t 0.5/0.5 (README, "Speed").
        ``chain-t`` draws them from a t fitted to the chain's own steps (thousands of
        points, not 32), at the ``fit_steps``; adding it (0.4/0.3/0.3) cut the median
        largest τ from 39 to 30 steps and the median run from 2356 to 2045 steps on 36
        runs of 12 shots (README, "Sampling").
    fit_steps : tuple of int
        Steps at which the ``chain-t`` move is fitted to the second half of the chain so
        far. The first is always made; each later one only while
        :func:`.adaptation.worth_refitting`. The steps before the last fit are burn-in: from then
        on the proposal is fixed and the chain an exact MCMC chain.
    fit_fraction : float
        A later fit at step f is made only if the run, at ``tau_multiple`` times the
        latest τ and at most ``max_steps``, is expected to last at least f /
        ``fit_fraction`` steps: an easy shot (τ ≈ 20) stops fitting at step 200, a slow
        one (τ ≈ 200) refits until its t spans the posterior's tails, at step 1600 (at
        400 under a cap of 2500 steps).
    """

    n_walkers: int = 64
    max_steps: int = 20_000
    check_every: int = 100
    check_growth: float = 0.1
    tau_multiple: float = 50.0
    tau_tolerance: float = 0.05
    burn_taus: float = 5.0
    tau_resolution: int = 10
    candidates: int = 4096
    starts: int = 32
    screen_iterations: int = 30
    polish: int = 3
    ball: float = 1.0
    mode_window: float = 0.0
    moves: tuple = (("de", 0.4), ("ensemble-t", 0.3), ("chain-t", 0.3))
    fit_steps: tuple = (100, 200, 400, 800, 1600, 3200)
    fit_fraction: float = 0.25


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
    """One basin of the posterior: an optimum, its log-posterior and Laplace covariance."""

    u: np.ndarray
    log_prob: float
    covariance: np.ndarray

    @property
    def log_mass(self) -> float:
        """log of the Laplace mass exp(log p)·√det Σ (up to a constant)."""
        return self.log_prob + 0.5 * np.linalg.slogdet(self.covariance)[1]


@dataclass
class SamplerRun:
    """Outcome of :func:`run_sampler` (chain arrays exclude nothing: burn-in is ``burn``)."""

    chain: np.ndarray  # (steps, walkers, ndim), unbounded coordinates
    log_prob: np.ndarray  # (steps, walkers)
    blobs: np.ndarray  # (steps, walkers, n_blobs)
    tau: np.ndarray
    tau_history: list
    acceptance: np.ndarray
    converged: bool
    burn: int
    thin: int
    flags: list = field(default_factory=list)
    start_modes: int = 1  # basins the walkers started in (0 for a resumed chain)
    seconds: dict = field(default_factory=dict)  # "start" (MAP search, ball), "sampling"


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


def find_map(log_prob, space, rng, settings: SamplerSettings) -> MapEstimate:
    """Maximise ``log_prob`` (of unbounded coordinates): the best ``starts`` of
    ``candidates`` prior draws run ``screen_iterations`` of L-BFGS-B each, and the best
    ``polish`` of those run on to convergence; the runs of each stage go in lockstep,
    their evaluations batched (:mod:`.lockstep`)."""
    draws = space.to_unbounded(space.sample_prior(rng, settings.candidates))
    draws = draws[np.all(np.isfinite(draws), axis=1)]
    scores = log_prob(draws)
    if not np.any(np.isfinite(scores)):
        raise ValueError("no prior draw has a finite posterior: check the priors and the data")
    order = np.argsort(-np.where(np.isfinite(scores), scores, -np.inf))
    objective, counter = _batched_objective(log_prob)
    best = MapEstimate(draws[order[0]], float(scores[order[0]]), False, draws.shape[0])
    screened = minimize_in_lockstep(
        objective,
        draws[order[: settings.starts]],
        method="L-BFGS-B",
        options={"maxiter": settings.screen_iterations},
    )
    screened.sort(key=lambda result: result.fun)
    starts = [result.x for result in _spread_out(screened, settings.polish, POLISH_SPACING)]
    polished = minimize_in_lockstep(objective, starts, method="L-BFGS-B", options={"maxiter": 400})
    optima = []
    for result in polished:
        value = -float(result.fun)
        if result.fun < _PENALTY:
            optima.append((result.x, value))
        if value > best.log_prob and result.fun < _PENALTY:
            best = MapEstimate(result.x, value, bool(result.success), 0)
    best.evaluations = draws.shape[0] + counter["n"]
    best.covariance = laplace_covariance(log_prob, best.u)
    best.optima = optima
    return best


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
    """The MAP and the other optima of ``estimate`` within ``window`` of its log-posterior
    that lie in distinct basins: more than ``separation`` (Mahalanobis, under the Laplace
    covariance of each kept mode) from every mode kept before them; best first."""
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
    """Inverse of the negative Hessian of ``log_prob`` at ``u`` (one batched call).

    Central differences; eigenvalues are clipped so that the result is positive definite
    and no direction is wider than ``max_variance`` (unbounded units, where a prior spans
    a few units).
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


def _check_coordinates(backend, coordinates, resume):
    """Refuse to resume a chain sampled in other coordinates; label a new one."""
    with backend.open("a") as handle:
        group = handle[backend.name]
        stored = group.attrs.get("lidarinv_coordinates")
        if resume and stored != coordinates:
            raise ValueError(
                f"{backend.filename} [{backend.name}] holds a chain sampled in other "
                f"coordinates ({stored or 'unlabelled'}), not {coordinates}: "
                "write to a new file or group"
            )
        group.attrs["lidarinv_coordinates"] = coordinates


def burn_in(n_steps, tau, burn_taus, floor=0) -> int:
    """Steps to discard: ``burn_taus`` times the largest finite τ, at most a third of the
    chain (a third while τ is unknown), and never fewer than ``floor`` (the steps before
    the moves last adapted)."""
    third = n_steps // 3
    if not np.all(np.isfinite(tau)):
        return max(floor, third)
    return max(floor, min(third, int(np.ceil(burn_taus * np.max(tau)))))


def _following_check(iteration, settings: SamplerSettings) -> int:
    """The step of the convergence check after one at ``iteration``."""
    return iteration + max(settings.check_every, int(settings.check_growth * iteration))


def _may_converge(iteration, tau, settings: SamplerSettings, floor=0) -> bool:
    """Whether a check at ``iteration`` could end the run, the previous check having
    estimated ``tau``. It cannot where the chain after burn-in is no longer than
    tau_multiple·max(τ)/(1 + tau_tolerance): a new τ short enough for that chain would
    differ from the previous one by more than the tolerance. A check is skipped only where
    the one after it could not end the run either, so the check before the first that
    could is still made; skipping spares their cost (20–50 ms each on a GEDI shot, a tenth
    of the sampling time in the first thousand steps)."""
    if not np.all(np.isfinite(tau)):
        return True
    kept = iteration - burn_in(iteration, tau, settings.burn_taus, floor)
    return kept > settings.tau_multiple * np.max(tau) / (1.0 + settings.tau_tolerance)


def initial_ball(log_prob, modes, ball, n_walkers, rng):
    """Walkers drawn from N(mode, ball²·Σ), each mode's share in proportion to its
    Laplace mass (largest remainders), with finite log-probability (the spread halves for
    redrawn walkers until all are finite)."""
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


def run_sampler(
    log_posterior,
    space,
    rng,
    settings: SamplerSettings | None = None,
    backend=None,
    progress=False,
    start=None,
    coordinates=None,
) -> SamplerRun:
    """Sample ``log_posterior`` (unbounded coordinates, emcee blob convention) to convergence.

    Parameters
    ----------
    log_posterior : callable
        Vectorised (n, ndim) → (n, 1 + n_blobs), e.g. :class:`.posterior.LogPosterior`.
    space : ParameterSpace
    rng : numpy.random.Generator
    settings : SamplerSettings
    backend : emcee.backends.Backend, optional
        E.g. an ``HDFBackend``; a backend that already holds steps is resumed.
    progress : bool
        Show a progress bar.
    start : array (ndim,), optional
        Centre of the initial ball (unbounded); default the MAP estimate.
    coordinates : str, optional
        What the sampled coordinates are (see :meth:`.parameters.ParameterSpace.signature`);
        stored with an HDF5 backend's chain, and a chain stored under another is not
        resumed.
    """
    s = SamplerSettings() if settings is None else settings
    ndim = space.ndim
    n_walkers = max(s.n_walkers, 2 * ndim + 2)
    if n_walkers % 2:
        n_walkers += 1
    unknown = sorted({name for name, _ in s.moves} - set(MOVES))
    if unknown:
        raise ValueError(f"unknown move(s) {unknown}; known: {sorted(MOVES)}")
    moves = [(MOVES[name](), weight) for name, weight in s.moves]
    resume = backend is not None and backend.initialized and backend.iteration > 0
    if resume and backend.shape != (n_walkers, ndim):
        raise ValueError(
            f"the backend holds a chain of shape {backend.shape}, not {(n_walkers, ndim)}"
        )
    sampler = BatchedSampler(
        n_walkers, ndim, log_posterior, moves=moves, backend=backend, vectorize=True
    )
    if coordinates is not None and isinstance(backend, emcee.backends.HDFBackend):
        _check_coordinates(backend, coordinates, resume)
    log_prob = lambda u: log_posterior(u)[:, 0]  # noqa: E731
    flags, modes = [], []
    clock = time.perf_counter()
    if resume:
        state = backend.get_last_sample()
    else:
        sampler.random_state = np.random.RandomState(int(rng.integers(2**32))).get_state()
        if start is None:
            estimate = find_map(log_prob, space, rng, s)
            modes = distinct_modes(log_prob, estimate, s.mode_window)
            if not estimate.converged:
                flags.append("MAP optimiser did not report convergence")
        else:
            centre = np.asarray(start, float)
            modes = [Mode(centre, 0.0, laplace_covariance(log_prob, centre))]
        state = initial_ball(log_prob, modes, s.ball, n_walkers, rng)
    seconds = {"start": time.perf_counter() - clock}
    clock = time.perf_counter()
    history, tau, converged = [], np.full(ndim, np.inf), False
    bar = tqdm(total=s.max_steps, disable=not progress, desc="sampling", unit="step")
    bar.update(sampler.iteration)
    next_check = sampler.iteration + s.check_every
    adaptive = [move for move, _ in moves if hasattr(move, "fit")]
    # a fit discards the steps before it: none at the last step
    fits = sorted(step for step in s.fit_steps if sampler.iteration < step < s.max_steps)
    fits = fits if adaptive else []
    floor = refit_on_resume(sampler, adaptive, backend) if resume else 0
    for _ in sample_in_chunks(sampler, state, max(s.max_steps - sampler.iteration, 0)):
        if fits and sampler.iteration == fits[0]:
            fits.pop(0)
            wanted = floor == 0 or worth_refitting(
                sampler.iteration, tau, s.fit_fraction, s.tau_multiple, s.max_steps
            )
            if wanted and fit_moves(sampler, adaptive):
                floor = sampler.iteration  # an exact MCMC chain from here on
                record_fit(backend, floor)
        if sampler.iteration < min(next_check, s.max_steps):
            continue
        bar.update(sampler.iteration - bar.n)
        following = _following_check(sampler.iteration, s)
        if following < s.max_steps and not _may_converge(following, tau, s, floor):
            next_check = following  # neither this check nor the next can end the run
            continue
        discard = burn_in(sampler.iteration, tau, s.burn_taus, floor)
        if sampler.iteration - discard < s.check_every:  # too few steps since the last fit
            next_check = following
            continue
        thin = max(1, int(np.min(tau) / s.tau_resolution)) if np.all(np.isfinite(tau)) else 1
        # NaN where a walker has not moved in the window (a τ not yet known)
        with np.errstate(invalid="ignore", divide="ignore"):
            new_tau = sampler.get_autocorr_time(tol=0, quiet=True, discard=discard, thin=thin)
        history.append((sampler.iteration, new_tau.copy()))
        stable = np.all(np.abs(new_tau - tau) < s.tau_tolerance * new_tau)
        long_enough = np.all(sampler.iteration - discard > s.tau_multiple * new_tau)
        tau = new_tau
        bar.set_postfix(tau=f"{np.max(tau):.0f}")
        if long_enough and stable and np.all(np.isfinite(tau)):
            converged = True
            break
        next_check = _following_check(sampler.iteration, s)
    bar.close()
    seconds["sampling"] = time.perf_counter() - clock
    if not converged:
        flags.append(
            f"not converged: {sampler.iteration} steps < {s.tau_multiple:g} τ "
            f"(max τ = {np.max(tau):.0f}) or τ not stable"
        )
    acceptance = sampler.acceptance_fraction
    if np.any(acceptance < 0.05):
        flags.append(f"low acceptance in {int(np.sum(acceptance < 0.05))} walker(s)")
    tau_max = float(np.max(tau)) if np.all(np.isfinite(tau)) else sampler.iteration / 10
    burn = burn_in(sampler.iteration, tau, s.burn_taus, floor)
    thin = max(1, int(tau_max / 2))
    return SamplerRun(
        chain=sampler.get_chain(),
        log_prob=sampler.get_log_prob(),
        blobs=sampler.get_blobs(),
        tau=tau,
        tau_history=history,
        acceptance=acceptance,
        converged=converged,
        burn=burn,
        thin=thin,
        flags=flags,
        start_modes=len(modes),
        seconds=seconds,
    )
