"""What a footprint holds, beside its tallest stem: the probability that it holds no stem
at all, and whether its own waveform shows anything above its ground's return."""

import numpy as np

from lidarinv.observe.ground_candidates import FALSE_ALARM, significance_sigmas
from lidarinv.observe.instrument import ground_return_cdf

from ..model.tallest_stem import disc_area
from ..problem import InversionProblem

#: Derived quantity: per sample, the probability that no stem stands within the footprint;
#: its posterior mean is the probability that the footprint holds no tree.
FOOTPRINT_NO_STEM = "footprint_no_stem_probability"


#: Derived quantity: per sample, 1 where the footprint's waveform shows no canopy return (its
#: canopy's return above a bare ground's lies within the noise), else 0 (NaN where the
#: sample has no footprint waveform).
FOOTPRINT_BARE = "footprint_bare"
#: The level (noise σ of a matched filter's output) a canopy return must reach to be seen:
#: the one-sided Gaussian level of one test at the ground search's false-alarm probability
#: (:data:`lidarinv.observe.ground_candidates.FALSE_ALARM`).
CANOPY_DETECTION_SIGMAS = significance_sigmas(1.0, FALSE_ALARM)
#: Posterior samples evaluated at once.
_CHUNK = 1024
#: Broadenings on which a bare ground's RH98 is computed, then interpolated per sample.
_BROADENING_GRID = 24


class BareGround:
    """A flat, bare ground's return under a pulse widened by each of a range of broadenings,
    tabulated once (:data:`_BROADENING_GRID` broadenings spanning the range) for every
    sample that needs it: its cumulative fraction (:meth:`cdf`) and its RH98
    (:meth:`rh98`), each sample's broadening taken to the nearest tabulated one.

    Parameters
    ----------
    pulse : GaussianPulse or MeasuredPulse
    broadening_m : array (n,) (m)
        The broadenings σ the table must span (NaN ignored).
    """

    def __init__(self, pulse, broadening_m):
        broadening = np.asarray(broadening_m, float)
        finite = broadening[np.isfinite(broadening)]
        low, high = (finite.min(), finite.max()) if finite.size else (0.0, 0.0)
        self.grid = np.unique(np.linspace(low, high, _BROADENING_GRID))
        self._cdfs = [ground_return_cdf(pulse, float(sigma)) for sigma in self.grid]
        support_low, support_high = pulse.support(1e-6)
        heights = []
        for sigma, cdf in zip(self.grid, self._cdfs):
            offsets = np.linspace(support_low - 6.0 * sigma, support_high + 6.0 * sigma, 4001)
            heights.append(float(np.interp(0.98, cdf(offsets), offsets)))
        self._rh98 = np.array(heights)

    def rh98(self, broadening_m, bin_m) -> np.ndarray:
        """RH98 (m): the height above the return's peak below which 98 % of it lies, at
        each broadening (n,), interpolated between the tabulated ones, plus one bin
        ``bin_m`` (m) (an RH spreads each bin's energy over the bin); NaN where the
        broadening is."""
        broadening = np.asarray(broadening_m, float)
        heights = np.interp(broadening, self.grid, self._rh98) + float(bin_m)
        return np.where(np.isfinite(broadening), heights, np.nan)

    def cdf(self, broadening_m, offsets) -> np.ndarray:
        """The return's cumulative fraction at ``offsets`` (n, k) (m from its peak), each
        row's broadening (n,) taken to the nearest tabulated one."""
        broadening = np.asarray(broadening_m, float)
        nearest = np.abs(broadening[:, None] - self.grid[None, :]).argmin(axis=1)
        out = np.empty(np.shape(offsets))
        for j in np.unique(nearest):
            rows = nearest == j
            out[rows] = self._cdfs[j](offsets[rows])
        return out


