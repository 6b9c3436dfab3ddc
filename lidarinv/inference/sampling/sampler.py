"""The emcee run: the ensemble from its start until the quantities it reports converge.

:func:`run_sampler` starts the walkers around the MAP (:mod:`.start`), or resumes a
stored chain, and samples in chunks (:mod:`.ensemble`) with a mixture of moves
(:mod:`.moves`) until the monitored quantities pass the stopping rule (:mod:`.stopping`:
bulk and tail ESS, rank-normalised split R̂ and a chain of at least a few τ, by ArviZ);
adaptive moves (:mod:`.moves.chain_t`) are fitted at a few early steps.
"""

import time
from dataclasses import dataclass, field

import emcee
import numpy as np
from tqdm.auto import tqdm

from .ensemble import BatchedSampler, sample_in_chunks
from .importance import ImportanceRun, ImportanceSettings, importance_sample
from .moves import MOVES
from .moves.chain_t import fit_moves, record_fit, refit_on_resume, worth_refitting
from .outcome import SamplerRun
from .start import (
    MAP_NOT_CONVERGED_NOTE,
    Mode,
    distinct_modes,
    find_map,
    initial_ball,
    laplace_covariance,
)
from .stopping import STOP_RULES, StopRule, coordinates_monitor, quantity_diagnostics

#: How the flag of a run that the step cap stopped begins.
NOT_CONVERGED_FLAG = "not converged at the step cap"
#: How the note of walkers that accepted fewer than 5 % of their moves begins.
LOW_ACCEPTANCE_NOTE = "low acceptance"


