"""Invert one shot: the stages in order, from the observation to the posterior result.

:func:`invert_shot` builds the problem (:func:`.problem.build_problem`), simulates its
discrepancy covariance where the settings ask (:func:`.realisations.realisation_covariance`),
samples the posterior (:func:`.sampling.run_sampler`) and collects the result
(:func:`.collect.collect_result`). With ``cohorts="auto"`` it first chooses the stand model,
one height cohort or two, by the BIC of their MAPs (:func:`choose_cohorts`).
"""

from dataclasses import dataclass, field, replace

import emcee
import numpy as np
from threadpoolctl import threadpool_limits

from lidarinv.observe.observation import Observation

from .likelihood.covariance import covariance_obstacle
from .likelihood.discrepancy import FOLLOWING, SIMULATED_MODELS
from .likelihood.following import FollowingCovariance
from .passes.ambiguity import competing_grounds, pulse_width_m
from .passes.ambiguity import describe as describe_competing
from .passes.cohorts import CohortChoice, choose_cohorts
from .passes.hidden_ground import hidden_ground_note
from .passes.model_error import (
    MODEL_ERROR_CEILING,
    bounded_floor,
    describe_floor,
    describe_misfit,
    exceeds_ceiling,
    shot_floor,
)
from .passes.realisation_count import EnoughRealisations
from .passes.realisations import PER_BIN_NOTE, realisation_covariance
from .passes.recentre import recentre
from .problem import InversionProblem, build_problem, fixed_discrepancy
from .results.collect import collect_result
from .results.realisation_spread import (
    SPREAD_NOT_MEASURED_NOTE,
    DiscrepancyDraws,
    add_realisation_spread,
)
from .results.reported import reported_monitor
from .results.result import InversionResult
from .sampling.sampler import run_sampler
from .sampling.start import MAP_NOT_CONVERGED_NOTE
from .settings import AUTO, InversionSettings


def invert_shot(
    observation: Observation,
    settings: InversionSettings | None = None,
    *,
    rng: np.random.Generator | None = None,
    progress: bool = False,
    backend_path=None,
) -> InversionResult:
    """Sample the posterior of the stand parameters for one observed waveform.

    Parameters
    ----------
    observation : Observation
    settings : InversionSettings, optional
    rng : numpy.random.Generator, optional
        Source of all randomness (a fresh default generator if omitted).
    progress : bool
        Show a progress bar.
    backend_path : path, optional
        HDF5 file for the emcee chain (group ``shot_<id>``); a run found there is resumed.
        A ``realisations`` discrepancy is simulated again on resuming: pass a generator
        seeded as for the first run to continue under the same covariance.

    Returns
    -------
    InversionResult

    Raises
    ------
    ValueError
        If the shot has no usable signal or ground peak.

    References
    ----------
    Sun, G. & Ranson, K. J. (2000). Modeling lidar returns from forest canopies. *IEEE
    Trans. Geosci. Remote Sens.* 38(6), 2617–2626 (the waveform model the expected stand
    extends).
    Foreman-Mackey, D., Hogg, D. W., Lang, D. & Goodman, J. (2013). emcee: the MCMC hammer.
    *PASP* 125(925), 306–312.

    Examples
    --------
    A synthetic GEDI shot of a stand whose tallest trees reach 22 m, inverted with
    settings far too short to converge (a few seconds), which still find its top height:

    >>> import numpy as np
    >>> from lidarinv.examples import SYNTHETIC_SHOTS, synthetic_shot
    >>> from lidarinv.inference import InversionSettings, invert_shot
    >>> from lidarinv.inference.sampling import SamplerSettings
    >>> shot = synthetic_shot(
    ...     SYNTHETIC_SHOTS["gedi-mixed"], np.random.default_rng(1), explicit=False
    ... )
    >>> quick = SamplerSettings(
    ...     n_walkers=16, max_steps=200, check_every=100, candidates=256, starts=4,
    ...     polish=1, fit_steps=(100,),
    ... )
    >>> settings = InversionSettings(cohorts=1, discrepancy_model="observed", sampler=quick)
    >>> result = invert_shot(shot, settings, rng=np.random.default_rng(0))
    >>> shot.truth["top_height"]
    22.0
    >>> bool(abs(np.median(result.column("top_height")) - 22.0) < 2.0)
    True
    """
    rng = np.random.default_rng() if rng is None else rng
    with one_blas_thread():
        return _invert(observation, settings, rng, progress, backend_path)


def one_blas_thread():
    """BLAS held to one thread while a shot is inverted. Every product here is small (tens
    to hundreds of rows): a threaded BLAS gains little on them and, sharing the cores with
    other work (batch workers, studies), stalls; a triangular solve of 11 rows measured
    30 µs on one thread and 8 ms threaded beside two busy processes."""
    return threadpool_limits(limits=1, user_api="blas")


