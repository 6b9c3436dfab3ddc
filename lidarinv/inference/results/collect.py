"""The results stage: a finished run's samples, derived quantities, bands and diagnostics
collected into an :class:`.result.InversionResult`."""

import numpy as np

from lidarinv.observe import processing_settings

from ..model.parameters import TALLEST_STEM
from ..model.tallest_stem import disc_area
from ..model.waveform import RH_LEVELS, relative_heights
from ..passes.ambiguity import describe_modes, ground_modes, pulse_width_m
from ..passes.realisations import footprint_cover
from ..posterior import BLOB_NAMES, BLOB_UNITS
from ..problem import InversionProblem
from ..sampling.sampler import SamplerRun
from .footprint import (
    FOOTPRINT_BARE,
    FOOTPRINT_NO_STEM,
    bare_ground_for,
    canopy_height_note,
    excess_sigmas,
    footprint_bare,
    footprint_no_stem,
    stand_rh98_note,
    unseen_top_note,
)
from .local_misfit import describe_local_misfit, local_misfit, return_width_bins
from .prior_learning import prior_learning, support_prior_draws
from .product_metrics import product_relative_heights
from .result import QUANTILES, InversionResult, seen_canopy_height

#: Posterior samples used for the predictive band and the crown-volume profile.
_BAND_SAMPLES = 400


#: Derived quantity: the tallest stem within the footprint, a posterior-predictive draw.
FOOTPRINT_TOP = "footprint_top_height"
#: Derived quantity: the footprint's own crown cover, where settings ask for its draws.
FOOTPRINT_COVER = "footprint_cover"


def footprint_top_height(problem: InversionProblem, x, density_per_ha, rng) -> np.ndarray:
    """The tallest stem within the footprint per posterior sample.

    Parameters
    ----------
    problem : InversionProblem
    x : array (n, ndim)
        Posterior samples (physical units).
    density_per_ha : array (n,) (stems/ha)
    rng : numpy.random.Generator

    Returns
    -------
    array (n,) (m)
        Height of the tallest stem within the footprint's 1/e² radius (2σf): one Poisson
        draw of stems from each sample's stand (:meth:`.model.stand.StandMapping.
        tallest_in_area`). This, not ``top_height`` (the distribution's upper end), is
        what the waveform's canopy top and RH98-style metrics measure. Where the
        posterior conditions on the tallest stem, it is that latent stem's height.
    """
    values = problem.space.values(x)
    mapping = problem.log_posterior.mapping
    if mapping.conditioned:  # the latent stem itself, within the same disc
        return mapping.model_vectors(values)[1]["tallest_stem"]
    values["density_m2"] = np.asarray(density_per_ha) * 1e-4
    area = disc_area(problem.instrument.footprint_sigma_m)
    uniform = rng.uniform(size=x.shape[0])
    return mapping.tallest_in_area(values, area, uniform)


#: Derived quantities: the RH of :data:`.model.waveform.RH_LEVELS` in the product's convention.
PRODUCT_RH = {f"{name}_product": level for name, level in RH_LEVELS.items()}
#: Derived quantities: the RH of the footprint's own noise-free waveform a·W + d, d the
#: discrepancy drawn given the data (:mod:`.likelihood.conditional`).
FOOTPRINT_RH = {f"{name}_footprint": level for name, level in RH_LEVELS.items()}
#: Posterior samples evaluated at once for :func:`sample_draws`.
_CHUNK = 1024