@dataclass(frozen=True)
class SamplerSettings:
    """Settings of the ensemble sampler.

    Parameters
    ----------
    n_walkers : int
        Walkers (raised to 2·ndim + 2 if smaller). A posterior call costs little more
        for 64 rows than for 32 (its cost is mostly per call), and τ in steps falls as
        walkers are added until the ``chain-t`` move, whose τ does not depend on them,
        sets it (``studies/inversion_speed.py --walkers`` compares counts).
    max_steps : int
        Cap on steps; a run that hits it unconverged is flagged with the quantities that
        failed the rule. Hard shots (tall two-storey forests) keep a τ of hundreds of
        steps however many walkers there are.
    stop_rule : str
        A name from :data:`.stopping.STOP_RULES`: ``"ess-rhat"`` (default), every
        monitored quantity with R̂ ≤ ``rhat_max``, bulk and tail ESS ≥ ``ess_min`` and a
        chain after burn-in ≥ ``min_taus`` of its τ (:class:`.stopping.StopRule`, whose
        docstring justifies the thresholds); ``"tau"``, the chain ``tau_multiple`` of
        emcee's τ of every sampled coordinate, τ stable within ``tau_tolerance``.
    rhat_max, ess_min, min_taus : float
        Thresholds of the ``"ess-rhat"`` rule (:class:`.stopping.StopRule`).
    quantile_mcse_max : float or None
        ``"ess-rhat"`` rule: the largest Monte Carlo error of each monitored quantity's
        5/50/95 % quantiles, in posterior sd (None: not asked).
    check_every : int
        Steps between convergence checks, at least (with τ of a few tens, 50 τ is soon
        reached, and sparser checks overshoot it).
    check_growth : float
        Steps between checks as a fraction of the chain so far, when that is more than
        ``check_every`` (each check costs time in proportion to the chain's length, so
        checks grow sparser as it grows: the total stays in proportion to the chain).
    tau_multiple : float
        ``"tau"`` rule: the chain must be at least this many integrated autocorrelation
        times long.
    tau_tolerance : float
        ``"tau"`` rule: largest relative change of τ between checks for τ to count as
        stable.
    burn_taus : float
        Burn-in discarded before τ is estimated and from the results: this many times the
        previous estimate of the largest τ (of the monitored quantities under
        ``"ess-rhat"``), and never more than a third of the chain.
    tau_resolution : int
        Each check estimates τ on the chain thinned by the previous estimate of the
        smallest τ over this (emcee's ``thin``; τ comes back in steps): steps a fifth of
        τ apart carry the same information, at a fraction of the cost (a chain of τ =
        30 steps gives τ within 1 % at a thinning of 1, 2 or 3). Under ``"ess-rhat"``
        the result keeps the chain thinned by twice the largest τ over this.
    candidates : int
        Prior draws scored to pick the optimiser's starts.
    starts : int
        Optimiser starts (the best candidates), each run for ``screen_iterations``.
    screen_iterations : int
        L-BFGS iterations of each start before the best are polished.
    polish : int
        Screened starts, the best ones at least :data:`.start.POLISH_SPACING` apart, run
        on to convergence: the best few of many prior draws often share one basin, and a
        wrong basin is one the ensemble never leaves.
    ball : float
        Scale of the initial balls: walkers start from N(mode, ball²·Σ) with Σ the Laplace
        covariance at the mode.
    mode_window : float
        Polished optima within this much of the best log-posterior, and in distinct
        basins, each start some walkers (in proportion to their Laplace mass
        exp(log p)·√det Σ); 0 (the default) starts every walker around the MAP. Walkers
        then cross between basins only by rare DE jumps, so long runs seldom converge.
    moves : tuple of (str, float)
        Move mixture: names from :data:`.moves.MOVES` and their weights. DE moves along
        the ensemble's differences; ``ensemble-t`` draws independent proposals from a
        Student t fitted to the other half of the ensemble, nearly fresh draws where the
        posterior is close to Gaussian in the sampler's coordinates; ``chain-t`` draws
        them from a t fitted to the chain's own steps at the ``fit_steps``
        (``studies/inversion_speed.py --moves`` compares mixtures).
    fit_steps : tuple of int
        Steps at which the ``chain-t`` move is fitted to the second half of the chain so
        far. The first is always made; each later one only while
        :func:`.moves.chain_t.worth_refitting`. Between fits the proposal is fixed, so
        each stretch of the chain is an exact MCMC chain; burn-in reaches at least the
        first fit.
    fit_fraction : float
        A later fit at step f is made only if the run, at ``tau_multiple`` times the
        latest τ and at most ``max_steps``, is expected to last at least f /
        ``fit_fraction`` steps: an easy shot stops fitting early, a slow one refits until
        its t spans the posterior's tails.
    importance : ImportanceSettings
        ``"ess-rhat"`` rule: at these steps the chain's second half so far is tried as an
        importance proposal (:mod:`.importance`); the run stops where the weighted draws
        pass, and goes on where they do not.
    """

    n_walkers: int = 128
    max_steps: int = 20_000
    stop_rule: str = "ess-rhat"
    rhat_max: float = StopRule.rhat_max
    ess_min: float = StopRule.ess_min
    min_taus: float = StopRule.min_taus
    quantile_mcse_max: float | None = StopRule.quantile_mcse_max
    check_every: int = 100
    check_growth: float = 0.1
    tau_multiple: float = 50.0
    tau_tolerance: float = 0.05
    burn_taus: float = 5.0
    tau_resolution: int = 5
    candidates: int = 4096
    starts: int = 32
    screen_iterations: int = 30
    polish: int = 3
    ball: float = 1.0
    mode_window: float = 0.0
    moves: tuple = (("de", 0.2), ("ensemble-t", 0.5), ("chain-t", 0.3))
    fit_steps: tuple = (100, 200, 400, 800, 1600, 3200)
    fit_fraction: float = 0.25
    importance: ImportanceSettings = field(default_factory=ImportanceSettings)


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
    """Steps to discard from the start of a chain.

    Parameters
    ----------
    n_steps : int
    tau : array (steps)
        The latest τ per coordinate.
    burn_taus : float
    floor : int
        Steps always discarded (those before the adaptive moves' first fit).

    Returns
    -------
    int
        ``burn_taus`` times the largest finite τ, at most a third of the chain (a third
        while τ is unknown), and never fewer than ``floor``.

    References
    ----------
    Sokal, A. (1997). Monte Carlo methods in statistical mechanics: foundations and new
    algorithms. In C. DeWitt-Morette, P. Cartier & A. Folacci (eds), *Functional
    Integration: Basics and Applications*, NATO ASI Series B 361, Springer, 131–192 (the
    initial transient, discarded in units of the autocorrelation time).
    """
    third = n_steps // 3
    if not np.all(np.isfinite(tau)):
        return max(floor, third)
    return max(floor, min(third, int(np.ceil(burn_taus * np.max(tau)))))


def _following_check(iteration, settings: SamplerSettings) -> int:
    """The step of the convergence check after one at ``iteration``."""
    return iteration + max(settings.check_every, int(settings.check_growth * iteration))


