"""Figures: waveforms beside their crown-volume profiles, as in Sun & Ranson Fig. 1 and 6."""

import numpy as np


def plot_waveforms(waveforms, path, title=""):
    """Waveform (dotted) against the crown-volume profile (solid), each normalised.

    One panel per waveform, heights on the vertical axis, as in the paper's figures.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = len(waveforms)
    cols = min(n, 3)
    rows = int(np.ceil(n / cols))
    fig, axes = plt.subplots(
        rows, cols, figsize=(3.2 * cols, 4.2 * rows), squeeze=False, sharey=True
    )
    for ax, wf in zip(axes.ravel(), waveforms):
        volume = wf.crown_volume / max(wf.crown_volume.max(), 1e-300)
        signal = wf.samples / max(wf.samples.max(), 1e-300)
        ax.plot(volume, wf.heights, "-", color="forestgreen", label="crown volume")
        ax.plot(signal, wf.heights, ":", color="k", lw=1.5, label="waveform")
        ax.plot(
            wf.canopy / max(wf.samples.max(), 1e-300),
            wf.heights,
            "-",
            color="0.6",
            lw=0.8,
            label="canopy part",
        )
        ax.set_xlabel("normalised")
        ax.set_title(f"({wf.center[0]:.0f}, {wf.center[1]:.0f}) m", fontsize=9)
        ax.grid(alpha=0.3)
    for ax in axes[:, 0]:
        ax.set_ylabel("height above ground (m)")
    for ax in axes.ravel()[n:]:
        ax.set_visible(False)
    axes[0, 0].legend(fontsize=7, loc="upper right")
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