@dataclass
class Preparation:
    """What the passes before sampling made of a shot (:func:`prepare_problem`).

    Attributes
    ----------
    problem : InversionProblem
        The posterior to sample.
    start : array (ndim,), array (k, ndim) or None
        The sampler's start (unbounded): the pilot MAP, or it and the optima of competing
        grounds, or None for the MAP search.
    notes : list of str
        Flags for the result.
    cohorts : CohortChoice or None
        The stand model's choice, with ``cohorts="auto"``.
    discrepancy_seconds : float or None (s)
        The discrepancy simulation's wall time, where it ran.
    instrument_floor : float or None
        η, the instrument model's error (:mod:`.model_error`), where it was sized: at
        most its ceiling.
    model_error_needed : float or None
        The η the pilot's residuals need, without the ceiling (inf for more than any).
    competing_grounds : list of float or None (m)
        The MAP's ground first, then other optima's, where they explain the shot with the
        ground elsewhere (:func:`.ambiguity.competing_grounds`).
    discrepancy_draws : DiscrepancyDraws or None
        The realisations the discrepancy covariance was made from, where it was simulated.
    recentring : dict or None
        Under ``following``, the centre chosen and each candidate's optimum
        (:meth:`.recentre.Recentring.describe`).
    realisations : dict or None
        The realisations asked and simulated, and the spread the first of them left
        (:meth:`.realisation_count.EnoughRealisations.describe`), where simulated.
    """

    problem: InversionProblem
    start: np.ndarray | None = None
    notes: list = field(default_factory=list)
    cohorts: CohortChoice | None = None
    discrepancy_seconds: float | None = None
    instrument_floor: float | None = None
    model_error_needed: float | None = None
    competing_grounds: list | None = None
    discrepancy_draws: DiscrepancyDraws | None = None
    recentring: dict | None = None
    realisations: dict | None = None

    def diagnostics(self) -> dict:
        """The passes' outcomes for the result's diagnostics."""
        found = {
            "cohorts": None if self.cohorts is None else self.cohorts.describe(),
            "competing_grounds": self.competing_grounds,
            "instrument_floor": self.instrument_floor,
            "model_error_needed": self.model_error_needed,
            "model_error_ceiling": None if self.instrument_floor is None else MODEL_ERROR_CEILING,
            "recentring": self.recentring,
            "realisations": self.realisations,
        }
        return {key: value for key, value in found.items() if value is not None}


def prepare_problem(
    observation: Observation, settings: InversionSettings | None, rng
) -> Preparation:
    """The posterior :func:`invert_shot` samples, and the passes' outcomes before it.

    Parameters
    ----------
    observation : Observation
    settings : InversionSettings or None
    rng : numpy.random.Generator

    Returns
    -------
    Preparation
        :func:`.problem.build_problem` (with ``cohorts="auto"``, the chosen model,
        :func:`choose_cohorts`), with the simulated discrepancy covariance
        (:func:`.realisations.realisation_covariance`) where the settings ask for it and
        it can apply, the instrument model's error sized by the pilot's residuals
        (:func:`.model_error.shot_floor`), and the sampler's start.
    """
    with one_blas_thread():
        return _prepare(observation, settings, rng)


def following_covariance(pilot, simulation, settings, diagonal, likelihood):
    """The covariance that follows each row's stand (:mod:`.likelihood.following`), scaled
    against the model waveform of the MAP the realisations were simulated about
    (:func:`.recentre.recentre`)."""
    x, _ = pilot.space.from_unbounded(np.atleast_2d(simulation.estimate.u))
    signal = pilot.evaluate(x, keep_signal=True).signal[0]
    return FollowingCovariance.of(
        simulation.residuals, settings.realisations.shrinkage, signal, diagonal,
        likelihood.whitening,
    )  # fmt: skip