def sample_draws(problem: InversionProblem, x, rng) -> tuple[dict, dict, np.ndarray]:
    """The marginalised parameters' draws and the RH of every posterior sample in the
    product's convention and of the footprint's own waveform, from one evaluation of the
    samples (in chunks).

    Parameters
    ----------
    problem : InversionProblem
    x : array (n, ndim)
        Posterior samples (physical units).
    rng : numpy.random.Generator
        For the marginalised parameters' draws.

    Returns
    -------
    drawn : dict of name → array (n,)
        :meth:`.posterior.LogPosterior.draw_marginalised` (e.g. the gain from
        p(a | θ, y)); empty where nothing is marginalised.
    heights : dict of name → array (n,) (m)
        :data:`PRODUCT_RH`: each sample's expected recorded waveform b + a·W measured in
        the product's RH convention between the shot's signal end and start
        (:func:`.product_metrics.product_relative_heights`); :data:`FOOTPRINT_RH`: the
        model's RH of the footprint's noise-free waveform a·W + d, d drawn from
        p(d | θ, y) (:func:`.likelihood.conditional.discrepancy_given_data`), NaN where
        the likelihood does not allow it; NaN where a sample has no finite posterior.
    canopy_sigmas : array (n,)
        :func:`.footprint.canopy_return_sigmas` of each sample (its drawn gain), from the
        same waveforms; NaN where a sample has no finite posterior.
    """
    post = problem.log_posterior
    like = post.likelihood
    settings = problem.settings.processing or processing_settings(problem.instrument.name)
    levels = list(PRODUCT_RH.values())
    heights = np.full((x.shape[0], len(levels)), np.nan)
    footprint = np.full((x.shape[0], len(FOOTPRINT_RH)), np.nan)
    canopy_sigmas = np.full(x.shape[0], np.nan)
    conditioned = like.conditioning_obstacle is None
    parts, bare = [], bare_ground_for(problem, x)
    for first in range(0, x.shape[0], _CHUNK):
        rows = slice(first, first + _CHUNK)
        terms = post.evaluate(x[rows], keep_signal=True)
        parts.append(post.draw_marginalised(x[rows], rng, terms))
        good = np.flatnonzero(np.isfinite(terms.log_posterior))
        if not good.size:
            continue
        values = problem.space.values(x[rows][good])
        values.update({name: draws[good] for name, draws in parts[-1].items()})
        mean = like.predictive_moments(terms.signal[good], values)[0]
        canopy_sigmas[first + good] = excess_sigmas(problem, terms.signal[good], values, bare)
        heights[first + good] = product_relative_heights(
            mean, problem.window.axis, values["ground_elevation"], values["baseline"],
            problem.analysis, settings, levels,
        )  # fmt: skip
        if conditioned:
            own = like.discrepancy_given_data(terms.signal[good], values, rng)
            own += mean - values["baseline"][:, None]  # a·W + d
            footprint[first + good] = relative_heights(
                own, problem.window.axis, values["ground_elevation"], list(FOOTPRINT_RH.values())
            )
    drawn = {name: np.concatenate([part[name] for part in parts]) for name in parts[0]}
    heights = {name: heights[:, i] for i, name in enumerate(PRODUCT_RH)}
    heights.update({name: footprint[:, i] for i, name in enumerate(FOOTPRINT_RH)})
    return drawn, heights, canopy_sigmas


#: A posterior-predictive p-value below this flags a misfit the model cannot explain.
MISFIT_P_VALUE = 0.01


