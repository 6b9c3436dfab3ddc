"""The stand model a shot's evidence prefers: one height cohort or two, by the BIC of
their MAPs (:func:`choose_cohorts`)."""

from dataclasses import asdict, dataclass, replace

import numpy as np

from ..model.tallest_stem import TALLEST_STEM, TALLEST_STEM_POSITION, disc_area
from ..model.two_cohort import EMPTY_LOWER_STOREY
from ..problem import InversionProblem, problem_for_shot
from ..sampling.start import find_map
from ..settings import AUTO
from ..shot import Shot
from .ambiguity import pulse_width_m

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

#: How the note of a shot that one and two storeys explain about as well begins.
UNDECIDED_NOTE = "stand model undecided"


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
            f"{UNDECIDED_NOTE}: BIC {self.bic[1]:.1f} with one cohort, {self.bic[2]:.1f} "
            "with two at their MAPs; the data leave both explanations"
        )


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
    storeys, and keeps one cohort without the second search. With ``tallest_stem="auto"``
    both models are weighed without the tallest-stem latents, and a chosen two-cohort
    model then gains them (:func:`with_latent_stem`).

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

    References
    ----------
    Schwarz, G. (1978). Estimating the dimension of a model. *Ann. Statist.* 6(2), 461–464.
    Kass, R. E. & Raftery, A. E. (1995). Bayes factors. *J. Am. Statist. Assoc.* 90(430),
    773–795.
    """
    shot, candidates = Shot.from_observation(observation, settings), {}  # analysed once
    asked, latent_after = settings, settings.tallest_stem == AUTO
    if latent_after:  # the storeys are weighed as one model each, the latents added after
        settings = replace(settings, tallest_stem=False)
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
    problem, estimate = candidates[chosen][:2]
    if latent_after and asked.latent_stem(chosen):
        problem, estimate = with_latent_stem(shot, problem, estimate, rng)
    return problem, estimate, choice


def with_latent_stem(shot: Shot, problem: InversionProblem, estimate, rng):
    """A problem's stand model conditioned on the footprint's tallest stem, and its MAP.

    The search starts from :func:`latent_start` beside half the sampler's prior draws
    (:data:`NESTED_SEARCH_STARTS`).

    Parameters
    ----------
    shot : Shot
    problem : InversionProblem
        Without the latents.
    estimate : MapEstimate
        Its MAP search.
    rng : numpy.random.Generator

    Returns
    -------
    problem : InversionProblem
        The same settings with ``tallest_stem=True``.
    estimate : MapEstimate
        Its MAP search.
    """
    latent = problem_for_shot(shot, replace(problem.settings, tallest_stem=True))
    post, search = latent.log_posterior, latent.settings.sampler
    seeds = latent_start(problem, estimate.u, latent.space, shot.instrument.footprint_sigma_m)
    if seeds is not None:
        search = replace(search, starts=max(1, round(search.starts * NESTED_SEARCH_STARTS)))
    return latent, find_map(lambda u: post(u)[:, 0], latent.space, rng, search, seeds)


def latent_start(problem: InversionProblem, u, space, footprint_sigma_m) -> np.ndarray | None:
    """The point ``u`` of a problem without the tallest-stem latents in a ``space`` with
    them: the same stand, its stem at the median of the stem's law given that stand (the
    tallest of a Poisson draw in the disc, :func:`.model.tallest_stem.disc_area`) and, where
    free, at the middle of its position's range.

    Parameters
    ----------
    problem : InversionProblem
    u : array (ndim,)
        Unbounded coordinates of ``problem.space``.
    space : ParameterSpace
        With the latents.
    footprint_sigma_m : float (m)

    Returns
    -------
    array (1, space.ndim) or None
        None where ``space`` frees a parameter neither gives or the point lies outside its
        support.
    """
    x, _ = problem.space.from_unbounded(np.asarray(u, float)[None, :])
    values = problem.space.values(x)
    mapping = problem.log_posterior.mapping
    density_m2 = mapping.model_vectors(values)[1]["density"] * 1e-4
    median = np.full(1, 0.5)
    stem = mapping.tallest_in_area(
        {**values, "density_m2": density_m2}, disc_area(footprint_sigma_m), median
    )
    return point_in(space, {**values, TALLEST_STEM: stem, TALLEST_STEM_POSITION: median})


def nested_start(space1, u1, space2) -> np.ndarray | None:
    """The one-cohort point ``u1`` of ``space1`` in the two-cohort ``space2`` (unbounded
    coordinates): the same upper storey over an empty lower storey
    (:data:`.model.two_cohort.EMPTY_LOWER_STOREY`); None where ``space2`` frees a
    parameter neither gives, or the point lies outside its support."""
    values = {**space1.values(space1.from_unbounded(u1[None, :])[0]), **EMPTY_LOWER_STOREY}
    return point_in(space2, values)


def point_in(space, values) -> np.ndarray | None:
    """One point of ``space`` in unbounded coordinates from parameter ``values`` (each a
    scalar or a one-row array); None where ``space`` frees a parameter ``values`` lacks,
    or the point lies outside its support."""
    if any(name not in values for name in space.names):
        return None
    x = np.array([[float(np.ravel(values[name])[0]) for name in space.names]])
    u = space.to_unbounded(x)
    return u if np.all(np.isfinite(u)) else None
