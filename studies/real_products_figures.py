"""Figures of ``studies/real_products.py``: our direct metrics against the products', and
the waveforms of typical, worst and multi-mode shots."""

import numpy as np


def scatter_figure(gedi_records, lvis_records, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 4, figsize=(15, 7.5))
    panels = (("ground", "ground − product (m)"), ("rh50", "RH50 (m)"), ("rh98", "RH98 (m)"))
    for row, (name, records) in enumerate((("GEDI", gedi_records), ("LVIS", lvis_records))):
        for col, (q, label) in enumerate(panels):
            ax = axes[row, col]
            ours = np.array([r["ours"][q] for r in records])
            theirs = np.array([r["product"][q] for r in records])
            if q == "ground":
                ax.hist(ours - theirs, bins=np.linspace(-1.5, 1.5, 31), color="0.4")
                ax.set_xlabel(f"{name}: lidarinv ground − product ground (m)")
                ax.set_ylabel("shots")
                continue
            ax.plot(theirs, ours, ".", ms=4)
            lim = [np.nanmin([ours, theirs]) - 1, np.nanmax([ours, theirs]) + 1]
            ax.plot(lim, lim, "k-", lw=0.6)
            ax.set_xlabel(f"{name} product {label}")
            ax.set_ylabel(f"lidarinv {label}")
        ax = axes[row, 3]
        if name == "GEDI":
            ours = [r["ours"]["cover"] for r in records]
            ax.plot([r["product"]["cover"] for r in records], ours, ".", ms=4)
            ax.plot([0, 1], [0, 1], "k-", lw=0.6)
            ax.set_xlabel("GEDI L2B cover")
            ax.set_ylabel("lidarinv cover (ρv/ρg = 1.5)")
        else:
            ax.axis("off")
    fig.suptitle("lidarinv direct metrics against the NASA products (quality shots)")
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def waveform_figure(examples, path):
    """Typical, worst and multi-mode shots of each instrument, marks and product ground."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from lidarinv.observe.figures import plot_analysis

    fig, axes = plt.subplots(1, len(examples), figsize=(3.4 * len(examples), 6.5), squeeze=False)
    for ax, (label, obs, result, product_ground) in zip(axes[0], examples):
        plot_analysis(ax, obs, result, product_ground, title=f"{label}\nshot {obs.shot_id}")
    axes[0, 0].legend(fontsize=6, loc="upper right")
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def tall_line_figure(rows, l2, lines, path, n_worst=6):
    """The worst shots (largest |ground − ZG|) of the flight line with the tallest canopy:
    waveform, chosen ground, its alternative and the L2 ZG."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from lidarinv.observe.figures import plot_analysis

    tall = max(lines, key=lambda k: np.nan_to_num(lines[k]["product_rh98_median"]))
    scored = [
        (abs(result.ground - l2[shot]["zg"]), obs, result, l2[shot]["zg"])
        for obs, result, _, shot in rows
        if obs is not None and str(obs.metadata.get("lfid")) == tall
        and result is not None and np.isfinite(result.ground) and shot in l2
    ]  # fmt: skip
    worst = sorted(scored, key=lambda item: -item[0])[:n_worst]
    if not worst:
        return tall
    fig, axes = plt.subplots(1, len(worst), figsize=(3.4 * len(worst), 6.5), squeeze=False)
    for ax, (error, obs, result, zg) in zip(axes[0], worst):
        flags = ", ".join(result.flags) or "no flag"
        title = f"shot {obs.shot_id}: {result.status}\n{flags}\n|ground − ZG| {error:.2f} m"
        plot_analysis(ax, obs, result, zg, title=title)
        low = np.nanmin([result.ground, result.ground_alternative, zg])
        ax.set_ylim(low - 8.0, result.signal_start + 5.0)
    axes[0, 0].legend(fontsize=6, loc="upper right")
    fig.suptitle(f"LVIS flight line {tall} (tallest canopy): worst shots against L2 ZG")
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return tall
