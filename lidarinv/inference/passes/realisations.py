"""Model discrepancy from explicit realisations: a covariance between bins for the shot.

One footprint holds one random arrangement of trees; the expected-waveform model predicts
the mean over arrangements. A per-bin variance (:mod:`.likelihood.discrepancy`) fixed by the
observed signal is zero where the shot shows no signal, so a row whose expected stand
puts a faint tail of crowns above the shot's tallest tree is penalised as if that were
noise, and the top height is pulled down to the tallest tree present. Here the
discrepancy is simulated instead (:func:`realisation_covariance`):

1. a pilot MAP search under the per-bin discrepancy;
2. K parameter draws from the Laplace ball around it (where the sampler starts);
3. for each draw θᵢ, one explicit random stand (:func:`forward.realise.realise`) seen by
   the explicit engine at the footprint centre, less the expected waveform of θᵢ,
   scaled by its gain: dᵢ = aᵢ·(W_explicit − W_expected) (DN);
4. S = Σ dᵢdᵢᵀ / K, uncentred (a systematic difference between the explicit engine and
   the expected model is discrepancy too), shrunk towards its diagonal,
   C = (1 − γ)·S + γ·diag(S), which is positive definite where S has variance although
   S has rank ≤ K.

C enters the likelihood as a covariance, σn² I + C (:mod:`.likelihood.covariance`). A shot whose
expected stand has a tail of rare tall crowns then finds "no crown there" a likely
departure, and one with crowns above the expected stand a likely one too. With the
latent tallest stem (``InversionSettings.tallest_stem``) each residual is taken against
the expectation conditioned on its own stand's tallest stem, which the latent then
explains: C keeps the spread that remains, a Gaussian one, without the skew.
"""

import time
from dataclasses import dataclass

import numpy as np

from forward.expected.vectors import CONDITIONING_FIELDS, FIELD_INDEX, params_from_vector
from forward.explicit import WaveformSimulator
from forward.footprint import footprint_crown_cover
from forward.realise import realise, scene_extras

from ..model.tallest_stem import (
    NO_STEM_DEPTH_M,
    TALLEST_STEM,
    TALLEST_STEM_LATENTS,
    TALLEST_STEM_POSITION,
    tallest_stem_within,
)
from ..posterior import LogPosterior
from ..sampling.sampler import SamplerSettings
from ..sampling.start import Mode, find_map, initial_ball
from ..settings import RealisationSettings

#: How the note of a window that cannot carry the simulated covariance begins (the
#: per-bin discrepancy is used instead).
PER_BIN_NOTE = "per-bin discrepancy used instead of realisations"


def realisation_residuals(
    log_posterior: LogPosterior, instrument, x, rng, plot_diameters=3.0, accuracy=None
) -> np.ndarray:
    """Residuals of explicit realisations against the expected waveform.

    Parameters
    ----------
    log_posterior : LogPosterior
        The shot's (pilot) posterior.
    instrument : forward.instrument.Instrument
    x : array (n, ndim)
        Physical parameters with a finite log-posterior, one explicit stand each.
    rng : numpy.random.Generator
    plot_diameters : float
        Side of each stand's square plot, in footprint diameters (4σf).
    accuracy : forward.explicit.AccuracySettings, optional
        The explicit engine's quadrature; its own default if None.

    Returns
    -------
    array (n, bins) (DN)
        dᵢ = aᵢ·(W_explicit − W_expected), aᵢ the row's gain or its least-squares fit where
        the gain is integrated out.

    Notes
    -----
    Where the latent tallest stem is sampled, each row's latents are set to those of its
    own stand's tallest stem within the disc (its height, or a height in the no-stem range
    below the stand's lowest tree, and its position), so the residuals hold what that stem
    does not explain; a position held fixed leaves the spread of the stem's weight in them.
    """
    post = log_posterior
    x = np.array(x, float)
    terms = post.evaluate(x, keep_signal=True)
    if not np.all(np.isfinite(terms.log_posterior)):
        raise ValueError("every parameter draw of the discrepancy needs a finite posterior")
    values = post.space.values(x)
    side = plot_diameters * instrument.footprint_diameter_m
    centre = (side / 2, side / 2)
    stands, full = explicit_stands(post, x, side, rng)
    names = post.space.names
    if set(TALLEST_STEM_LATENTS) & set(names):  # each row on its own stand's tallest stem
        sigma = instrument.footprint_sigma_m
        found = np.array([tallest_stem_within(stand, centre, sigma) for _, stand in stands])
        if TALLEST_STEM in names:  # none in the disc: half the no-stem depth below
            none = post.mapping.lowest_height(values) - 0.5 * NO_STEM_DEPTH_M
            x[:, names.index(TALLEST_STEM)] = np.where(found[:, 0] > 0, found[:, 0], none)
        if TALLEST_STEM_POSITION in names:  # none in the disc: any position
            position = np.where(np.isnan(found[:, 1]), 0.5, found[:, 1])
            x[:, names.index(TALLEST_STEM_POSITION)] = position
        terms = post.evaluate(x, keep_signal=True)
    values = post.space.values(x)
    gain = values["gain"] if terms.gain_fit is None else terms.gain_fit[:, 1]
    simulator = WaveformSimulator(instrument, accuracy)
    axis = post.data.axis
    residuals = np.empty((x.shape[0], axis.size))
    for i, ((params, stand), row) in enumerate(zip(stands, full)):
        ground, understory, rho_v = scene_extras(params)
        heights = axis - row[FIELD_INDEX["ground_elevation"]]
        explicit = simulator.simulate(stand, centre, heights, ground, rho_v, understory).samples
        explicit = post.model.widen(explicit[None, :], {k: v[i : i + 1] for k, v in values.items()})
        residuals[i] = gain[i] * (explicit[0] - terms.signal[i])
    return residuals