def may_converge(iteration, tau, settings: SamplerSettings, floor=0) -> bool:
    """Whether a check at ``iteration`` could end the run, the previous check having
    estimated ``tau``. It cannot where the chain after burn-in is no longer than
    tau_multiple·max(τ)/(1 + tau_tolerance): a new τ short enough for that chain would
    differ from the previous one by more than the tolerance. A check is skipped only where
    the one after it could not end the run either, so the check before the first that
    could is still made; skipping spares their cost."""
    if not np.all(np.isfinite(tau)):
        return True
    kept = iteration - burn_in(iteration, tau, settings.burn_taus, floor)
    return kept > settings.tau_multiple * np.max(tau) / (1.0 + settings.tau_tolerance)


def _show_target(bar, next_check, discard, tau, max_steps, multiple) -> None:
    """Count the bar towards the steps convergence needs by the latest τ (burn-in plus
    ``multiple`` τ, at least the next check), within the step cap, rather than towards
    the cap itself."""
    if bar.disable or not np.all(np.isfinite(tau)):
        return
    needed = discard + multiple * float(np.max(tau))
    bar.total = int(min(max_steps, max(needed, next_check)))
    bar.refresh()


def run_sampler(
    log_posterior,
    space,
    rng,
    settings: SamplerSettings | None = None,
    backend=None,
    progress=False,
    start=None,
    coordinates=None,
    monitor=None,
) -> SamplerRun:
    """Sample ``log_posterior`` (unbounded coordinates, emcee blob convention) to convergence.

    Parameters
    ----------
    log_posterior : callable
        Vectorised (n, ndim) → (n, 1 + n_blobs), e.g.
        :class:`lidarinv.inference.posterior.LogPosterior`.
    space : ParameterSpace
    rng : numpy.random.Generator
    settings : SamplerSettings
    backend : emcee.backends.Backend, optional
        E.g. an ``HDFBackend``; a backend that already holds steps is resumed.
    progress : bool
        Show a progress bar.
    start : array (ndim,) or (k, ndim), optional
        Centre of the initial ball (unbounded), or the optima of k basins to start walkers
        in (each in proportion to its Laplace mass under this posterior; none in a basin
        whose optimum has log-probability −inf); default the MAP estimate.
    coordinates : str, optional
        What the sampled coordinates are (see
        :meth:`lidarinv.inference.model.space.ParameterSpace.signature`); stored with an
        HDF5 backend's chain, and a chain stored under another is not resumed.
    monitor : callable, optional
        (chain (steps, walkers, ndim), blobs (steps, walkers, n_blobs) or None) → dict of
        name → array (steps, walkers): the quantities the stopping rule judges (e.g.
        :func:`lidarinv.inference.results.reported.reported_monitor`); default the sampled
        coordinates (:func:`.stopping.coordinates_monitor`).

    Returns
    -------
    SamplerRun
        The chain (unbounded coordinates), log-probabilities and blobs, τ per coordinate
        and the history of the monitored τ, acceptance, burn-in and thinning, flags, and
        the monitored quantities' ESS, R̂ and τ after burn-in.

    Raises
    ------
    ValueError
        For unknown moves or stopping rules, a stored chain of another shape or other
        coordinates.

    Notes
    -----
    ``"ess-rhat"`` (default): the run stops at the first check where every monitored
    quantity of the chain after burn-in has a rank-normalised split R̂ ≤ ``rhat_max``,
    bulk and tail ESS ≥ ``ess_min`` and a chain ≥ ``min_taus`` of its τ (Vehtari et al.
    2021; :mod:`.stopping`); ``converged`` is that check's verdict on the very samples
    the run returns after ``burn``. ``"tau"``: at the first check where the chain after
    burn-in is longer than ``tau_multiple``·τ for every coordinate and τ changed by less
    than ``tau_tolerance`` since the previous check (Foreman-Mackey et al. 2013; Sokal
    1997).

    References
    ----------
    Foreman-Mackey, D., Hogg, D. W., Lang, D. & Goodman, J. (2013). emcee: the MCMC
    hammer. *PASP* 125, 306–312.
    Goodman, J. & Weare, J. (2010). Ensemble samplers with affine invariance. *Commun.
    Appl. Math. Comput. Sci.* 5(1), 65–80 (the integrated autocorrelation time of an
    ensemble).
    Sokal, A. (1997). Monte Carlo methods in statistical mechanics: foundations and new
    algorithms. In C. DeWitt-Morette, P. Cartier & A. Folacci (eds), *Functional
    Integration: Basics and Applications*, NATO ASI Series B 361, Springer, 131–192.
    emcee documentation, "Autocorrelation analysis & convergence",
    https://emcee.readthedocs.io/en/stable/tutorials/autocorr/ (τ's estimate and the
    chain's length as a multiple of it).
    Vehtari, A., Gelman, A., Simpson, D., Carpenter, B. & Bürkner, P.-C. (2021).
    Rank-normalization, folding, and localization: an improved R̂ for assessing
    convergence of MCMC. *Bayesian Analysis* 16, 667–718.
    """
    s = SamplerSettings() if settings is None else settings
    ndim = space.ndim
    n_walkers = max(s.n_walkers, 2 * ndim + 2)
    if n_walkers % 2:
        n_walkers += 1
    unknown = sorted({name for name, _ in s.moves} - set(MOVES))
    if unknown:
        raise ValueError(f"unknown move(s) {unknown}; known: {sorted(MOVES)}")
    if s.stop_rule not in _CHECKS:
        raise ValueError(f"unknown stop_rule {s.stop_rule!r}; known: {sorted(_CHECKS)}")
    monitor = coordinates_monitor(space.names) if monitor is None else monitor
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
                flags.append(MAP_NOT_CONVERGED_NOTE)
        else:
            centres = np.atleast_2d(np.asarray(start, float))
            values = log_prob(centres)
            if not np.any(np.isfinite(values)):  # one start, however bad: its ball
                centres, values = centres[:1], np.zeros(1)
            modes = [
                Mode(centre, float(value), laplace_covariance(log_prob, centre))
                for centre, value in zip(centres, values)
                if np.isfinite(value)
            ]
        state = initial_ball(log_prob, modes, s.ball, n_walkers, rng)
    seconds = {"start": time.perf_counter() - clock}
    clock = time.perf_counter()
    history, converged, shortfalls = [], False, []
    tau = np.full(ndim if s.stop_rule == "tau" else 1, np.inf)
    bar = tqdm(total=s.max_steps, disable=not progress, desc="sampling", unit="step",
               dynamic_ncols=True)  # fmt: skip
    bar.update(sampler.iteration)
    next_check = sampler.iteration + s.check_every
    adaptive = [move for move, _ in moves if hasattr(move, "fit")]
    # no fit at the last step; burn-in reaches at least the first fit
    fits = sorted(step for step in s.fit_steps if sampler.iteration < step < s.max_steps)
    first_fit = min(s.fit_steps, default=0)
    floor = first_fit if adaptive and first_fit < s.max_steps else 0
    fits = fits if adaptive else []
    last_fit = refit_on_resume(sampler, adaptive, backend) if resume else 0
    multiple = _run_length_in_taus(s)
    importance, history_of_tries = None, []
    tries, importance_rng = _importance_steps(sampler.iteration, s), rng.spawn(1)[0]
    for _ in sample_in_chunks(sampler, state, max(s.max_steps - sampler.iteration, 0)):
        if fits and sampler.iteration == fits[0]:
            fits.pop(0)
            wanted = last_fit == 0 or worth_refitting(
                sampler.iteration, tau, s.fit_fraction, multiple, s.max_steps
            )
            if wanted and fit_moves(sampler, adaptive):
                last_fit = sampler.iteration  # the proposal is fixed until the next fit
                record_fit(backend, last_fit)
        if tries and sampler.iteration == tries[0]:
            tries.pop(0)
            tried = _try_importance(sampler, log_posterior, monitor, s, importance_rng)
            if tried is not None:
                history_of_tries.append((tried.step, tried.khat, tried.ess))
                if tried.passed:
                    importance, converged = tried, True
                    break
        if sampler.iteration < min(next_check, s.max_steps):
            continue
        bar.update(sampler.iteration - bar.n)
        following = _following_check(sampler.iteration, s)
        skippable = s.stop_rule == "tau" and not may_converge(following, tau, s, floor)
        if following < s.max_steps and skippable:
            next_check = following  # neither this check nor the next can end the run
            continue
        discard = burn_in(sampler.iteration, tau, s.burn_taus, floor)
        if sampler.iteration - discard < s.check_every:  # too few steps after burn-in
            next_check = following
            continue
        new_tau, converged, shortfalls, quantities = _CHECKS[s.stop_rule](
            sampler, discard, tau, s, monitor
        )
        history.append((sampler.iteration, new_tau.copy()))
        tau = new_tau
        bar.set_postfix(tau=f"{np.max(tau):.0f}")
        if converged:
            break
        next_check = _following_check(sampler.iteration, s)
        _show_target(bar, next_check, discard, tau, s.max_steps, multiple)
    if converged:  # the bar ends full, not at a fraction of the step cap
        bar.total = sampler.iteration
        done = f"τ {np.max(tau):.0f}"
        done = done if importance is None else f"importance draws, k̂ {importance.khat:.2f}"
        bar.set_postfix_str(f"converged, {done}", refresh=False)
        bar.update(sampler.iteration - bar.n)
    bar.close()
    seconds["sampling"] = time.perf_counter() - clock
    if importance is not None:  # the weighted draws stand for the posterior, not the chain
        burn, thin, quantities = sampler.iteration, 1, importance.quantities
        coordinate_tau = np.full(ndim, np.nan)
    elif s.stop_rule == "ess-rhat":
        # a passing check's burn-in: what it judged is reported
        burn = discard if converged else burn_in(sampler.iteration, tau, s.burn_taus, floor)
        # per coordinate, from ArviZ's bulk ESS as for the monitored quantities
        by_coordinate = coordinates_monitor(range(ndim))
        coordinates = _diagnostics(sampler, burn, tau, s, by_coordinate, bulk_only=True)
        coordinate_tau = np.array([coordinates[i]["tau"] for i in range(ndim)])
        if not converged:  # a passing check's diagnostics hold the quantiles' MCSE
            quantities = _diagnostics(sampler, burn, tau, s, monitor)
            shortfalls = _rule(s).shortfalls(quantities, sampler.iteration - burn)
        tau_max = float(np.max(tau)) if np.all(np.isfinite(tau)) else np.inf
        # 2/5 τ apart at the default resolution: 50 draws a walker at 20 τ
        thin = max(1, int(2 * tau_max / s.tau_resolution)) if np.isfinite(tau_max) else 1
    else:
        burn = burn_in(sampler.iteration, tau, s.burn_taus, floor)
        coordinate_tau = tau
        quantities = _diagnostics(sampler, burn, tau, s, monitor)
        tau_max = float(np.max(tau)) if np.all(np.isfinite(tau)) else sampler.iteration / 10
        thin = max(1, int(tau_max))
    if not converged:
        flags.append(_not_converged(sampler.iteration, s, tau, shortfalls, quantities))
    acceptance = sampler.acceptance_fraction
    if np.any(acceptance < 0.05):
        flags.append(f"{LOW_ACCEPTANCE_NOTE} in {int(np.sum(acceptance < 0.05))} walker(s)")
    return SamplerRun(
        chain=sampler.get_chain(),
        log_prob=sampler.get_log_prob(),
        blobs=sampler.get_blobs(),
        tau=coordinate_tau,
        tau_history=history,
        acceptance=acceptance,
        converged=converged,
        burn=burn,
        thin=thin,
        flags=flags,
        start_modes=len(modes),
        seconds=seconds,
        quantities=quantities,
        importance=importance,
        importance_tries=history_of_tries,
    )


