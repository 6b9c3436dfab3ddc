"""Ground candidates under a closed canopy: weak lowest returns judged by their energy.

Under a dense canopy the ground return may be a few noise σ high and a pulse wide, on the
lower flank of a canopy return ten or fifty times stronger. Smoothed by a pulse width it
is then no local maximum, or one with a shallow trough, and a per-sample floor set for
open canopies (the back floor) may cut it off. LVIS L2 (Blair, Rabine & Hofton 1999;
Hofton, Minster & Blair 2000) takes the ground as the lowest Gaussian of a decomposition
of the smoothed waveform, shoulders included; GEDI L2A takes the lowest mode of the
smoothed waveform above its back floor. Here the candidates below the lowest mode are
the waveform's concave stretches (where the smoothed second derivative is negative, the
core of each component of a decomposition, shoulders included), and a candidate is
judged by what the noise allows for a return of the pulse's width:

* **energy**: the sum of the recorded samples above the noise mean over a window one
  pulse FWHM wide about it (:func:`window_energy`), against the σ of that sum under the
  shot's measured noise autocorrelation, σ_sum² = σ² Σ_i Σ_j R(|i − j|)
  (:func:`window_sum_sigma`);
* **separation**: its excess over the chord between the ends of its concave stretch
  (:func:`chord_excess`), against the σ of that linear combination of samples under the
  same autocorrelation: a shoulder that is no separate return has no excess.

Both are compared with a one-sided Gaussian level (:func:`significance_sigmas`) that holds
the false-alarm probability of the whole search at ``FALSE_ALARM`` (Bonferroni over the
independent pulse-wide windows searched). A candidate that reaches the level of the
search at ``PLAUSIBLE_FALSE_ALARM`` but not at ``FALSE_ALARM`` is *plausible*: it is
reported as the alternative ground and the shot is flagged ambiguous. Symmetrically, a
candidate chosen below the lowest mode that reaches the level at ``FALSE_ALARM`` but not
at ``CONFIDENT_FALSE_ALARM`` may still be noise: the lowest mode is then the alternative
and the shot is flagged ambiguous, so that the inversion's ground prior holds both.
"""

from dataclasses import dataclass

import numpy as np
from scipy.stats import norm

from .noise import clipped_mean_sigma, filtered_sigma, gaussian_weights

#: Probability that a shot's search finds a ground candidate in noise alone (one in a
#: hundred shots): the false-alarm rate of GEDI L2A's and LVIS L2's thresholds is of this
#: order, and the level grows only logarithmically with it.
FALSE_ALARM = 0.01
#: The same probability for a *plausible* candidate (one in ten shots): a weaker return
#: below the chosen ground that the search would find in noise alone more often than
#: ``FALSE_ALARM`` but seldom is reported as the alternative and flags the shot.
PLAUSIBLE_FALSE_ALARM = 0.1
#: The same probability for a *confident* choice (one in a thousand shots): a candidate
#: chosen below the lowest mode whose evidence reaches the level at ``FALSE_ALARM`` but not
#: at this one keeps the lowest mode as a plausible ground (:func:`choose_ground`).
CONFIDENT_FALSE_ALARM = 0.001


@dataclass(frozen=True)
class GroundCandidate:
    """One candidate ground return.

    Attributes
    ----------
    position : float (m)
        Axis value of its centre (the smoothed waveform's maximum for a mode, the minimum
        of the smoothed second derivative for a shoulder).
    index : float
        Fractional bin of ``position``.
    kind : str
        ``"mode"`` (a local maximum of the smoothed waveform) or ``"shoulder"``.
    energy_sigmas : float
        Summed energy above the noise mean over a pulse-wide window, in σ of that sum.
    separation_sigmas : float
        Excess over the chord of its concave stretch, in σ of that excess (``inf`` for the
        lowest mode of the smoothed waveform, whose prominence already separates it).
    """

    position: float
    index: float
    kind: str
    energy_sigmas: float
    separation_sigmas: float

    def evidence(self) -> float:
        """The weaker of the two tests (σ)."""
        return float(min(self.energy_sigmas, self.separation_sigmas))


