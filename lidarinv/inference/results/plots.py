"""Figures of a posterior: corner plot, posterior predictive with residuals, crown-volume
profile.

Every figure states what its bands are (5–95 %: the 90 % interval), writes units the same
way (:func:`lidarinv.plotting.unit_label`), and draws a simulated shot's true values with
a label.
"""

import textwrap
from pathlib import Path

import numpy as np

from lidarinv.plotting import QUANTITY_NAMES, quantity_label

from .result import InversionResult

#: Quantities shown in the corner plot by default (those that are free).
CORNER_DEFAULT = (
    "cover",
    "pai",
    "top_height",
    "height_sd",
    "crown_length_ratio",
    "cone_fraction",
    "ground_elevation",
    "rho_ratio",
)

#: The interval every figure draws: 5–95 % (the rows 0 and 4 of the stored quantiles).
BAND = "90 % interval (5–95 %)"

TRUTH_COLOUR = "tab:orange"

#: What the corner plot says about the heights, whose truths sit high by design.
HEIGHT_NOTE = (
    "top height is the upper limit of the stand's height distribution; one footprint "
    "rarely holds a stem that tall, so its truth often lies above the posterior "
    "(see the docs: assumptions and limitations)"
)


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _save(fig, path, dpi=110):
    if path is not None:
        fig.savefig(path, dpi=dpi)
        _pyplot().close(fig)
    return fig


def corner_plot(result: InversionResult, names=None, path=None):
    """Corner plot of the chosen quantities (default: the main free parameters).

    Titles give the median and the 5–95 % range, dashed lines mark the 5, 50 and 95 %
    quantiles, and a simulated shot's true values are drawn in orange.
    """
    import corner

    names = [n for n in (names or CORNER_DEFAULT) if n in result.quantity_names]
    data = np.column_stack([result.column(n) for n in names])
    data = data[np.all(np.isfinite(data), axis=1)]
    truths = [result.truth.get(n) for n in names]
    has_truth = any(t is not None for t in truths)
    labels = [quantity_label(n, result.units.get(n, "")) for n in names]
    size = max(7.0, 1.5 * len(names))
    figure = corner.corner(
        data,
        labels=labels,
        quantiles=(0.05, 0.5, 0.95),
        show_titles=False,
        label_kwargs={"fontsize": 8},
        labelpad=0.12,
        truths=truths if has_truth else None,
        truth_color=TRUTH_COLOUR,
        fig=_pyplot().figure(figsize=(size, size)),
    )
    k = len(names)
    for ax in figure.axes:
        ax.tick_params(labelsize=7)
    at_prior = set(result.prior_dominated)
    for i, name in enumerate(names):  # median [5 %, 95 %] above each histogram
        low, median, high = np.percentile(data[:, i], (5, 50, 95))
        short = QUANTITY_NAMES.get(name, name.replace("_", " "))
        figure.axes[i * k + i].set_title(
            f"{short}{' (≈ prior)' if name in at_prior else ''}\n"
            f"{median:.3g} [{low:.3g}, {high:.3g}]",
            fontsize=8,
            color="0.45" if name in at_prior else "black",
        )
    lines = [
        f"shot {result.shot_id}",
        f"titles: median [5 %, 95 %], the {BAND}",
        "dashed lines: the 5, 50 and 95 % quantiles",
    ]
    if at_prior & set(names):
        lines.append("grey titles (≈ prior): posteriors that stayed at their prior")
    if has_truth:
        lines.append("orange lines: the true values of this simulated shot")
        if "top_height" in names and result.truth.get("top_height") is not None:
            lines += textwrap.wrap(HEIGHT_NOTE, 60)
    figure.text(0.55, 0.97, "\n".join(lines), ha="left", va="top", fontsize=9)
    figure.subplots_adjust(top=0.95, bottom=0.08, left=0.08, right=0.98, wspace=0.08, hspace=0.12)
    return _save(figure, path, dpi=90)