def _importance_steps(iteration, s: SamplerSettings) -> list:
    """The steps after ``iteration`` at which the chain is tried as an importance proposal
    (none under the ``"tau"`` rule or with no draws asked)."""
    if s.stop_rule != "ess-rhat" or s.importance.draws == 0:
        return []
    return sorted(step for step in s.importance.steps if iteration < step < s.max_steps)


def _try_importance(sampler, log_posterior, monitor, s: SamplerSettings, rng) -> ImportanceRun:
    """:func:`.importance.importance_sample` with a t fitted to the chain's second half,
    making about as many draws from each t as the chain has made evaluations, at most
    (rounded up to whole batches)."""
    half = sampler.get_chain(discard=sampler.iteration // 2)
    return importance_sample(
        log_posterior, half.reshape(-1, half.shape[-1]), monitor, _rule(s), s.importance, rng,
        sampler.iteration, budget=sampler.iteration * half.shape[1],
    )  # fmt: skip


def _rule(s: SamplerSettings) -> StopRule:
    return StopRule(s.rhat_max, s.ess_min, s.min_taus, s.quantile_mcse_max)


def _run_length_in_taus(s: SamplerSettings) -> float:
    """The run's expected length in τ of what it monitors: its rule's multiple, with the
    burn-in under ``"ess-rhat"``."""
    return s.tau_multiple if s.stop_rule == "tau" else s.min_taus + s.burn_taus


def _diagnostics_thin(kept, tau, s: SamplerSettings) -> int:
    """Thinning of a check's chain: the smallest τ over ``tau_resolution`` (steps that
    close carry the same information), and at most about 500 draws a walker (a check
    then costs about a tenth of a second for seven quantities of 128 walkers)."""
    thin = max(1, int(np.min(tau) / s.tau_resolution)) if np.all(np.isfinite(tau)) else 1
    return max(thin, kept // 500)


def _monitored_draws(sampler, discard, tau, s: SamplerSettings, monitor):
    """The monitored quantities after ``discard`` steps, thinned for the diagnostics, and
    the thinning."""
    thin = _diagnostics_thin(sampler.iteration - discard, tau, s)
    chain = sampler.get_chain(discard=discard, thin=thin)
    blobs = sampler.get_blobs(discard=discard, thin=thin)
    return monitor(chain, blobs), thin


def _diagnostics(sampler, discard, tau, s: SamplerSettings, monitor, quantile_errors=True,
                 bulk_only=False):  # fmt: skip
    """:func:`.stopping.quantity_diagnostics` of the monitored quantities after
    ``discard`` steps."""
    draws, thin = _monitored_draws(sampler, discard, tau, s, monitor)
    return quantity_diagnostics(draws, thin, quantile_errors, bulk_only)


def _check_ess_rhat(sampler, discard, tau, s: SamplerSettings, monitor):
    """The ``"ess-rhat"`` check: the monitored quantities' τ, whether they pass, what
    fails, and their diagnostics. The bulk ESS comes first: where it already fails the
    rule (the usual check, before the chain is long enough) the tail ESS, R̂ and the
    quantiles' MCSE are not computed. Where they are, a passing check's diagnostics are
    the result's: those of the very draws it judged."""
    rule, kept = _rule(s), sampler.iteration - discard
    draws, thin = _monitored_draws(sampler, discard, tau, s, monitor)
    quantities = quantity_diagnostics(draws, thin, bulk_only=True)
    shortfalls = rule.bulk_shortfalls(quantities, kept)
    if not shortfalls:  # with the quantiles' MCSE, which a passing check's result reports
        quantities = quantity_diagnostics(draws, thin)
        shortfalls = rule.shortfalls(quantities, kept)
    new_tau = np.array([d["tau"] for d in quantities.values()])
    new_tau = np.where(np.isnan(new_tau), np.inf, new_tau)
    return new_tau, not shortfalls, shortfalls, quantities


def _check_tau(sampler, discard, tau, s: SamplerSettings, monitor):
    """The ``"tau"`` check: emcee's τ of every coordinate, ``tau_multiple`` of them
    after burn-in and stable within ``tau_tolerance`` since the previous check."""
    thin = max(1, int(np.min(tau) / s.tau_resolution)) if np.all(np.isfinite(tau)) else 1
    # NaN where a walker has not moved in the window (a τ not yet known)
    with np.errstate(invalid="ignore", divide="ignore"):
        new_tau = sampler.get_autocorr_time(tol=0, quiet=True, discard=discard, thin=thin)
    stable = np.all(np.abs(new_tau - tau) < s.tau_tolerance * new_tau)
    long_enough = np.all(sampler.iteration - discard > s.tau_multiple * new_tau)
    converged = bool(long_enough and stable and np.all(np.isfinite(new_tau)))
    return new_tau, converged, [], {}


#: The check of each stopping rule: (sampler, discard, τ, settings, monitor) → (τ,
#: converged, shortfalls, diagnostics of the monitored quantities).
_CHECKS = {"ess-rhat": _check_ess_rhat, "tau": _check_tau}
assert set(_CHECKS) == set(STOP_RULES)


def _not_converged(steps, s: SamplerSettings, tau, shortfalls, quantities) -> str:
    """The flag of a run stopped by the step cap: what failed, by how much, and how far
    the reported quantiles may be off (their largest Monte Carlo error)."""
    if s.stop_rule == "tau":
        return (
            f"not converged: {steps} steps < {s.tau_multiple:g} τ "
            f"(max τ = {np.max(tau):.0f}) or τ not stable"
        )
    failed = "; ".join(shortfalls) if shortfalls else "too few steps after burn-in to judge"
    errors = {k: d.get("quantile_mcse", np.nan) for k, d in quantities.items()}
    errors = {k: v for k, v in errors.items() if np.isfinite(v)}
    if errors:
        worst = max(errors, key=errors.get)
        failed += (
            f"; the reported 5/50/95 % quantiles' Monte Carlo error reaches "
            f"{errors[worst]:.2f} posterior sd ({worst})"
        )
    return f"{NOT_CONVERGED_FLAG} ({steps} steps): {failed}"