def fit_statistics(log_likelihood, observed, replicated, mean, variance) -> dict:
    """How well the posterior explains the shot: DIC and a posterior-predictive check.

    Parameters
    ----------
    log_likelihood : array (n,)
        log p(y | θᵢ) of posterior samples θᵢ.
    observed : array (bins,) (DN)
    replicated : array (n, bins) (DN)
        One replicated observation per sample (the likelihood's ``replicate``).
    mean, variance : array (n, bins)
        Each sample's predictive mean (DN) and per-bin variance (DN²).

    Returns
    -------
    dict
        ``dic``: the deviance information criterion D̄ + p_V, D = −2 log p(y | θ), with
        p_V = var(D)/2 the effective number of parameters (Gelman et al. 2004, Bayesian
        Data Analysis, 2nd ed., §6.7); smaller is better, and it compares models of the
        same data under the same likelihood. ``effective_parameters``: p_V.
        ``predictive_p_value``: P(T(y_rep, θ) ≥ T(y, θ)) for the discrepancy
        T(y, θ) = Σ (y − μθ)²/σθ² over the window (Gelman, Meng & Stern 1996): near 0, the
        waveform departs from the model by more than its noise and discrepancy allow.
        ``residual_scale``: √(mean T(y, θ) / mean T(y_rep, θ)), the residuals' RMS over the
        scatter the model allows; 1 where the model explains the waveform, and how far off
        it is where the p-value flags a misfit (over a long window a p-value finds small
        misfits as readily as large ones).

    References
    ----------
    Gelman, A., Carlin, J. B., Stern, H. S. & Rubin, D. B. (2004). *Bayesian Data Analysis*,
    2nd ed., Chapman & Hall/CRC, Sec. 6.7 (DIC with p_V = var(D)/2).
    Spiegelhalter, D. J., Best, N. G., Carlin, B. P. & van der Linde, A. (2002). Bayesian
    measures of model complexity and fit. *J. R. Statist. Soc. B* 64(4), 583–639 (the
    deviance information criterion).
    Gelman, A., Meng, X.-L. & Stern, H. (1996). Posterior predictive assessment of model
    fitness via realized discrepancies. *Statistica Sinica* 6(4), 733–807 (the posterior-
    predictive p-value of a realised discrepancy).
    """
    deviance = -2.0 * np.asarray(log_likelihood, float)
    deviance = deviance[np.isfinite(deviance)]
    p_v = 0.5 * float(np.var(deviance)) if deviance.size > 1 else float("nan")
    t_observed = np.sum((observed - mean) ** 2 / variance, axis=1)
    t_replicated = np.sum((replicated - mean) ** 2 / variance, axis=1)
    return {
        "dic": float(np.mean(deviance) + p_v) if deviance.size else float("nan"),
        "effective_parameters": p_v,
        "predictive_p_value": float(np.mean(t_replicated >= t_observed)),
        "residual_scale": float(np.sqrt(np.mean(t_observed) / np.mean(t_replicated))),
    }


def _misfit_flags(fit) -> list:
    """A flag where the posterior-predictive check finds a misfit."""
    if not fit["predictive_p_value"] < MISFIT_P_VALUE:
        return []
    return [
        f"misfit: the waveform departs from the model beyond its noise and discrepancy "
        f"(posterior-predictive p = {fit['predictive_p_value']:.3f}; residuals "
        f"{fit['residual_scale']:.2f}× the scatter the model allows; see the residual panel)"
    ]


def _importance_diagnostics(run: SamplerRun) -> dict:
    """How the draws were made: ``"sampling"`` is ``"importance"`` where weighted draws
    from a t fitted to the chain ended the run (with their Pareto k̂, ESS, count and the
    step the t was fitted at), else ``"chain"``; and every try's (step, k̂, ESS)."""
    out = {"sampling": "chain", "importance_tries": [list(t) for t in run.importance_tries]}
    if run.importance is not None:
        i = run.importance
        out["sampling"] = "importance"
        out["importance"] = {
            "khat": i.khat, "ess": i.ess, "draws": len(i.u), "made": i.made, "step": i.step
        }  # fmt: skip
    return out