def _prepare(observation, settings, rng) -> Preparation:
    settings = InversionSettings() if settings is None else settings
    if settings.cohorts == AUTO:
        problem, estimate, choice = choose_cohorts(observation, settings, rng)
        prepared = Preparation(problem, cohorts=choice)
        if choice.note() is not None:
            prepared.notes.append(choice.note())
    else:
        problem, estimate = build_problem(observation, settings), None
        prepared = Preparation(problem)
    realisations = problem.settings.realisations.for_cohorts(problem.settings.cohorts)
    if realisations != problem.settings.realisations:  # the result records the count used
        problem = replace(problem, settings=replace(problem.settings, realisations=realisations))
    settings = problem.settings
    hidden = hidden_ground_note(problem.shot)
    if hidden is not None:
        prepared.notes.append(hidden)
    pilot = problem.log_posterior  # the posterior the MAP search maximised
    likelihood = pilot.likelihood
    if settings.discrepancy_model in SIMULATED_MODELS:
        obstacle = covariance_obstacle(problem.window, settings.shot_factor)
        if obstacle is None:
            least = settings.realisations.instrument_floor
            unit = fixed_discrepancy(problem.shot, replace(settings, discrepancy=1.0))
            enough = EnoughRealisations(pilot, settings.realisations, least**2 * unit, rng)
            covariance, simulation = realisation_covariance(
                problem.log_posterior, problem.instrument, rng, settings.realisations,
                settings.sampler, estimate, enough,
            )  # fmt: skip
            estimate = simulation.estimate
            prepared.discrepancy_seconds = simulation.seconds
            prepared.realisations = enough.describe(simulation.residuals.shape[0])
            diagonal = np.zeros(covariance.shape[0])
            if least > 0:  # the instrument model's own error, on the diagonal
                simulated_only = likelihood.with_fixed_discrepancy(covariance)
                needed = shot_floor(pilot, simulated_only, estimate, unit, least)
                floor = bounded_floor(needed, least)
                diagonal = floor**2 * unit
                covariance = covariance + np.diag(diagonal)
                prepared.instrument_floor, prepared.model_error_needed = floor, needed
                if floor > least:
                    prepared.notes.append(describe_floor(floor, least))
                if exceeds_ceiling(needed, least):
                    prepared.notes.append(describe_misfit(needed))
            simulated = likelihood.with_fixed_discrepancy(covariance)
            if settings.discrepancy_model == FOLLOWING:  # the centre its covariance rates best
                fixed = problem.with_likelihood(simulated).log_posterior
                recentring = recentre(
                    fixed, problem.instrument, rng, settings.realisations, settings.sampler,
                    simulation, diagonal,
                )  # fmt: skip
                simulation = recentring.simulation
                prepared.discrepancy_seconds = simulation.seconds
                prepared.recentring = recentring.describe()
                if recentring.chosen == "refound":  # searched under the fixed covariance
                    estimate, pilot = simulation.estimate, fixed
                simulated = simulated.with_following(
                    following_covariance(fixed, simulation, settings, diagonal, simulated)
                )
            problem = problem.with_likelihood(simulated)
            prepared.discrepancy_draws = DiscrepancyDraws(
                simulation.residuals, settings.realisations.shrinkage, diagonal
            )
            if not estimate.converged:
                prepared.notes.append(MAP_NOT_CONVERGED_NOTE)
        else:
            prepared.notes.append(f"{PER_BIN_NOTE}: {obstacle}")
    prepared.problem = problem
    if estimate is not None:  # the pilot's MAP, not searched twice, and its rivals
        kept = competing_grounds(
            lambda u: pilot(u)[:, 0], estimate, problem.space,
            pulse_width_m(problem.instrument.pulse),
        )  # fmt: skip
        prepared.start = estimate.u
        if len(kept) > 1:
            prepared.start = np.array([mode.u for mode, _ in kept])
            prepared.notes.append(describe_competing(kept))
            prepared.competing_grounds = [float(elevation) for _, elevation in kept]
    return prepared


def _invert(observation, settings, rng, progress, backend_path) -> InversionResult:
    prepared = _prepare(observation, settings, rng)
    backend = None
    if backend_path is not None:
        name = f"shot_{observation.shot_id}"
        backend = emcee.backends.HDFBackend(str(backend_path), name=name)
    return _sample(prepared, rng, None, progress, backend)


def sample_prepared(
    prepared: Preparation, rng, sampler=None, *, progress=False, backend=None
) -> InversionResult:
    """Sample a prepared posterior and collect its result: the second half of
    :func:`invert_shot`.

    Parameters
    ----------
    prepared : Preparation
        :func:`prepare_problem`'s outcome; it is not changed, so that independent runs
        (restarts with generators of their own) can sample the same posterior.
    rng : numpy.random.Generator
    sampler : SamplerSettings, optional
        In place of the problem's own sampler settings.
    progress : bool
    backend : emcee backend, optional

    Returns
    -------
    InversionResult
    """
    with one_blas_thread():
        return _sample(prepared, rng, sampler, progress, backend)


def _sample(prepared, rng, sampler, progress, backend) -> InversionResult:
    problem = prepared.problem
    if sampler is not None:  # the result records the settings it was sampled with
        problem = replace(problem, settings=replace(problem.settings, sampler=sampler))
    run = run_sampler(
        problem.log_posterior,
        problem.space,
        rng,
        problem.settings.sampler,
        backend=backend,
        progress=progress,
        start=prepared.start,
        coordinates=problem.space.signature(),
        monitor=reported_monitor(problem.space, problem.log_posterior.blob_names),
    )
    run.flags.extend(prepared.notes)
    if prepared.discrepancy_seconds is not None:
        run.seconds["discrepancy"] = prepared.discrepancy_seconds
    result = collect_result(problem, run, rng)
    result.diagnostics.update(prepared.diagnostics())
    resamples = problem.settings.realisations.resamples
    if prepared.discrepancy_draws is not None and resamples:
        try:  # a diagnostic: the samples drawn are kept whatever it meets
            add_realisation_spread(result, problem, prepared.discrepancy_draws, rng, resamples)
        except (ValueError, np.linalg.LinAlgError) as error:
            result.flags.append(f"{SPREAD_NOT_MEASURED_NOTE}: {error}")
    return result