def canopy_return_sigmas(problem: InversionProblem, x) -> np.ndarray:
    """How far each sample's return above a bare ground's stands out of the noise.

    Parameters
    ----------
    problem : InversionProblem
    x : array (n, ndim)
        Posterior samples (physical units).

    Returns
    -------
    array (n,)
        S/σ of the matched filter of the sample's excess e over a bare ground: e (DN) is
        its waveform (widened by its broadening, scaled by its gain) less a bare ground's
        return of the same energy under the same broadening, peaking where the waveform's
        ground return peaks, where positive, over the bins above that bare ground's RH98
        (:meth:`BareGround.rh98`); S = Σ e², σ the noise of Σ e·n under the shot's
        measured σ and autocorrelation. Low vegetation within the ground's return shifts
        its peak up and the sample's ground down, and the waveform cannot tell it from a
        ground: only what a bare ground cannot return counts. The gain is the sample's, or
        where it is marginalised the least-squares gain of its waveform to the recorded
        one. NaN where the sample is no stand.
    """
    model, window, noise = problem.log_posterior.model, problem.window, problem.analysis.noise
    values = problem.space.values(x)
    sigmas = np.full(x.shape[0], np.nan)
    bare = bare_ground_for(problem, x)
    for first in range(0, x.shape[0], _CHUNK):
        rows = slice(first, first + _CHUNK)
        part = {k: v[rows] if np.ndim(v) else v for k, v in values.items()}
        vectors, _ = model.mapping.model_vectors(part)
        expected = model.expected.evaluate(vectors)
        whole = model.widen(expected.samples, part)
        gain = part.get("gain")
        if gain is None:  # marginalised: the least-squares gain of the whole waveform
            baseline = part.get("baseline", np.full(whole.shape[0], noise.mean))
            recorded = window.samples[None, :] - np.asarray(baseline)[..., None]
            power = np.sum(whole * whole, axis=1)
            gain = np.sum(whole * recorded, axis=1) / np.where(power > 0, power, np.inf)
        part["gain"] = gain
        sigmas[rows] = np.where(expected.valid, excess_sigmas(problem, whole, part, bare), np.nan)
    return sigmas


def excess_sigmas(problem: InversionProblem, waveforms, values, bare=None) -> np.ndarray:
    """:func:`canopy_return_sigmas` of given model waveforms.

    Parameters
    ----------
    problem : InversionProblem
    waveforms : array (n, bins)
        Model waveforms W, widened by each row's broadening.
    values : dict of arrays (n,)
        Each row's parameters: ``ground_elevation``, ``gain`` (DN), and
        ``pulse_broadening`` (m) where the space has it.
    bare : BareGround, optional
        A table spanning the rows' broadenings (:func:`bare_ground_for`), made once for
        every chunk of a posterior's samples; made for these rows if omitted.

    Returns
    -------
    array (n,)
    """
    window, noise = problem.window, problem.analysis.noise
    n = waveforms.shape[0]
    broadening = np.asarray(values.get("pulse_broadening", np.zeros(n)), float) * np.ones(n)
    bin_m = float(window.axis[1] - window.axis[0])
    bare = BareGround(problem.instrument.pulse, broadening) if bare is None else bare
    reach = bare.rh98(broadening, bin_m)
    edges = np.append(window.axis - 0.5 * bin_m, window.axis[-1] + 0.5 * bin_m)
    peak = _ground_peak(waveforms, window.axis, values["ground_elevation"], reach)
    share = np.diff(bare.cdf(broadening, edges[None, :] - peak[:, None]), axis=1)
    excess = waveforms - np.sum(waveforms, axis=1, keepdims=True) * share
    above = window.axis[None, :] > (peak + reach)[:, None]
    gain = np.asarray(values["gain"], float) * np.ones(n)
    e = np.where(above, np.clip(excess, 0.0, None), 0.0) * gain[:, None]
    signal = np.sum(e * e, axis=1)
    power = _lagged_power(e, _noise_lags(noise.autocorrelation))
    spread = noise.sigma * np.sqrt(np.maximum(power, 0.0))
    return np.where(spread > 0, signal / np.where(spread > 0, spread, 1.0), 0.0)