def collect_result(problem: InversionProblem, run: SamplerRun, rng) -> InversionResult:
    """Posterior samples, derived quantities, bands and diagnostics of a finished run.

    Parameters
    ----------
    problem : InversionProblem
    run : SamplerRun
    rng : numpy.random.Generator
        For the marginalised gain's draws, the band's samples and the footprint's
        tallest stem.

    Returns
    -------
    InversionResult
        The samples after burn-in and thinning in physical units (with the marginalised
        gain drawn from p(a | θ, y)), the blobs, the footprint's tallest stem, the
        quantiles of the model mean b + a·W over :data:`_BAND_SAMPLES` samples, the
        crown-volume profile and the run's diagnostics.
    """
    space, post = problem.space, problem.log_posterior
    u, log_prob, blobs = run.draws()
    x, _ = space.from_unbounded(u)
    derived = {name: blobs[:, i] for i, name in enumerate(BLOB_NAMES)}
    derived[FOOTPRINT_TOP] = footprint_top_height(problem, x, derived["density"], rng)
    derived[FOOTPRINT_NO_STEM] = footprint_no_stem(problem, derived["density"])
    drawn, heights, canopy_sigmas = sample_draws(problem, x, rng)  # e.g. the gain drawn
    derived.update(heights)
    seen = heights["rh98_footprint"]  # the footprint's own waveform, else the model's
    seen = seen if np.isfinite(seen).any() else derived["rh98"]
    derived[FOOTPRINT_BARE] = footprint_bare(problem, x, seen, canopy_sigmas)
    canopy_height = seen_canopy_height(derived[FOOTPRINT_TOP], derived)
    pulse_width = pulse_width_m(problem.instrument.pulse)
    signal_top = problem.analysis.signal_start - space.values(x)["ground_elevation"]
    height_notes = [
        canopy_height_note(canopy_height, seen, pulse_width, derived[FOOTPRINT_BARE]),
        unseen_top_note(canopy_height, signal_top, pulse_width),
        stand_rh98_note(derived["rh98"], heights["rh98_footprint"], pulse_width,
                        derived[FOOTPRINT_BARE]),
    ]  # fmt: skip
    pick = rng.choice(x.shape[0], size=min(_BAND_SAMPLES, x.shape[0]), replace=False)
    terms = post.evaluate(x[pick], keep_signal=True)
    good = np.isfinite(terms.log_posterior)
    values = space.values(x[pick][good])
    values.update({name: draws[pick][good] for name, draws in drawn.items()})
    replicated, rep_mean, rep_variance = post.likelihood.replicate(terms.signal[good], values, rng)
    predictive = np.percentile(rep_mean, QUANTILES, axis=0)
    fit = fit_statistics(
        terms.log_likelihood[good], problem.window.samples, replicated, rep_mean, rep_variance
    )
    broadening = float(np.median(values.get("pulse_broadening", 0.0)))
    fit.update(
        local_misfit(
            problem.window.samples, replicated, rep_mean, values["baseline"], problem.window.axis,
            return_width_bins(problem.instrument.pulse, problem.observation.bin_size, broadening),
        )
    )  # fmt: skip
    units = {FOOTPRINT_TOP: "m", FOOTPRINT_NO_STEM: "1", FOOTPRINT_BARE: "1"}
    if problem.settings.footprint_cover_draws:  # the last of the rng's uses: the rest as without
        derived[FOOTPRINT_COVER] = footprint_cover(
            post, problem.instrument, x, rng, problem.settings.footprint_cover_draws
        )
        units[FOOTPRINT_COVER] = "1"
    # after every other use of the rng, so that the rest is drawn as without
    prior = support_prior_draws(post, space, rng)
    ess = run.coordinate_ess()
    # a conditioned tallest stem's prior is the stand's law, which the draws do not follow
    compared = [name for name in space.names if name != TALLEST_STEM]
    columns = [space.names.index(name) for name in compared]
    learning = prior_learning(
        x[:, columns], prior[:, columns], compared, dict(zip(space.names, ess, strict=True))
    )
    top = float(np.max(values["top_height"]))
    profile_heights = np.linspace(0.0, top, 60)
    profile = post.mapping.crown_volume_profile(values, profile_heights)
    a = problem.analysis
    modes = ground_modes(space, x)  # the evidence for each ground of a two-ground prior
    truth = {
        k: float(v)
        for k, v in problem.observation.truth.items()
        if np.ndim(v) == 0 and isinstance(v, (int, float, np.floating))
    }
    return InversionResult(
        shot_id=problem.observation.shot_id,
        parameter_names=(*space.names, *drawn),
        units={
            **{p.name: p.units for p in space.parameters},
            **BLOB_UNITS,
            **units,
            **dict.fromkeys(PRODUCT_RH, "m"),
            **dict.fromkeys(FOOTPRINT_RH, "m"),
        },
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
            "map_log_prob": float(max(np.max(run.log_prob), np.max(log_prob))),
            "start_modes": int(run.start_modes),
            "seconds": dict(run.seconds),
            "tau_history": [[int(i), t] for i, t in run.tau_history],
            # the monitored reported quantities: bulk and tail ESS, split R̂, τ (steps)
            "quantities": run.quantities,
            **_importance_diagnostics(run),
            # each parameter's posterior against its prior (:mod:`.prior_learning`)
            "prior_learning": learning,
            **fit,
            **({} if modes is None else {"ground_modes": modes}),
        },
        flags=list(run.flags)
        + post.likelihood.notes
        + _misfit_flags(fit)
        + describe_local_misfit(fit)
        + [flag for flag in [describe_modes(modes), *height_notes] if flag],
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