def explicit_stands(log_posterior: LogPosterior, x, side, rng) -> tuple[list, np.ndarray]:
    """One explicit stand per parameter row, the whole stand whatever stem a row's
    footprint is conditioned on.

    Parameters
    ----------
    log_posterior : LogPosterior
    x : array (n, ndim)
        Physical parameters.
    side : float (m)
        Side of each square plot.
    rng : numpy.random.Generator
        Each stand is drawn from a stream of its own (:func:`realisation_streams`).

    Returns
    -------
    stands : list of (forward.stand_params.StandParams, forward.stand.Stand)
    full : array (n, fields)
        The rows' expected-model vectors.
    """
    post = log_posterior
    vectors, _ = post.mapping.model_vectors(post.space.values(x))
    full = post.model.expected.full_vectors(vectors)
    full[:, [FIELD_INDEX[name] for name in CONDITIONING_FIELDS]] = list(
        CONDITIONING_FIELDS.values()
    )
    stands = []
    for row, stream in zip(full, realisation_streams(rng, full.shape[0])):
        params, _ = params_from_vector(row, post.model.expected.template)
        stands.append((params, realise(params, side, stream)))
    return stands, full


def realisation_streams(rng, count) -> list:
    """One independent generator per explicit stand (common random numbers).

    Drawn from one stream, a stand whose Poisson count changes (a MAP moved in its fourth
    digit) would shift the draws of every stand after it, and so redraw the whole
    discrepancy; with a stream each, it redraws that stand alone. The children come from
    ``rng``'s seed sequence (:meth:`numpy.random.Generator.spawn`), not from its state.

    Parameters
    ----------
    rng : numpy.random.Generator
        Made from a seed sequence (as :func:`numpy.random.default_rng` makes every one).
    count : int

    Returns
    -------
    list of numpy.random.Generator
    """
    try:
        return rng.spawn(int(count))
    except TypeError as error:  # a bit generator made without a seed sequence
        raise TypeError(
            "the discrepancy's realisations need a generator made from a seed sequence "
            f"(numpy.random.default_rng): {error}"
        ) from None


#: Side of the plots of :func:`footprint_cover`, in footprint diameters (4σf): the 3σf disc
#: and every crown reaching into it lie inside.
COVER_PLOT_DIAMETERS = 3.0


def footprint_cover(log_posterior: LogPosterior, instrument, x, rng, draws) -> np.ndarray:
    """Draws of the footprint's own crown cover, a posterior-predictive quantity.

    A sample's ``cover`` is its stationary stand's, the expectation over footprints; one
    footprint's cover scatters about it (no crown within reach in a sparse stand, every
    node covered in a dense one), and that is what a footprint's truth or a plot
    measured under it holds. Each draw realises the sample's stand
    (:func:`forward.realise.realise`) and takes its footprint-weighted crown cover
    (:func:`forward.footprint.footprint_crown_cover`).

    Parameters
    ----------
    log_posterior : LogPosterior
    instrument : forward.instrument.Instrument
    x : array (n, ndim)
        Posterior samples (physical units).
    rng : numpy.random.Generator
    draws : int
        Samples given a draw (picked at random; each costs an explicit stand).

    Returns
    -------
    array (n,)
        The draws; NaN for the samples not picked.
    """
    out = np.full(x.shape[0], np.nan)
    pick = rng.choice(x.shape[0], size=min(int(draws), x.shape[0]), replace=False)
    side = COVER_PLOT_DIAMETERS * instrument.footprint_diameter_m
    stands, _ = explicit_stands(log_posterior, x[pick], side, rng)
    sigma = instrument.footprint_sigma_m
    out[pick] = [footprint_crown_cover(stand, (side / 2, side / 2), sigma) for _, stand in stands]
    return out