def significance_sigmas(n_trials: float, false_alarm: float = FALSE_ALARM) -> float:
    """One-sided Gaussian level z with P(any of ``n_trials`` exceeds z) ≈ ``false_alarm``:
    z = Φ⁻¹(1 − false_alarm / n_trials).

    References
    ----------
    Dunn, O. J. (1961). Multiple comparisons among means. *J. Am. Statist. Assoc.* 56(293),
    52–64 (the Bonferroni bound on a family's false-alarm rate).
    """
    return float(norm.isf(false_alarm / max(float(n_trials), 1.0)))


def rescaled_level(level: float, false_alarm: float, base: float = FALSE_ALARM) -> float:
    """The level of the same search at another false-alarm probability: ``level`` holds
    it at ``base``, and the Bonferroni count of trials cancels,
    z' = Φ⁻¹(1 − Φ̄(level)·false_alarm/base)."""
    return float(norm.isf(norm.sf(level) * false_alarm / base))


def window_sum_sigma(noise, n_bins: int) -> float:
    """σ of the sum of ``n_bins`` consecutive noise samples: σ² Σ_i Σ_j R(|i − j|), with
    the shot's measured σ and autocorrelation R (DN × bins)."""
    return filtered_sigma(noise.sigma, noise.autocorrelation, np.ones(max(int(n_bins), 1)))


def measured_window_sum_sigma(samples, signal_free, mean: float, n_bins: int) -> float:
    """σ of the sum of ``n_bins`` consecutive samples measured on the signal-free runs
    (σ-clipped): holds slow baseline wander that the truncated autocorrelation misses.
    NaN when the signal-free runs hold fewer than a few such windows."""
    x = np.asarray(samples, float) - mean
    free = np.asarray(signal_free, bool)
    n = max(int(n_bins), 1)
    kernel = np.ones(n)
    sums = np.convolve(np.where(free, x, 0.0), kernel, mode="valid")
    whole = np.convolve(free.astype(float), kernel, mode="valid") == n
    if whole.sum() < 4 * n:
        return np.nan
    return clipped_mean_sigma(sums[whole])[1]


def window_energy(samples, mean: float, centre: int, half: int) -> float:
    """Sum of the samples above the noise mean over bins ``centre ± half`` (DN × bins)."""
    lo, hi = max(centre - half, 0), min(centre + half + 1, len(samples))
    return float(np.sum(np.asarray(samples[lo:hi], float) - mean))


def chord_weights(first: int, last: int, smoothing_bins: float, n_bins: int) -> np.ndarray:
    """Weights w on the recorded samples with Σ w·y = Σ_(first<i<last) (y_i − chord_i), the
    chord joining the smoothed waveform at ``first`` and ``last`` (bins)."""
    weights = np.zeros(n_bins)
    inner = np.arange(first + 1, last)
    if inner.size == 0:
        return weights
    weights[inner] = 1.0
    t = (inner - first) / (last - first)
    kernel, _ = gaussian_weights(max(float(smoothing_bins), 1e-6))
    radius = kernel.size // 2
    for end, share in ((first, np.sum(1.0 - t)), (last, np.sum(t))):
        lo, hi = end - radius, end + radius + 1
        k = kernel[max(0, -lo) : kernel.size - max(0, hi - n_bins)]
        weights[max(lo, 0) : min(hi, n_bins)] -= share * k / k.sum()
    return weights


def chord_excess(samples, weights) -> float:
    """Σ w·y: the samples' excess over the chord (DN × bins)."""
    return float(np.dot(weights, samples))


def concave_stretches(smoothed, lo: int, hi: int):
    """Runs of bins ``lo ≤ i < hi`` where the smoothed waveform's second derivative is
    negative, each as (first, last, centre) with centre its most negative bin."""
    curvature = np.gradient(np.gradient(np.asarray(smoothed, float)))
    concave = np.zeros(curvature.size, bool)
    concave[lo:hi] = curvature[lo:hi] < 0
    edges = np.flatnonzero(np.diff(np.concatenate([[0], concave.view(np.int8), [0]])))
    out = []
    for first, stop in zip(edges[::2], edges[1::2]):
        centre = first + int(np.argmin(curvature[first:stop]))
        out.append((int(first), int(stop - 1), centre))
    return out, curvature


