"""A misfit one stretch of the waveform shows: a return the fit leaves out or adds.

The posterior-predictive check of :func:`.collect.fit_statistics` sums squared residuals
over the whole window. A fit that leaves out a canopy return twenty bins long, among
several hundred bins of noise, barely moves that sum, and the instrument model's error
(η times the signal per bin, raised per shot up to its ceiling) widens the band over the
very bins the fit misses. What that error stands for, a receiver reshaping the returns,
moves energy between neighbouring bins; it neither makes a return nor removes one. So
the energy of the residuals summed over a stretch a return wide, or wider, tells a
missing return from a reshaped one.

For each window w (widths from one return's width up, doubling; half-overlapping) the
check compares the posterior-mean residual sum Σ_w (y − μ) with the spread of the same
sum in replicated data, Σ_w (y_rep − μ), which carries the noise correlated as the
likelihood takes it, the simulated discrepancy and the bounded model error:

    z_w = mean_θ Σ_w (y − μθ) / √(mean_θ (Σ_w (y_rep − μθ))²).

A shot whose largest |z_w| exceeds the two-sided normal quantile at a false-alarm level
:data:`FALSE_ALARM` per shot, shared over its windows (Bonferroni), is a misfit.
Posterior-predictive scores lean towards zero (the posterior was fitted to the same
data), so the level is an upper bound.
"""

import numpy as np
from scipy.stats import norm

#: False-alarm probability of the local check per shot, shared over its windows.
FALSE_ALARM = 0.01

#: The flag's first word (the same as the other misfit flags, so that a reader of the
#: flags needs one test).
MISFIT_FLAG = "misfit"

#: Tail area of the pulse left out at each side when sizing a return's width.
_PULSE_TAIL = 0.025


def return_width_bins(pulse, bin_size_m, broadening_m=0.0) -> int:
    """Bins a single return spans: the pulse's central 95 %, widened by the broadening.

    Parameters
    ----------
    pulse : forward.pulse.GaussianPulse or MeasuredPulse
    bin_size_m : float (m)
    broadening_m : float (m)
        σ of the Gaussian that widens the pulse (added in quadrature to a Gaussian of the
        pulse's 95 % width over 3.92 σ).

    Returns
    -------
    int
        At least 3.
    """
    low, high = pulse.support(_PULSE_TAIL)
    sigma = (high - low) / (2.0 * norm.isf(_PULSE_TAIL))
    width = 2.0 * norm.isf(_PULSE_TAIL) * np.hypot(sigma, broadening_m)
    return max(3, int(np.ceil(width / bin_size_m)))


def windows(n_bins, least_width) -> np.ndarray:
    """Half-overlapping windows of widths least_width·2^k that fit in ``n_bins``.

    Returns
    -------
    array (K, 2) of int
        [start, stop) bin indices.
    """
    out, width = [], int(least_width)
    while width <= n_bins:
        step = max(1, width // 2)
        starts = np.arange(0, n_bins - width + 1, step)
        if starts[-1] != n_bins - width:  # the last window ends at the last bin
            starts = np.append(starts, n_bins - width)
        out.append(np.column_stack([starts, starts + width]))
        width *= 2
    return np.concatenate(out) if out else np.empty((0, 2), int)


def window_sums(values, spans) -> np.ndarray:
    """Sums of each row of ``values`` (n, bins) over each span (K, 2): array (n, K)."""
    values = np.atleast_2d(np.asarray(values, float))
    cumulative = np.concatenate([np.zeros((values.shape[0], 1)), np.cumsum(values, axis=1)], 1)
    return cumulative[:, spans[:, 1]] - cumulative[:, spans[:, 0]]


def local_misfit(observed, replicated, mean, baseline, axis, least_width, false_alarm=FALSE_ALARM):
    """The local check of a posterior's fit (see the module).

    Parameters
    ----------
    observed : array (bins,) (DN)
    replicated : array (n, bins) (DN)
        One replicated observation per posterior sample.
    mean : array (n, bins) (DN)
        Each sample's predictive mean.
    baseline : array (n,) (DN)
        Each sample's noise mean.
    axis : array (bins,) (m)
        Bin centres.
    least_width : int
        The narrowest window, in bins (:func:`return_width_bins`).
    false_alarm : float
        Per shot.

    Returns
    -------
    dict
        ``local_misfit``: whether any |z| passes the threshold;
        ``local_z``: the largest |z| of the narrowest windows that pass it (of all
        windows where none does), with its sign (positive: the waveform holds energy the
        fit leaves out);
        ``local_threshold``; ``local_window_m``: the window's lowest and highest bin
        centre (m); ``local_excess``: the mean residual sum there over the fit's whole return
        energy (inf where the fit has none).
    """
    observed = np.asarray(observed, float)
    replicated, mean = np.atleast_2d(replicated), np.atleast_2d(mean)
    if replicated.shape != mean.shape or mean.shape[1] != observed.size:
        raise ValueError(
            f"local misfit: observed {observed.shape}, replicated {replicated.shape} and "
            f"mean {mean.shape} must share their bins"
        )
    spans = windows(observed.size, least_width)
    if not spans.size or not mean.shape[0]:
        return {"local_misfit": False, "local_z": float("nan"), "local_threshold": float("nan")}
    residual = window_sums(observed[None, :] - mean, spans).mean(axis=0)
    spread = np.sqrt(np.mean(window_sums(replicated - mean, spans) ** 2, axis=0))
    with np.errstate(divide="ignore", invalid="ignore"):
        z = np.where(spread > 0, residual / spread, 0.0)
    threshold = float(norm.isf(false_alarm / (2.0 * len(spans))))
    widths = spans[:, 1] - spans[:, 0]
    failing = np.abs(z) > threshold
    # where the check fails, the narrowest failing width places the misfit best
    among = widths == widths[failing].min() if failing.any() else np.ones(len(spans), bool)
    worst = int(np.flatnonzero(among)[np.argmax(np.abs(z[among]))])
    start, stop = spans[worst]
    baseline = np.asarray(baseline, float).reshape(-1, 1)
    modelled = float(np.mean(np.sum(mean - baseline, axis=1)))  # the fit's return energy
    return {
        "local_misfit": bool(abs(z[worst]) > threshold),
        "local_z": float(z[worst]),
        "local_threshold": threshold,
        "local_window_m": [float(axis[start]), float(axis[stop - 1])],
        "local_excess": float(residual[worst] / modelled) if modelled > 0 else float("inf"),
    }


def describe_local_misfit(check) -> list:
    """The result's flag where the local check finds a misfit, else none."""
    if not check.get("local_misfit"):
        return []
    low, high = check["local_window_m"]
    what = "energy the fit leaves out" if check["local_z"] > 0 else "less energy than the fit"
    excess = check["local_excess"]
    amount = (
        ""
        if not np.isfinite(excess)
        else f" ({100 * abs(excess):.1f} % of the fit's return energy)"
    )
    return [
        f"{MISFIT_FLAG}: between {low:.1f} and {high:.1f} m the waveform holds {what}{amount}, "
        f"z = {check['local_z']:.1f} beyond the noise, the simulated discrepancy and the "
        f"bounded model error (threshold {check['local_threshold']:.1f} at a "
        f"{100 * FALSE_ALARM:g} % false alarm per shot); see the residual panel"
    ]
