"""Invert one shot: the stages in order, from the observation to the posterior result.

:func:`invert_shot` builds the problem (:func:`.problem.build_problem`), simulates its
discrepancy covariance where the settings ask (:func:`.realisations.realisation_covariance`),
samples the posterior (:func:`.sampling.run_sampler`) and collects the result
(:func:`.collect.collect_result`). With ``cohorts="auto"`` it first chooses the stand model,
one height cohort or two, by the BIC of their MAPs (:func:`choose_cohorts`).
"""

from dataclasses import asdict, dataclass, field, replace

import emcee
import numpy as np
from threadpoolctl import threadpool_limits

from lidarinv.observe.observation import Observation

from .ambiguity import competing_grounds, pulse_width_m
from .ambiguity import describe as describe_competing
from .collect import collect_result
from .hidden_ground import hidden_ground_note
from .likelihood.covariance import covariance_obstacle
from .likelihood.discrepancy import SIMULATED
from .model.two_cohort import EMPTY_LOWER_STOREY
from .model_error import describe_floor, shot_floor
from .problem import InversionProblem, build_problem, fixed_discrepancy, problem_for_shot
from .realisations import realisation_covariance
from .result import InversionResult
from .sampling.sampler import run_sampler
from .sampling.start import find_map
from .settings import AUTO, InversionSettings
from .shot import Shot

#: Prior draws the two-cohort MAP search starts from, as a share of the sampler's
#: ``starts``, beside the one-cohort optimum (:func:`choose_cohorts`).
NESTED_SEARCH_STARTS = 0.5

#: BIC difference below which the two stand models are reported as undecided: a Bayes
#: factor under about e (Kass & Raftery 1995: "not worth more than a bare mention").
BIC_UNDECIDED = 2.0