def _vertex(values, index: int) -> float:
    """Fractional index of the parabola vertex through ``values[index-1:index+2]``."""
    if 0 < index < len(values) - 1:
        a, b, c = values[index - 1 : index + 2]
        curvature = a - 2.0 * b + c
        if curvature < 0:
            return index + float(np.clip(0.5 * (a - c) / curvature, -0.5, 0.5))
    return float(index)


def ground_candidates(
    samples,
    smoothed,
    axis,
    noise,
    *,
    lowest_mode: int,
    lowest_bin: int,
    return_sigma_bins: float,
    signal_free=None,
):
    """The lowest mode and the concave stretches below it, with their evidence.

    Parameters
    ----------
    samples, smoothed : arrays (DN)
        Recorded and smoothed waveform on the ascending ``axis`` (m).
    noise : NoiseModel
        The shot's noise (σ, autocorrelation, smoothing).
    lowest_mode : int
        Bin of the lowest significant mode of the smoothed waveform.
    lowest_bin : int
        Lowest bin searched (above the window's edge).
    return_sigma_bins : float
        σ of a flat ground's return as the smoothed waveform shows it (bins); the energy
        window is one FWHM of it wide.
    signal_free : array of bool, optional
        Signal-free bins, on which the σ of a window sum is also measured directly (the
        larger of the two is used).

    Returns
    -------
    candidates : list of GroundCandidate
        Lowest first; the lowest mode last.
    level, plausible_level : float
        Significance levels (σ) of the search at ``FALSE_ALARM`` and at
        ``PLAUSIBLE_FALSE_ALARM``.

    References
    ----------
    Hofton, M. A., Minster, J. B. & Blair, J. B. (2000). Decomposition of laser altimeter
    waveforms. *IEEE Trans. Geosci. Remote Sens.* 38(4), 1989–1996 (the lowest Gaussian
    component, shoulders included, as LVIS L2's ground).
    Blair, J. B., Rabine, D. L. & Hofton, M. A. (1999). The Laser Vegetation Imaging Sensor:
    a medium-altitude, digitisation-only, airborne laser altimeter for mapping vegetation
    and topography. *ISPRS J. Photogramm. Remote Sens.* 54(2–3), 115–122.
    Hofton, M. & Blair, J. B. (2019). *Algorithm Theoretical Basis Document (ATBD) for GEDI
    Transmit and Receive Waveform Processing for L1 and L2 Products*, version 1.0. NASA
    Goddard Space Flight Center, Greenbelt, MD (GEDI L2A's lowest mode).
    """
    samples = np.asarray(samples, float)
    smoothed = np.asarray(smoothed, float)
    axis = np.asarray(axis, float)
    step = float(axis[1] - axis[0])
    half = max(int(np.rint(np.sqrt(2.0 * np.log(2.0)) * return_sigma_bins)), 1)
    sum_sigma = window_sum_sigma(noise, 2 * half + 1)
    if signal_free is not None:
        measured = measured_window_sum_sigma(samples, signal_free, noise.mean, 2 * half + 1)
        sum_sigma = float(np.nanmax([sum_sigma, measured]))
    stretches, curvature = concave_stretches(smoothed, lowest_bin, lowest_mode)
    # the lowest mode's own concave core is no separate candidate
    stretches = [s for s in stretches if s[1] < lowest_mode - half]
    n_windows = max((lowest_mode - lowest_bin) / (2 * half + 1), 1.0)
    level = significance_sigmas(n_windows)
    plausible_level = significance_sigmas(n_windows, PLAUSIBLE_FALSE_ALARM)
    out = []
    for first, last, centre in stretches:
        energy = window_energy(samples, noise.mean, centre, half) / sum_sigma
        weights = chord_weights(first, last, noise.smoothing_bins, samples.size)
        spread = filtered_sigma(noise.sigma, noise.autocorrelation, weights)
        excess = chord_excess(samples, weights) / spread if spread > 0 else 0.0
        top = first + int(np.argmax(smoothed[first : last + 1]))
        if first < top < last:  # a local maximum inside its concave stretch
            kind, index = "mode", _vertex(smoothed, top)
        else:  # the most concave bin: a component's centre on another's flank
            kind, index = "shoulder", _vertex(-curvature, centre)
        out.append(GroundCandidate(float(axis[0] + index * step), index, kind, energy, excess))
    energy = window_energy(samples, noise.mean, lowest_mode, half) / sum_sigma
    index = _vertex(smoothed, lowest_mode)
    out.append(GroundCandidate(float(axis[0] + index * step), index, "mode", energy, np.inf))
    return out, level, plausible_level


