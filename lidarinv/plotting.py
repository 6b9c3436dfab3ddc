"""Figures: waveforms beside their crown-volume profiles, as in Sun & Ranson Fig. 1 and 6,
and the labels every figure of the package writes units with."""

import re

import numpy as np

__all__ = ["QUANTITY_NAMES", "plot_waveforms", "quantity_label", "unit_label"]

_SUPERSCRIPTS = str.maketrans("-0123456789", "⁻⁰¹²³⁴⁵⁶⁷⁸⁹")

#: Names printed for quantities in figures (others: the name with spaces).
QUANTITY_NAMES = {
    "cover": "crown cover",
    "pai": "PAI",
    "lai": "LAI",
    "favd": "FAVD",
    "rho_ratio": "ρv/ρg",
    "rh50": "RH50",
    "rh98": "RH98",
}


def unit_label(units: str) -> str:
    """Units as every figure writes them: ``"m2/m2"`` → ``"m² m⁻²"``, ``"m3/m2/m"`` →
    ``"m³ m⁻² m⁻¹"``, ``"stems/ha"`` → ``"stems ha⁻¹"``; ``"1"`` or ``""`` (no units) → ``""``."""
    if units in ("", "1", None):
        return ""
    parts = units.split("/")
    out = []
    for i, part in enumerate(parts):
        match = re.fullmatch(r"([A-Za-z]+)(-?\d*)", part.strip())
        if match is None:
            out.append(part)
            continue
        name, power = match.groups()
        power = int(power) if power else 1
        power = -power if i > 0 else power
        out.append(name + ("" if power == 1 else str(power).translate(_SUPERSCRIPTS)))
    return " ".join(out)


def quantity_label(name: str, units: str = "") -> str:
    """``"top height (m)"``, ``"PAI (m² m⁻²)"``, ``"crown cover"``: an axis label."""
    text = QUANTITY_NAMES.get(name, name.replace("_", " "))
    label = unit_label(units)
    return f"{text} ({label})" if label else text


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
        ax.set_xlabel("normalised to its maximum")
        ax.set_title(f"({wf.center[0]:.0f}, {wf.center[1]:.0f}) m", fontsize=9)
        ax.grid(alpha=0.3)
    for ax in axes[:, 0]:
        ax.set_ylabel(f"height above ground ({unit_label('m')})")
    for ax in axes.ravel()[n:]:
        ax.set_visible(False)
    axes[0, 0].legend(fontsize=7, loc="upper right")
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