def _ground_peak(waveforms, axis, ground, reach) -> np.ndarray:
    """Where each row's ground return peaks (m): its waveform's maximum within ``reach``
    (n,) of its ground (n,), refined by the parabola through the three highest bins. Low
    vegetation shifts the return's peak above the sample's ground, and the ground below
    it: the return's own peak is where a bare ground would have returned it."""
    near = np.abs(axis[None, :] - np.asarray(ground)[:, None]) <= np.asarray(reach)[:, None]
    k = np.argmax(np.where(near, waveforms, -np.inf), axis=1)
    k = np.clip(k, 1, axis.size - 2)
    rows = np.arange(waveforms.shape[0])
    a, b, c = (waveforms[rows, k + j] for j in (-1, 0, 1))
    curvature = a - 2.0 * b + c
    shift = np.where(curvature < 0, 0.5 * (a - c) / np.where(curvature < 0, curvature, -1.0), 0.0)
    return axis[k] + np.clip(shift, -0.5, 0.5) * (axis[1] - axis[0])


def bare_ground_for(problem: InversionProblem, x) -> BareGround:
    """The :class:`BareGround` table spanning the broadenings of posterior samples ``x``
    (n, ndim) (physical units); the pulse as it is where the space has no broadening."""
    values = problem.space.values(x)
    broadening = values.get("pulse_broadening", np.zeros(x.shape[0]))
    return BareGround(problem.instrument.pulse, np.asarray(broadening, float) * np.ones(x.shape[0]))


def _noise_lags(autocorrelation) -> np.ndarray:
    """The noise's autocorrelation up to its first non-positive lag (the usual truncation of
    a sample autocorrelation, as :func:`lidarinv.observe.noise.filtered_sigma` makes it)."""
    r = np.asarray(autocorrelation, float)
    stop = np.flatnonzero(r <= 0)
    return r[: stop[0]] if stop.size else r


def _lagged_power(c, lags) -> np.ndarray:
    """Σ_ij c_i c_j R(|i − j|) per row of ``c``."""
    total = np.sum(c * c, axis=1)
    for k in range(1, min(lags.size, c.shape[1])):
        total += 2.0 * lags[k] * np.sum(c[:, k:] * c[:, :-k], axis=1)
    return total


def footprint_bare(problem: InversionProblem, x, rh98, sigmas=None) -> np.ndarray:
    """Whether each sample's footprint waveform shows no canopy return (1) or does (0).

    Parameters
    ----------
    problem : InversionProblem
    x : array (n, ndim)
        Posterior samples (physical units).
    rh98 : array (n,) (m)
        The RH98 of each sample's footprint waveform: NaN marks a sample without one.
    sigmas : array (n,), optional
        :func:`canopy_return_sigmas` where already computed (e.g. by
        :func:`.collect.sample_draws` from the waveforms it evaluates anyway).

    Returns
    -------
    array (n,)
        1 where the sample's canopy return above a bare ground's (:func:`canopy_return_sigmas`)
        stays below :data:`CANOPY_DETECTION_SIGMAS`: the noise would hide it, and the
        waveform is one of a bare ground, whatever stems the sample's stand holds; NaN where
        the RH98 is NaN or the sample is no stand. Averaged over the posterior, P(the
        footprint's waveform shows no canopy | y). Judged by the footprint's RH98 against
        its bare ground's instead, a waveform the data cannot tell from a bare ground is
        judged by a coin's toss: its samples spread their RH98 about the bare ground's by
        what the noise hides in the return's top 2 %.
    """
    sigmas = canopy_return_sigmas(problem, x) if sigmas is None else np.asarray(sigmas, float)
    known = np.isfinite(np.asarray(rh98, float)) & np.isfinite(sigmas)
    return np.where(known, (sigmas < CANOPY_DETECTION_SIGMAS).astype(float), np.nan)


