"""Figures of a shot's analysis: the waveform with its floors, signal extent and ground."""

import numpy as np

from .signal import smooth

#: Line colours of the marks, shared by every analysis figure.
COLOURS = {
    "start": "tab:green",
    "end": "tab:orange",
    "ground": "tab:brown",
    "product": "tab:purple",
    "alternative": "tab:red",
    "floor": "0.5",
}


def plot_analysis(ax, obs, result, product_ground=None, title=None):
    """Draw one shot on ``ax``: samples, smoothed waveform, floors, extent and ground.

    Parameters
    ----------
    ax : matplotlib Axes
    obs : Observation
    result : ShotAnalysis
        The shot's analysis.
    product_ground : float (m), optional
        A product's ground (e.g. GEDI L2A ``elev_lowestmode``), drawn dashed.
    title : str, optional
        Default: the shot id, status and flags.
    """
    ax.plot(obs.samples, obs.axis, color="0.6", lw=0.6, label="samples")
    if np.isfinite(result.smoothing_bins):
        smoothed = smooth(obs.samples, result.smoothing_bins)
        label = f"smoothed (σ {result.smoothing_bins:.1f} bins)"
        ax.plot(smoothed, obs.axis, color="k", lw=1.0, label=label)
    for value, label, style in (
        (result.start_floor, "front floor", ":"),
        (result.end_floor, "back floor", "--"),
    ):
        if np.isfinite(value):
            ax.axvline(value, color=COLOURS["floor"], ls=style, lw=0.8, label=label)
    marks = (
        (result.signal_start, "signal start", COLOURS["start"], "-"),
        (result.signal_end, "signal end", COLOURS["end"], "-"),
        (result.ground, f"ground ({result.ground_kind or 'mode'})", COLOURS["ground"], "-"),
        (result.ground_alternative, "alternative ground", COLOURS["alternative"], ":"),
        (product_ground, "product ground", COLOURS["product"], "--"),
    )
    for value, label, colour, style in marks:
        if value is not None and np.isfinite(value):
            ax.axhline(value, color=colour, ls=style, lw=1.0, label=label)
    if np.isfinite(result.ground):
        top = result.signal_start if np.isfinite(result.signal_start) else obs.axis[-1]
        ax.set_ylim(max(result.signal_end - 10.0, obs.axis[0]), min(top + 10.0, obs.axis[-1]))
    ax.set_xlabel("digitiser counts (DN)")
    ax.set_ylabel(f"{obs.axis_kind} (m)")
    flags = f" ({', '.join(result.flags)})" if result.flags else ""
    ax.set_title(title or f"shot {obs.shot_id}: {result.status}{flags}", fontsize=8)


def save_analysis_figure(obs, result, path, product_ground=None) -> None:
    """One shot's analysis figure as a PNG."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(4.5, 6.0))
    plot_analysis(ax, obs, result, product_ground)
    ax.legend(fontsize=7, loc="upper right")
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
