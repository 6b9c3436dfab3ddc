"""Figures of ``studies/real_inversion.py``: a shot's fit with its grounds, posterior
RH98 against the products', and the typical, worst and most layered shots' fits."""

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np


def shot_figure(result, record, path) -> None:
    """The fit and its residuals (:func:`lidarinv.inference.results.plots.predictive_plot`)
    with the analysis's ground candidates, the posterior's ground and the product's."""
    from lidarinv.inference.results.plots import predictive_plot

    path.parent.mkdir(parents=True, exist_ok=True)
    fig = predictive_plot(result, None)
    analysis = record["analysis"]
    lines = (
        (analysis["ground"], "analysis ground", "tab:green", "-"),
        (analysis.get("ground_alternative", np.nan), "alternative ground", "tab:olive", ":"),
        (record["posterior"]["ground"][1], "posterior ground (median)", "tab:purple", "--"),
        (record["product"]["ground"], "product ground", "k", "-."),
    )
    for ax in fig.axes:
        for height, label, colour, style in lines:
            if height is not None and np.isfinite(height):
                ax.axhline(height, color=colour, ls=style, lw=0.9, label=label)
    fig.axes[0].legend(fontsize=6, loc="upper right")
    fig.suptitle(f"shot {result.shot_id} (line {record.get('lfid')}): fit, residuals, grounds",
                 fontsize=10)  # fmt: skip
    fig.savefig(path, dpi=80)
    plt.close(fig)


def rh98_figure(records, path):
    """Posterior RH98 (median and 90 % interval) against each instrument's product."""
    fig, axes = plt.subplots(1, 2, figsize=(10, 4.5))
    for ax, instrument in zip(axes, ("gedi", "lvis")):
        done = [r for r in records if r["instrument"] == instrument and "posterior" in r]
        done = [r for r in done if np.isfinite(r["product"]["rh98"])]
        if not done:
            ax.set_axis_off()
            continue
        x = np.array([r["product"]["rh98"] for r in done])
        colour = ["tab:blue" if r["converged"] else "tab:red" for r in done]
        series = (("rh98", "o", "model waveform"), ("rh98_footprint", "s", "footprint"))
        spans = [x]
        for name, marker, label in series:
            p = np.array([r["posterior"].get(name, [np.nan] * 3) for r in done])
            if not np.any(np.isfinite(p)):
                continue
            ax.errorbar(x, p[:, 1], yerr=[p[:, 1] - p[:, 0], p[:, 2] - p[:, 1]], fmt="none",
                        ecolor="0.6", lw=0.8)  # fmt: skip
            ax.scatter(x, p[:, 1], c=colour, s=14, marker=marker, zorder=3, label=label)
            spans.append(p[np.isfinite(p)])
        values = np.concatenate(spans)
        lim = [values.min() - 1, values.max() + 1]
        ax.plot(lim, lim, "k-", lw=0.6)
        legend = ax.legend(fontsize=8, title="RH98 of the", title_fontsize=8)
        for handle in getattr(legend, "legend_handles", []):  # shapes, not convergence
            handle.set_color("0.4")
        ax.set_xlabel(f"{instrument.upper()} product RH98 (m)")
        ax.set_ylabel("posterior RH98: median and 90 % interval (m)")
        ax.set_title(f"{instrument.upper()}: red = not converged", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def predictive_figures(records, results, out):
    """The typical and worst shot of each instrument and its most multi-layered one."""
    from lidarinv.inference.results.plots import predictive_plot

    for instrument in ("gedi", "lvis"):
        done = [r for r in records if r["instrument"] == instrument and "posterior" in r]
        if not done:
            continue
        error = [abs(r["posterior"]["ground"][1] - r["product"]["ground"]) for r in done]
        order = np.argsort(error)
        chosen = {"typical": done[order[len(order) // 2]], "worst": done[order[-1]],
                  "layers": max(done, key=lambda r: r["analysis"]["n_modes"])}  # fmt: skip
        for label, record in chosen.items():
            result = results[(instrument, record["shot"])]
            predictive_plot(result, out / f"predictive_{instrument}_{label}.png")
