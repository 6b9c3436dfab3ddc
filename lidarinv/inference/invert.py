"""Invert one shot: the stages in order, from the observation to the posterior result.

:func:`invert_shot` builds the problem (:func:`.problem.build_problem`), simulates its
discrepancy covariance where the settings ask (:func:`.realisations.realisation_covariance`),
samples the posterior (:func:`.sampling.run_sampler`) and collects the result
(:func:`.collect.collect_result`). With ``cohorts="auto"``, where one height cohort leaves
a misfit, it does so again with two and keeps the stand model the DIC prefers.
"""

from dataclasses import replace

import emcee
import numpy as np
from threadpoolctl import threadpool_limits

from lidarinv.observe.observation import Observation

from .collect import MISFIT_P_VALUE, collect_result
from .likelihood.covariance import covariance_obstacle
from .likelihood.discrepancy import SIMULATED
from .problem import InversionProblem, build_problem
from .realisations import realisation_covariance
from .result import InversionResult
from .sampling.sampler import run_sampler
from .settings import AUTO, InversionSettings

#: DIC difference below which the two stand models are reported as undecided (a
#: difference of a few units is within the DIC's own sampling noise).
DIC_UNDECIDED = 5.0


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


def prepare_problem(
    observation: Observation, settings: InversionSettings | None, rng
) -> tuple[InversionProblem, np.ndarray | None, dict]:
    """The posterior :func:`invert_shot` samples.

    Parameters
    ----------
    observation : Observation
    settings : InversionSettings or None
    rng : numpy.random.Generator

    Returns
    -------
    problem : InversionProblem
        :func:`.problem.build_problem`, with the simulated discrepancy covariance
        (:func:`.realisations.realisation_covariance`) where the settings ask for it and
        it can apply.
    start : array (ndim,) or None
        The sampler's start (unbounded): the pilot MAP, or None for the MAP search.
    report : dict
        ``seconds`` and ``map_converged`` of the simulation, if run, and ``notes`` (flags
        for the result).
    """
    problem = build_problem(observation, settings)
    start, report = None, {"notes": []}
    settings = problem.settings
    if settings.discrepancy_model == SIMULATED:
        obstacle = covariance_obstacle(problem.window, settings.shot_factor)
        if obstacle is None:
            covariance, start, simulated = realisation_covariance(
                problem.log_posterior, problem.instrument, rng, settings.realisations,
                settings.sampler,
            )  # fmt: skip
            problem = problem.with_fixed_discrepancy(covariance)
            report.update(simulated)
            if not simulated["map_converged"]:
                report["notes"].append("MAP optimiser did not report convergence")
        else:
            report["notes"].append(f"per-bin discrepancy used instead of realisations: {obstacle}")
    return problem, start, report


def _invert(observation, settings, rng, progress, backend_path) -> InversionResult:
    settings = InversionSettings() if settings is None else settings
    if settings.cohorts == AUTO:
        return _select_cohorts(observation, settings, rng, progress, backend_path)
    problem, start, report = prepare_problem(observation, settings, rng)
    return _sample(problem, start, report, rng, progress, backend_path, observation.shot_id)


def _sample(problem, start, report, rng, progress, backend_path, group) -> InversionResult:
    """Run the sampler on a prepared problem and collect its result."""
    backend = None
    if backend_path is not None:
        backend = emcee.backends.HDFBackend(str(backend_path), name=f"shot_{group}")
    run = run_sampler(
        problem.log_posterior,
        problem.space,
        rng,
        problem.settings.sampler,
        backend=backend,
        progress=progress,
        start=start,
        coordinates=problem.space.signature(),
    )
    run.flags.extend(report["notes"])
    if "seconds" in report:
        run.seconds["discrepancy"] = report["seconds"]
    return collect_result(problem, run, rng)


def _select_cohorts(observation, settings, rng, progress, backend_path) -> InversionResult:
    """One height cohort, and two where one leaves a misfit: the lower DIC is kept.

    The one-cohort run comes first. Where its posterior-predictive check finds a misfit
    (p below :data:`.collect.MISFIT_P_VALUE`) the shot is inverted again with a lower
    storey under the same likelihood (the one-cohort run's discrepancy, simulated once:
    DICs under two simulated covariances would compare the covariances too), and the
    stand model with the lower DIC is kept. The result records the DICs and the choice,
    and a flag where they differ by less than :data:`DIC_UNDECIDED` (the data leave both
    explanations).
    """
    group = observation.shot_id
    one, start, report = prepare_problem(observation, replace(settings, cohorts=1), rng)
    results = {1: _sample(one, start, report, rng, progress, backend_path, group)}
    p_value = results[1].diagnostics["predictive_p_value"]
    if p_value >= MISFIT_P_VALUE:
        result = results[1]
        result.diagnostics["cohorts"] = {"chosen": 1, "dic": {1: result.diagnostics["dic"]}}
        return result
    two = build_problem(observation, replace(settings, cohorts=2))
    shared = one.log_posterior.likelihood.fixed_discrepancy
    if shared is not None:
        two = two.with_fixed_discrepancy(shared)
    group = f"{observation.shot_id}_cohorts2"
    results[2] = _sample(two, None, {"notes": list(report["notes"])}, rng, progress,
                         backend_path, group)  # fmt: skip
    dic = {k: r.diagnostics["dic"] for k, r in results.items()}
    chosen = 2 if dic[2] < dic[1] else 1
    result = results[chosen]
    result.diagnostics["cohorts"] = {"chosen": chosen, "dic": dic}
    if abs(dic[2] - dic[1]) < DIC_UNDECIDED:
        result.flags.append(
            f"stand model undecided: DIC {dic[1]:.1f} with one cohort, {dic[2]:.1f} with two; "
            f"the other ({3 - chosen} cohort{'s' if chosen == 1 else ''}) fits nearly as well"
        )
    return result