#: Pulse widths (:func:`.ambiguity.pulse_width_m`) a shot's canopy return must span above
#: its ground for two storeys to be told apart from one: the ground's, a lower storey's and
#: an upper storey's returns each a pulse width apart (returns closer than that merge).
#: A shorter canopy keeps one cohort, whose understory already holds a low layer.
STOREYS_RESOLVED_PULSE_WIDTHS = 3.0


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
    """
    rng = np.random.default_rng() if rng is None else rng
    # Every product here is small (tens to hundreds of rows): a threaded BLAS gains little
    # on them and, sharing the cores with other work (batch workers, studies), stalls.
    with threadpool_limits(limits=1, user_api="blas"):
        return _invert(observation, settings, rng, progress, backend_path)


@dataclass(frozen=True)
class CohortChoice:
    """The stand model :func:`choose_cohorts` chose, and why.

    Attributes
    ----------
    chosen : int
        Height cohorts, 1 or 2.
    map_log_likelihood, bic : dict of int → float
        Per model searched, its MAP's log-likelihood and BIC.
    undecided : bool
        The BICs differ by less than :data:`BIC_UNDECIDED`.
    canopy_extent_m, pulse_width_m : float (m)
        The shot's signal start above its ground and its pulse's width, which decide
        whether two storeys are searched.
    """

    chosen: int
    map_log_likelihood: dict
    bic: dict
    undecided: bool
    canopy_extent_m: float
    pulse_width_m: float

    def describe(self) -> dict:
        """The choice as a dict (the result's ``diagnostics["cohorts"]``)."""
        return asdict(self)

    def note(self) -> str | None:
        """The result's flag where the data leave both stand models."""
        if not self.undecided:
            return None
        return (
            f"stand model undecided: BIC {self.bic[1]:.1f} with one cohort, {self.bic[2]:.1f} "
            "with two at their MAPs; the data leave both explanations"
        )


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
        η, the instrument model's error (:mod:`.model_error`), where it was sized.
    competing_grounds : list of float or None (m)
        The MAP's ground first, then other optima's, where they explain the shot with the
        ground elsewhere (:func:`.ambiguity.competing_grounds`).
    """

    problem: InversionProblem
    start: np.ndarray | None = None
    notes: list = field(default_factory=list)
    cohorts: CohortChoice | None = None
    discrepancy_seconds: float | None = None
    instrument_floor: float | None = None
    competing_grounds: list | None = None

    def diagnostics(self) -> dict:
        """The passes' outcomes for the result's diagnostics."""
        found = {
            "cohorts": None if self.cohorts is None else self.cohorts.describe(),
            "competing_grounds": self.competing_grounds,
            "instrument_floor": self.instrument_floor,
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
    settings = InversionSettings() if settings is None else settings
    if settings.cohorts == AUTO:
        problem, estimate, choice = choose_cohorts(observation, settings, rng)
        prepared = Preparation(problem, cohorts=choice)
        if choice.note() is not None:
            prepared.notes.append(choice.note())
    else:
        problem, estimate = build_problem(observation, settings), None
        prepared = Preparation(problem)
    settings = problem.settings
    hidden = hidden_ground_note(problem.shot)
    if hidden is not None:
        prepared.notes.append(hidden)
    pilot = problem.log_posterior  # the posterior the MAP search maximised
    likelihood = pilot.likelihood
    if settings.discrepancy_model == SIMULATED:
        obstacle = covariance_obstacle(problem.window, settings.shot_factor)
        if obstacle is None:
            covariance, simulation = realisation_covariance(
                problem.log_posterior, problem.instrument, rng, settings.realisations,
                settings.sampler, estimate,
            )  # fmt: skip
            estimate = simulation.estimate
            prepared.discrepancy_seconds = simulation.seconds
            least = settings.realisations.instrument_floor
            if least > 0:  # the instrument model's own error, on the diagonal
                unit = fixed_discrepancy(problem.shot, replace(settings, discrepancy=1.0))
                simulated_only = likelihood.with_fixed_discrepancy(covariance)
                floor = shot_floor(pilot, simulated_only, estimate, unit, least)
                covariance = covariance + floor**2 * np.diag(unit)
                prepared.instrument_floor = floor
                if floor > least:
                    prepared.notes.append(describe_floor(floor, least))
            problem = problem.with_likelihood(likelihood.with_fixed_discrepancy(covariance))
            if not estimate.converged:
                prepared.notes.append("MAP optimiser did not report convergence")
        else:
            prepared.notes.append(f"per-bin discrepancy used instead of realisations: {obstacle}")
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


def choose_cohorts(observation, settings, rng) -> tuple[InversionProblem, object, CohortChoice]:
    """The stand model, one height cohort or two, the shot's own evidence prefers.

    Each model's MAP is searched under the per-bin ``observed`` discrepancy, which the
    observation fixes and both models share, and the one with the lower Bayesian
    information criterion BIC = −2 ln L̂ + k ln n (k sampled parameters, n window bins;
    Schwarz 1978, an approximation to −2 ln of the evidence) is kept. The two-cohort
    model nests the one-cohort one (:data:`.model.two_cohort.EMPTY_LOWER_STOREY`), so its
    search starts from the one-cohort optimum as well as from half as many prior draws
    (:data:`NESTED_SEARCH_STARTS`): its optimum is then never far below the nested one's,
    and the search costs less. A canopy return that spans fewer than
    :data:`STOREYS_RESOLVED_PULSE_WIDTHS` pulse widths above the ground cannot show two
    storeys, and keeps one cohort without the second search.

    Parameters
    ----------
    observation : Observation
    settings : InversionSettings
        With ``cohorts="auto"``.
    rng : numpy.random.Generator

    Returns
    -------
    problem : InversionProblem
        The chosen model's problem (before any simulated discrepancy).
    estimate : MapEstimate
        Its MAP search, for the discrepancy's simulation.
    choice : CohortChoice
    """
    shot, candidates = Shot.from_observation(observation, settings), {}  # analysed once
    search, seeds = settings.sampler, None
    extent = float(shot.analysis.signal_start - shot.analysis.ground)
    width = pulse_width_m(shot.instrument.pulse)
    resolved = extent >= STOREYS_RESOLVED_PULSE_WIDTHS * width
    for cohorts in (1, 2) if resolved else (1,):
        problem = problem_for_shot(shot, replace(settings, cohorts=cohorts))
        post, space = problem.log_posterior, problem.space
        if cohorts == 2:
            one_cohort, one_cohort_map = candidates[1][:2]
            seeds = nested_start(one_cohort.space, one_cohort_map.u, space)
            if seeds is not None:
                search = replace(search, starts=max(1, round(search.starts * NESTED_SEARCH_STARTS)))
        estimate = find_map(lambda u, post=post: post(u)[:, 0], space, rng, search, seeds)
        x, _ = space.from_unbounded(estimate.u[None, :])
        log_likelihood = float(post.evaluate(x).log_likelihood[0])
        bic = -2.0 * log_likelihood + space.ndim * np.log(problem.window.samples.size)
        candidates[cohorts] = (problem, estimate, log_likelihood, bic)
    chosen = min(candidates, key=lambda k: candidates[k][3])
    bic = {k: c[3] for k, c in candidates.items()}
    choice = CohortChoice(
        chosen=chosen,
        map_log_likelihood={k: c[2] for k, c in candidates.items()},
        bic=bic,
        undecided=bool(resolved and abs(bic[2] - bic[1]) < BIC_UNDECIDED),
        canopy_extent_m=extent,
        pulse_width_m=width,
    )
    return candidates[chosen][0], candidates[chosen][1], choice


def nested_start(space1, u1, space2) -> np.ndarray | None:
    """The one-cohort point ``u1`` of ``space1`` in the two-cohort ``space2`` (unbounded
    coordinates): the same upper storey over an empty lower storey
    (:data:`.model.two_cohort.EMPTY_LOWER_STOREY`); None where ``space2`` frees a
    parameter neither gives, or the point lies outside its support."""
    values = {**space1.values(space1.from_unbounded(u1[None, :])[0]), **EMPTY_LOWER_STOREY}
    if any(name not in values for name in space2.names):
        return None
    x2 = np.array([[float(np.ravel(values[name])[0]) for name in space2.names]])
    u2 = space2.to_unbounded(x2)
    return u2 if np.all(np.isfinite(u2)) else None


def _invert(observation, settings, rng, progress, backend_path) -> InversionResult:
    prepared = prepare_problem(observation, settings, rng)
    problem = prepared.problem
    backend = None
    if backend_path is not None:
        name = f"shot_{observation.shot_id}"
        backend = emcee.backends.HDFBackend(str(backend_path), name=name)
    run = run_sampler(
        problem.log_posterior,
        problem.space,
        rng,
        problem.settings.sampler,
        backend=backend,
        progress=progress,
        start=prepared.start,
        coordinates=problem.space.signature(),
    )
    run.flags.extend(prepared.notes)
    if prepared.discrepancy_seconds is not None:
        run.seconds["discrepancy"] = prepared.discrepancy_seconds
    result = collect_result(problem, run, rng)
    result.diagnostics.update(prepared.diagnostics())
    return result
