"""Invert one shot: build the posterior, sample it, and collect the result."""

import emcee
import numpy as np
from threadpoolctl import threadpool_limits

from lidarinv.observe.observation import Observation

from .correlated import covariance_obstacle
from .discrepancy import SIMULATED
from .likelihood import model_moments
from .posterior import BLOB_NAMES, BLOB_UNITS
from .problem import InversionProblem, InversionSettings, build_problem
from .realisations import with_realisation_covariance
from .result import QUANTILES, InversionResult
from .sampling import SamplerRun, run_sampler
from .stand_mapping import TALLEST_STEM_RADIUS_SIGMAS

#: Posterior samples used for the predictive band and the crown-volume profile.
_BAND_SAMPLES = 400


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

    Raises
    ------
    ValueError
        If the shot has no usable signal or ground peak.
    """
    rng = np.random.default_rng() if rng is None else rng
    # Every product here is small (tens to hundreds of rows): a threaded BLAS gains little
    # on them and, sharing the cores with other work (batch workers, studies), stalls:
    # the MAP search of a GEDI shot took 5.0 s instead of 1.4 s beside one other process.
    with threadpool_limits(limits=1, user_api="blas"):
        return _invert(observation, settings, rng, progress, backend_path)


def prepare_problem(observation: Observation, settings: InversionSettings | None, rng):
    """The posterior :func:`invert_shot` samples: :func:`.problem.build_problem`, then the
    simulated discrepancy covariance (:mod:`.realisations`) where the settings ask for it
    and it can apply. Returns the problem, the sampler's start (unbounded; None for the
    MAP search) and a dict: ``seconds`` and ``map_converged`` of the simulation, if run,
    and ``notes`` (flags for the result)."""
    problem = build_problem(observation, settings)
    start, report = None, {"notes": []}
    if problem.settings.discrepancy_model == SIMULATED:
        obstacle = covariance_obstacle(problem.window, problem.settings.shot_factor)
        if obstacle is None:
            problem, start, simulated = with_realisation_covariance(
                problem, rng, problem.settings.realisations
            )
            report.update(simulated)
            if not simulated["map_converged"]:
                report["notes"].append("MAP optimiser did not report convergence")
        else:
            report["notes"].append(f"per-bin discrepancy used instead of realisations: {obstacle}")
    return problem, start, report


def _invert(observation, settings, rng, progress, backend_path) -> InversionResult:
    problem, start, report = prepare_problem(observation, settings, rng)
    backend = None
    if backend_path is not None:
        backend = emcee.backends.HDFBackend(str(backend_path), name=f"shot_{observation.shot_id}")
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


#: Derived quantity: the tallest stem within the footprint, a posterior-predictive draw.
FOOTPRINT_TOP = "footprint_top_height"


def footprint_top_height(problem: InversionProblem, x, density_per_ha, rng) -> np.ndarray:
    """Height (m) of the tallest stem within the footprint (its 1/e² radius, 2σf) per
    posterior sample: the stand's parameters fix the height distribution, and one
    footprint holds one Poisson draw of stems from it, whose tallest is drawn here.
    This, not ``top_height`` (the distribution's upper end), is what the waveform's
    canopy top and RH98-style metrics measure. Where the posterior conditions on the
    tallest stem, it is that latent stem's height."""
    values = problem.space.values(x)
    mapping = problem.log_posterior.mapping
    if mapping.conditioned:  # the latent stem itself, within the same disc
        return mapping.model_vectors(values)[1]["tallest_stem"]
    values["density_m2"] = np.asarray(density_per_ha) * 1e-4
    radius = TALLEST_STEM_RADIUS_SIGMAS * problem.instrument.footprint_sigma_m
    uniform = rng.uniform(size=x.shape[0])
    return mapping.tallest_in_area(values, np.pi * radius**2, uniform)


def replicate_observation(post, signal, values, rng) -> np.ndarray:
    """One replicated observation per posterior sample (n, bins), DN: the model mean
    b + a·W plus noise of the likelihood's per-bin variance (noise, shot noise and the
    model discrepancy), set to the floor or the digitiser maximum where the product
    would have set it. Quantiles over the rows are the posterior predictive bands."""
    if post.fixed_discrepancy is None:
        extra = (post.discrepancy * np.asarray(values["gain"])[:, None] * signal) ** 2
    elif post.fixed_discrepancy.ndim == 2:  # a covariance: its diagonal, per bin
        extra = np.diag(post.fixed_discrepancy)
    else:
        extra = post.fixed_discrepancy
    mean, variance = model_moments(
        signal,
        values["gain"],
        values["baseline"],
        values["noise_sigma"],
        post.shot_factor,
        extra,
    )
    draws = mean + np.sqrt(variance) * rng.standard_normal(mean.shape)
    data = post.data
    if data.censored.any() and np.isfinite(data.floor):
        draws = np.maximum(draws, data.floor)
    if np.isfinite(data.saturation):
        draws = np.minimum(draws, data.saturation)
    return draws


def _flat(array, run: SamplerRun):
    return array[run.burn :: run.thin].reshape(-1, *array.shape[2:])


def collect_result(problem: InversionProblem, run: SamplerRun, rng) -> InversionResult:
    """Posterior samples, derived quantities, bands and diagnostics of a finished run."""
    space, post = problem.space, problem.log_posterior
    u = _flat(run.chain, run)
    x, _ = space.from_unbounded(u)
    log_prob = _flat(run.log_prob, run)
    blobs = _flat(run.blobs, run)
    derived = {name: blobs[:, i] for i, name in enumerate(BLOB_NAMES)}
    derived[FOOTPRINT_TOP] = footprint_top_height(problem, x, derived["density"], rng)
    drawn = post.draw_marginalised(x, rng)  # e.g. the gain, from p(gain | θ, y)
    pick = rng.choice(x.shape[0], size=min(_BAND_SAMPLES, x.shape[0]), replace=False)
    terms = post.evaluate(x[pick], keep_signal=True)
    good = np.isfinite(terms.log_posterior)
    values = space.values(x[pick][good])
    values.update({name: draws[pick][good] for name, draws in drawn.items()})
    mean = model_moments(
        terms.signal[good], values["gain"], values["baseline"], values["noise_sigma"]
    )[0]
    predictive = np.percentile(mean, QUANTILES, axis=0)
    replicated = replicate_observation(post, terms.signal[good], values, rng)
    top = float(np.max(values["top_height"]))
    profile_heights = np.linspace(0.0, top, 60)
    profile = post.mapping.crown_volume_profile(values, profile_heights)
    n_kept = run.chain.shape[0] - run.burn
    ess = n_kept * run.chain.shape[1] / np.where(np.isfinite(run.tau), run.tau, np.inf)
    a = problem.analysis
    truth = {
        k: float(v)
        for k, v in problem.observation.truth.items()
        if np.ndim(v) == 0 and isinstance(v, (int, float, np.floating))
    }
    return InversionResult(
        shot_id=problem.observation.shot_id,
        parameter_names=(*space.names, *drawn),
        units={**{p.name: p.units for p in space.parameters}, **BLOB_UNITS, FOOTPRINT_TOP: "m"},
        samples=np.column_stack([x, *drawn.values()]),
        log_prob=log_prob,
        derived=derived,
        fixed={p.name: p.fixed for p in space.parameters if not p.free},
        diagnostics={
            "sampled": list(space.names),  # the coordinates of tau and ess
            "tau": run.tau,
            "acceptance": run.acceptance,
            "ess": ess,
            "n_steps": int(run.chain.shape[0]),
            "n_walkers": int(run.chain.shape[1]),
            "burn": run.burn,
            "thin": run.thin,
            "converged": run.converged,
            "map_log_prob": float(np.max(run.log_prob)),
            "start_modes": int(run.start_modes),
            "seconds": dict(run.seconds),
            "tau_history": [[int(i), t] for i, t in run.tau_history],
        },
        flags=list(run.flags),
        profile_heights=profile_heights,
        profile=np.percentile(profile, QUANTILES, axis=0),
        axis=problem.window.axis,
        observed=problem.window.samples,
        censored=problem.window.censored,
        predictive=predictive,
        replicated=np.percentile(replicated, QUANTILES, axis=0),
        saturated=problem.window.saturated,
        floor=problem.window.floor,
        saturation=problem.window.saturation,
        noise_floor=float(a.start_floor),
        priors=space.describe(),
        settings=problem.settings.describe(),
        truth=truth,
    )