def predictive_plot(result: InversionResult, path=None):
    """Observed samples against the posterior predictive, with a residual panel.

    Left: the 90 % band of replicated observations (model mean plus the likelihood's
    noise and discrepancy: where the observed points should fall), inside it the 90 %
    band of the model mean b + a·W alone, the median model, the detection threshold,
    and the samples the product censored at its floor or the digitiser saturated.
    Right: observed minus the median model, against the predictive band's spread.
    """
    plt = _pyplot()
    fig, (ax, res) = plt.subplots(
        1, 2, figsize=(8.0, 6.5), sharey=True, gridspec_kw={"width_ratios": [3, 2]}
    )
    axis, observed = result.axis, result.observed
    low, _, median, _, high = result.predictive
    if result.replicated is not None:
        r_low, _, _, _, r_high = result.replicated
        inside = np.mean((observed >= r_low) & (observed <= r_high))
        ax.fill_betweenx(
            axis,
            r_low,
            r_high,
            color="tab:blue",
            alpha=0.18,
            lw=0,
            label=f"observations: {BAND}\n({inside:.0%} of samples inside)",
        )
        res.fill_betweenx(
            axis,
            r_low - median,
            r_high - median,
            color="tab:blue",
            alpha=0.18,
            lw=0,
            label="predictive spread",
        )
    ax.fill_betweenx(
        axis, low, high, color="tab:blue", alpha=0.45, lw=0, label=f"model mean b + a·W: {BAND}"
    )
    ax.plot(median, axis, color="tab:blue", lw=1.1, label="median model mean")
    exact = ~result.censored
    saturated = result.saturated if result.saturated is not None else np.zeros_like(exact)
    exact &= ~saturated
    ax.plot(observed[exact], axis[exact], ".", ms=2.5, color="k", label="observed")
    res.plot((observed - median)[exact], axis[exact], ".", ms=2.5, color="k")
    res.axvline(0.0, color="tab:blue", lw=0.8)
    if result.censored.any():
        ax.plot(
            observed[result.censored],
            axis[result.censored],
            "v",
            ms=3,
            color="tab:gray",
            label="at the product's floor: true value ≤ floor (censored)",
        )
    if saturated.any():
        ax.plot(
            observed[saturated],
            axis[saturated],
            "^",
            ms=3,
            color="tab:red",
            label="at the digitiser maximum: true value ≥ it (censored)",
        )
    if np.isfinite(result.saturation):
        ax.axvline(
            result.saturation,
            color="tab:red",
            lw=0.8,
            ls=":",
            label="digitiser maximum (saturation)",
        )
    ax.axvline(
        result.noise_floor,
        color="tab:green",
        ls="--",
        lw=0.8,
        label=f"front floor: noise mean + {_front_sigmas(result):g} σ of the smoothed noise"
        "\n(the signal starts above it)",
    )
    if "signal" in result.truth:  # a noise-free truth, where a file keeps one
        truth = np.asarray(result.truth["signal"], float)
        if truth.shape == axis.shape:
            ax.plot(truth, axis, color=TRUTH_COLOUR, lw=1.0, label="true model mean")
    ground = result.truth.get("ground_elevation")
    if ground is not None:
        ax.axhline(ground, color=TRUTH_COLOUR, lw=0.8, label="true ground (simulated shot)")
        res.axhline(ground, color=TRUTH_COLOUR, lw=0.8)
    ax.set_xlabel("waveform sample (DN, digitiser units)")
    ax.set_ylabel("height on the waveform axis (m)")
    res.set_xlabel("observed − median model (DN)")
    res.legend(fontsize=7, loc="upper right")
    ax.legend(fontsize=7, loc="upper right")
    fig.suptitle(f"shot {result.shot_id}: posterior predictive check", fontsize=10)
    fig.tight_layout()
    return _save(fig, path)


def profile_plot(result: InversionResult, path=None):
    """Crown-volume profile (median and 90 % band) against height above ground."""
    from lidarinv.plotting import unit_label

    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(4.2, 5.5))
    low, _, median, _, high = result.profile
    ax.fill_betweenx(
        result.profile_heights, low, high, color="forestgreen", alpha=0.3, lw=0, label=BAND
    )
    ax.plot(median, result.profile_heights, color="forestgreen", label="median")
    ax.set_xlabel(f"crown volume density ({unit_label('m3/m2/m')})")
    ax.set_ylabel(f"height above ground ({unit_label('m')})")
    ax.set_title(f"shot {result.shot_id}: crown-volume profile", fontsize=9)
    ax.legend(fontsize=8)
    fig.tight_layout()
    return _save(fig, path)


#: Figure makers by file stem.
PLOTS = {"corner": corner_plot, "predictive": predictive_plot, "profile": profile_plot}


def save_plots(result: InversionResult, folder) -> list:
    """Write every figure of :data:`PLOTS` as ``shot_<id>_<name>.png``; returns the paths."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    paths = []
    for name, make in PLOTS.items():
        path = folder / f"shot_{result.shot_id}_{name}.png"
        make(result, path=path)
        paths.append(path)
    return paths


def _front_sigmas(result) -> float:
    """The front floor's multiple of the smoothed noise σ the shot was analysed with."""
    from lidarinv.observe.processing import PROCESSING_DEFAULTS

    processing = result.settings.get("processing") if isinstance(result.settings, dict) else None
    if isinstance(processing, dict) and "start_sigmas" in processing:
        return float(processing["start_sigmas"])
    return PROCESSING_DEFAULTS[None].start_sigmas