def footprint_no_stem(problem: InversionProblem, density_per_ha) -> np.ndarray:
    """The probability that the footprint's disc holds no stem, per posterior sample.

    Parameters
    ----------
    problem : InversionProblem
    density_per_ha : array (n,) (stems/ha)

    Returns
    -------
    array (n,)
        exp(−λ·A), λ the Poisson stand's density (stems/m²) and A the area of the
        footprint's 1/e² disc (m²), the disc :func:`.collect.footprint_top_height` draws its stems
        on; 0 where the posterior conditions on the tallest stem (that stem stands).
        Averaged over the posterior it is P(no tree in the footprint | y), the weight of
        the zeros of :func:`.collect.footprint_top_height`.
    """
    if problem.log_posterior.mapping.conditioned:
        return np.zeros(np.shape(density_per_ha))
    area = disc_area(problem.instrument.footprint_sigma_m)
    return np.exp(-np.asarray(density_per_ha, float) * 1e-4 * area)


#: How the result's flag of :func:`canopy_height_note` begins.
CANOPY_HEIGHT_FLAG = "canopy height below the waveform's RH98"
#: Share of the posterior's draws above which the result says that the footprint's canopy
#: height and its own waveform's RH98 disagree (:func:`canopy_height_note`).
DISAGREEING_SHARE = 0.5


def canopy_height_note(canopy_height, rh98, tolerance_m: float, bare=None) -> str | None:
    """The result's flag where most draws put the footprint's canopy height well below the
    RH98 of the draw's own waveform; None where they agree.

    Parameters
    ----------
    canopy_height : array (n,) (m)
        The footprint's canopy height per draw (:func:`.result.seen_canopy_height`): its
        tallest stem within the 1/e² disc, drawn from the draw's stand.
    rh98 : array (n,) (m)
        RH98 of each draw's own footprint waveform (``rh98_footprint``).
    tolerance_m : float (m)
        How far the stem may stand below the RH98 and still agree: a pulse width
        (:func:`.passes.ambiguity.pulse_width_m`), by which the pulse spreads the canopy's
        top return upward.
    bare : array (n,), optional
        :func:`footprint_bare` of each draw: a draw whose waveform shows nothing a bare
        ground could not return agrees whatever its RH98, which is then the bare ground's
        under the draw's broadening and may stand several metres up.

    Returns
    -------
    str or None
        The flag where more than :data:`DISAGREEING_SHARE` of the draws with both values
        hold a stem more than ``tolerance_m`` below their RH98 under a canopy return the
        waveform shows.

    Notes
    -----
    The tallest stem is drawn from the stand's law on the disc, not conditioned on this
    footprint's waveform, while the waveform sees every crown over the disc, and a wide
    crown reaches into it from a stem standing up to a crown radius outside. Where a tall
    storey is sparse (under one stem a disc) and its crowns wide, as in tall tropical
    forest, the draw then often holds only the lower storey's stems, and the canopy height
    falls far below the top the waveform shows.
    """
    disagree = _disagreeing_draws(canopy_height, rh98, lambda h, r: h < r - tolerance_m, bare)
    if disagree is None:
        return None
    share, h, r = disagree
    return (
        f"{CANOPY_HEIGHT_FLAG}: in {share:.0%} of draws the tallest stem "
        f"within the footprint's disc stands more than {tolerance_m:.1f} m (a pulse width) "
        f"below the RH98 of the draw's own waveform (medians {h:.1f} m and "
        f"{r:.1f} m); the stem is drawn from the stand, not from this "
        "waveform, and wide crowns reach into the disc from stems outside it: take "
        "rh98_footprint as the canopy's top"
    )


#: How the result's flag of :func:`stand_rh98_note` begins.
STAND_RH98_FLAG = "expected stand's RH98 below the footprint's"