def candidate_uncertainty(candidate: GroundCandidate, return_sigma_m: float) -> float:
    """1-σ uncertainty (m) of a candidate's centre: a mode of a return of σ_r found at S σ
    is centred to about σ_r / S; a shoulder, a component overlapping a stronger one, no
    better than half its σ_r (the most concave bin leans away from the flank above it)."""
    if candidate.kind == "shoulder":
        return 0.5 * return_sigma_m
    return return_sigma_m / max(candidate.evidence(), 1.0)


@dataclass(frozen=True)
class GroundChoice:
    """The ground chosen among the candidates, and the alternative where there is one.

    Attributes
    ----------
    chosen, alternative : GroundCandidate or None
        The lowest significant candidate; the plausible candidate below it, or else the
        lowest mode where a candidate below it was chosen (``None`` if neither).
    ambiguous : bool
        A plausible but not significant candidate lies below the chosen one, or the
        chosen one, below the lowest mode, is significant but not confidently so.
    level, plausible_level : float
        Significance levels (σ) of the search and of a plausible alternative.
    """

    chosen: GroundCandidate
    alternative: GroundCandidate | None
    ambiguous: bool
    level: float
    plausible_level: float


def choose_ground(
    candidates, level: float, plausible_level: float, kinds=("mode", "shoulder")
) -> GroundChoice:
    """The ground among the candidates (lowest first, the lowest prominent mode last).

    The products rank their modes from the lowest up (GEDI L2A: the lowest mode of the
    smoothed waveform; LVIS L2: the lowest Gaussian of its decomposition), so the ground is
    the lowest candidate whose energy and separation both reach ``level``; the lowest
    prominent mode always qualifies. A shoulder is a component that only the decomposition
    resolves: where it lies on the lower flank of a significant mode that is not the
    prominent one, it may as well be that mode's own broadened return (a sloped or rough
    ground spreads its return over metres), so the mode is chosen and the shoulder is
    the alternative. Where a candidate below the chosen one reaches ``plausible_level``
    but not ``level``, it is the alternative. Either way the choice is ambiguous. So is a
    candidate chosen below the lowest mode whose evidence reaches ``level`` but not the
    level at :data:`CONFIDENT_FALSE_ALARM` (:func:`rescaled_level`): a search finds such a
    candidate in noise alone about once in a hundred shots, so the lowest mode stays a
    plausible ground (its alternative). Candidates of other ``kinds`` than those the
    instrument's product resolves are left out (GEDI L2A resolves modes only).
    """
    candidates = [c for c in candidates[:-1] if c.kind in kinds] + [candidates[-1]]
    last = len(candidates) - 1
    significant = [i for i, c in enumerate(candidates[:last]) if c.evidence() >= level] + [last]
    chosen_at, alternative = significant[0], None
    if candidates[chosen_at].kind == "shoulder":
        modes = [i for i in significant[1:-1] if candidates[i].kind == "mode"]
        if modes:
            chosen_at, alternative = modes[0], candidates[chosen_at]
    chosen = candidates[chosen_at]
    if alternative is None:
        below = [c for c in candidates[:chosen_at] if c.evidence() >= plausible_level]
        alternative = below[-1] if below else None
    if alternative is not None:
        return GroundChoice(chosen, alternative, True, level, plausible_level)
    if chosen_at == last:
        return GroundChoice(chosen, None, False, level, plausible_level)
    marginal = chosen.evidence() < rescaled_level(level, CONFIDENT_FALSE_ALARM)
    return GroundChoice(chosen, candidates[last], marginal, level, plausible_level)
