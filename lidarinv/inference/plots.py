"""Figures of a posterior: corner plot, posterior predictive, crown-volume profile."""

from pathlib import Path

import numpy as np

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


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def corner_plot(result: InversionResult, names=None, path=None):
    """Corner plot of the chosen quantities (default: the main free parameters)."""
    import corner

    names = [n for n in (names or CORNER_DEFAULT) if n in result.quantity_names]
    data = np.column_stack([result.column(n) for n in names])
    data = data[np.all(np.isfinite(data), axis=1)]
    truths = [result.truth.get(n) for n in names]
    labels = [f"{n} ({result.units.get(n, '')})" for n in names]
    figure = corner.corner(
        data,
        labels=labels,
        quantiles=(0.05, 0.5, 0.95),
        show_titles=True,
        title_fmt=".3g",
        truths=truths if any(t is not None for t in truths) else None,
    )
    if path is not None:
        figure.savefig(path, dpi=90)
        _pyplot().close(figure)
    return figure


def predictive_plot(result: InversionResult, path=None):
    """Observed samples, noise floor, median model and 90 % band against height."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(4.5, 6.5))
    low, _, median, _, high = result.predictive
    ax.fill_betweenx(result.axis, low, high, color="tab:blue", alpha=0.35, label="90 % band")
    ax.plot(median, result.axis, color="tab:blue", lw=1.2, label="median model")
    ax.plot(result.observed, result.axis, ".", ms=2, color="k", label="observed")
    if result.censored.any():
        ax.plot(
            result.observed[result.censored],
            result.axis[result.censored],
            "v",
            ms=3,
            color="tab:gray",
            label="censored",
        )
    ax.axvline(result.noise_floor, color="tab:red", ls="--", lw=0.8, label="noise floor")
    ax.set_xlabel("digitiser units")
    ax.set_ylabel("height on the waveform axis (m)")
    ax.set_title(f"shot {result.shot_id}: posterior predictive", fontsize=9)
    ax.legend(fontsize=7, loc="upper right")
    fig.tight_layout()
    if path is not None:
        fig.savefig(path, dpi=110)
        plt.close(fig)
    return fig


def profile_plot(result: InversionResult, path=None):
    """Crown-volume profile (median and 90 % band) against height above ground."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(4.0, 5.5))
    low, _, median, _, high = result.profile
    ax.fill_betweenx(
        result.profile_heights, low, high, color="forestgreen", alpha=0.3, label="90 %"
    )
    ax.plot(median, result.profile_heights, color="forestgreen", label="median")
    ax.set_xlabel("crown volume density (m³ m⁻² m⁻¹)")
    ax.set_ylabel("height above ground (m)")
    ax.set_title(f"shot {result.shot_id}: crown-volume profile", fontsize=9)
    ax.legend(fontsize=8)
    fig.tight_layout()
    if path is not None:
        fig.savefig(path, dpi=110)
        plt.close(fig)
    return fig


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