def discrepancy_covariance(residuals, shrinkage) -> np.ndarray:
    """The shrunk second moment of the realisation residuals.

    Parameters
    ----------
    residuals : array (K ≥ 2, bins) (DN)
    shrinkage : float
        γ ∈ [0, 1].

    Returns
    -------
    array (bins, bins) (DN²)
        C = (1 − γ)·S + γ·diag(S), S = Σ dᵢdᵢᵀ / K.

    Raises
    ------
    ValueError
        For fewer than two residuals or non-finite ones.

    References
    ----------
    Schäfer, J. & Strimmer, K. (2005). A shrinkage approach to large-scale covariance matrix
    estimation and implications for functional genomics. *Stat. Appl. Genet. Mol. Biol.*
    4(1), Article 32 (shrinkage towards the diagonal of the sample covariance; here with a
    fixed weight γ, not their estimated one).
    Ledoit, O. & Wolf, M. (2004). A well-conditioned estimator for large-dimensional
    covariance matrices. *J. Multivariate Anal.* 88(2), 365–411.
    """
    residuals = np.asarray(residuals, float)
    if residuals.ndim != 2 or residuals.shape[0] < 2:
        raise ValueError(f"residuals must have shape (K ≥ 2, bins), got {residuals.shape}")
    if not np.all(np.isfinite(residuals)):
        raise ValueError("the realisation residuals hold NaN or infinite values")
    second = residuals.T @ residuals / residuals.shape[0]
    return (1.0 - shrinkage) * second + shrinkage * np.diag(np.diag(second))


@dataclass(frozen=True)
class SimulatedDiscrepancy:
    """How a discrepancy covariance was simulated.

    Attributes
    ----------
    seconds : float (s)
        The simulation's wall time.
    estimate : MapEstimate
        The pilot posterior's MAP search it was simulated about.
    residuals : array (K, bins) (DN)
        The realisation residuals the covariance was made from.
    """

    seconds: float
    estimate: object
    residuals: np.ndarray


def realisation_covariance(
    pilot: LogPosterior, instrument, rng, settings: RealisationSettings | None = None,
    sampler=None, estimate=None, enough=None,
):  # fmt: skip
    """The discrepancy covariance of a shot, simulated around its pilot MAP.

    Parameters
    ----------
    pilot : LogPosterior
        The shot's posterior under the per-bin ``observed`` discrepancy.
    instrument : forward.instrument.Instrument
        The shot's instrument (for the explicit engine).
    rng : numpy.random.Generator
    settings : RealisationSettings, optional
    sampler : SamplerSettings, optional
        The MAP search's settings (:func:`.sampling.start.find_map`).
    estimate : MapEstimate, optional
        The pilot's MAP search, if already run.
    enough : callable, optional
        (ball draws (count, ndim) unbounded, residuals (k, bins)) → bool: whether the
        first ``settings.first_count`` realisations suffice
        (:class:`.realisation_count.EnoughRealisations`); the rest of ``settings.count``
        are simulated where they do not. Without it, all ``count`` are.

    Returns
    -------
    covariance : array (bins, bins) (DN²)
        C of :func:`discrepancy_covariance`, for the likelihood's
        ``with_fixed_discrepancy``.
    simulation : SimulatedDiscrepancy
        The simulation's wall time, the pilot's MAP search (whose optimum the sampler
        may start from) and the residuals.
    """
    settings = RealisationSettings() if settings is None else settings
    sampler = SamplerSettings() if sampler is None else sampler
    clock = time.perf_counter()
    space = pilot.space
    log_prob = lambda u: pilot(u)[:, 0]  # noqa: E731
    if estimate is None:
        estimate = find_map(log_prob, space, rng, sampler)
    mode = Mode(estimate.u, estimate.log_prob, estimate.covariance)
    draws = initial_ball(log_prob, [mode], settings.ball, settings.count, rng)
    x, _ = space.from_unbounded(draws)
    first = settings.count if enough is None else settings.first_count
    simulate = lambda rows: realisation_residuals(  # noqa: E731
        pilot, instrument, x[rows], rng, settings.plot_diameters, settings.accuracy
    )
    residuals = simulate(slice(0, first))  # each stand its own stream: the same stands
    if first < settings.count and not enough(draws, residuals):  # as all in one call
        residuals = np.concatenate([residuals, simulate(slice(first, None))])
    covariance = discrepancy_covariance(residuals, settings.shrinkage)
    return covariance, SimulatedDiscrepancy(time.perf_counter() - clock, estimate, residuals)