def stand_rh98_note(stand_rh98, footprint_rh98, tolerance_m: float, bare=None) -> str | None:
    """The result's flag where most draws put the expected stand's RH98 well below the RH98
    of the draw's own footprint waveform; None where they agree.

    Parameters
    ----------
    stand_rh98 : array (n,) (m)
        RH98 of each draw's model waveform, the expected stand's (``rh98``).
    footprint_rh98 : array (n,) (m)
        RH98 of each draw's footprint waveform, the model's plus the discrepancy drawn
        given the data (``rh98_footprint``); NaN where it cannot be drawn.
    tolerance_m : float (m)
        A pulse width (:func:`.passes.ambiguity.pulse_width_m`).
    bare : array (n,), optional
        :func:`footprint_bare` of each draw: a draw whose waveform shows no canopy agrees.

    Returns
    -------
    str or None
        The flag where more than :data:`DISAGREEING_SHARE` of the draws with both values
        put the stand's RH98 more than ``tolerance_m`` below the footprint's.

    Notes
    -----
    The expected stand spreads a sparse storey's crowns thin over every arrangement;
    where the footprint holds a few tall crowns, the discrepancy carries their return and
    the stand's RH98 falls below the footprint's. Then the stand the posterior describes
    (its RH98, cover, PAI and crown volume) is lower than the one this waveform shows.
    """
    disagree = _disagreeing_draws(stand_rh98, footprint_rh98, lambda h, r: h < r - tolerance_m,
                                  bare)  # fmt: skip
    if disagree is None:
        return None
    share, stand, footprint = disagree
    return (
        f"{STAND_RH98_FLAG}: in {share:.0%} of draws the RH98 of the expected stand's "
        f"waveform lies more than {tolerance_m:.1f} m (a pulse width) below that of the "
        f"footprint's own waveform (medians {stand:.1f} m and {footprint:.1f} m): the "
        "discrepancy, not the stand, carries the canopy's top return, and the stand's "
        "quantities describe a lower canopy than this footprint's: take rh98_footprint "
        "as the footprint's RH98"
    )


#: How the result's flag of :func:`unseen_top_note` begins.
UNSEEN_TOP_NOTE = "canopy height above the waveform's highest return"


def unseen_top_note(canopy_height, signal_top, tolerance_m: float) -> str | None:
    """The result's note where most draws put the footprint's tallest stem well above the
    highest return the recorded waveform shows above its noise floor; None otherwise.

    Parameters
    ----------
    canopy_height : array (n,) (m)
        The footprint's canopy height per draw (:func:`.result.seen_canopy_height`).
    signal_top : array (n,) (m)
        The recorded waveform's signal start (its highest bin above the noise floor,
        :class:`lidarinv.observe.analyse.WaveformAnalysis`) above each draw's ground.
    tolerance_m : float (m)
        A pulse width (:func:`.passes.ambiguity.pulse_width_m`): the pulse spreads a
        crown top's return upward, so the signal starts above the highest crown.

    Returns
    -------
    str or None
        The note where more than :data:`DISAGREEING_SHARE` of the draws hold a stem more
        than ``tolerance_m`` above the signal start.

    Notes
    -----
    A note, not a warning. The tallest stem is drawn from the stand's law on the disc,
    and a crown's apex returns little: the highest return above the noise floor often
    lies metres below the tallest stem, and the likelihood still reads the faint
    return spread over many bins under that floor. In-family synthetic shots so flagged
    hold the truth within their intervals (the limitations page gives the count).
    """
    disagree = _disagreeing_draws(canopy_height, signal_top, lambda h, t: h > t + tolerance_m)
    if disagree is None:
        return None
    share, h, top = disagree
    return (
        f"{UNSEEN_TOP_NOTE}: in {share:.0%} of draws the tallest stem within the "
        f"footprint's disc stands more than {tolerance_m:.1f} m (a pulse width) above the "
        f"signal start (medians {h:.1f} m and {top:.1f} m above the ground): the stand "
        "model, not a return above the noise floor, sets the canopy height"
    )


def _disagreeing_draws(heights, reference, disagree, bare=None):
    """(share, median height, median reference) of the draws where ``disagree(h, r)``
    and the draw is not judged bare, over the draws with both values; None where that
    share is at most :data:`DISAGREEING_SHARE` or no draw has both."""
    h, r = np.asarray(heights, float), np.asarray(reference, float)
    both = np.isfinite(h) & np.isfinite(r)
    if not both.any():
        return None
    bare = np.zeros(h.shape) if bare is None else np.asarray(bare, float)
    share = float(np.mean(disagree(h[both], r[both]) & (bare[both] != 1.0)))
    if share <= DISAGREEING_SHARE:
        return None
    return share, float(np.median(h[both])), float(np.median(r[both]))
