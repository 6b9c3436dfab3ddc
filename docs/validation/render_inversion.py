"""Sections of real-data inversions (``studies/real_inversion.py``): the posteriors against
the products, instrument by instrument, with the shots that have long reference runs, the
parameters left at their prior and, from the compact rows the study publishes
(``per_shot``), a per-shot figure of RH98 against the product's and a per-shot table."""

from pathlib import Path

import numpy as np

from .render import _cell, difference_table, literal, provenance, table

#: Shots above which the section draws the figure only, without the table.
TABLE_ROWS = 40


def per_shot_section(rows, figures: Path, key: str, instrument: str) -> str:
    """The figure of posterior RH98 against the product's (moved into the model's
    convention), shot by shot, and, for up to :data:`TABLE_ROWS` shots, their table."""
    if not rows:
        return ""
    name = f"{key}-{instrument}-rh98.png"
    shown = _rh98_figure(rows, figures / name, instrument)
    text = ""
    if shown:
        text += (
            f".. image:: {name}\n   :width: 650\n   :alt: {instrument.upper()} posterior RH98 "
            "against the product's, shot by shot\n\n"
        )
    if len(rows) <= TABLE_ROWS:
        text += _table(rows, instrument) + "\n"
    return text


def _median(row, quantity):
    values = row["posterior"].get(quantity)
    return None if values is None else values[1]


def _table(rows, instrument) -> str:
    product = "L2A" if instrument == "gedi" else "L2"
    header = [
        "shot",
        "storeys",
        f"{product} RH98 (m)",
        f"RH98 in {product}'s convention (m)",
        f"{product} RH98 in the model's convention (m)",
        "model RH98, 5/50/95 % (m)",
        "footprint RH98 (m)",
        f"ground − {product}'s (m)",
        "converged",
        "flags",
    ]
    body = []
    for row in sorted(rows, key=lambda r: (r["product"]["rh98"] is None, r["product"]["rh98"])):
        ground = _median(row, "ground")
        product_ground = row["product"]["ground"]
        difference = (
            None if ground is None or product_ground is None else round(ground - product_ground, 2)
        )
        model = row["posterior"].get("rh98")
        body.append(
            [
                row["shot"],
                row["cohorts"],
                row["product"]["rh98"],
                _median(row, "rh98_product"),
                row["product"].get("rh98_model_convention"),
                "–" if model is None else "/".join(_cell_m(v) for v in model),
                _median(row, "rh98_footprint"),
                difference,
                row["converged"],
                "; ".join(row["flags"]) or "–",
            ]
        )
    title = f"{instrument.upper()} shots by the product's RH98"
    return table(header, body, title)


def _model_convention(row):
    """The product's RH98 moved into the model's convention (as published in rows that
    lack it)."""
    product = row["product"]
    moved = product.get("rh98_model_convention")
    return product["rh98"] if moved is None else moved


def _cell_m(value) -> str:
    return "–" if value is None else f"{value:.1f}"


def _rh98_figure(rows, path: Path, instrument) -> bool:
    """Model and footprint RH98 (median, 90 % interval for the model) against the
    product's in the same convention; orange where a warning flag is on (the row's ``warned``:
    :attr:`lidarinv.inference.InversionResult.warnings`), hollow where the run did not
    converge.
    False where no shot has a product RH98."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = [r for r in rows if _model_convention(r) is not None and "rh98" in r["posterior"]]
    if not rows:
        return False
    x = np.array([_model_convention(r) for r in rows], float)
    model = np.array([[np.nan if v is None else v for v in r["posterior"]["rh98"]] for r in rows])
    footprint = np.array([_median(r, "rh98_footprint") for r in rows], float)
    colour = np.where([r.get("warned", False) for r in rows], "tab:orange", "tab:blue")
    converged = np.array([r["converged"] for r in rows])
    fig, ax = plt.subplots(figsize=(6.5, 4.6))
    ax.errorbar(x, model[:, 1], yerr=[model[:, 1] - model[:, 0], model[:, 2] - model[:, 1]],
                fmt="none", ecolor="0.7", lw=0.8, zorder=1)  # fmt: skip
    for series, marker, label in ((model[:, 1], "o", "model waveform"),
                                  (footprint, "s", "footprint")):  # fmt: skip
        for done, face in ((True, None), (False, "none")):
            keep = converged == done
            ax.scatter(x[keep], series[keep], marker=marker, s=22, zorder=3,
                       edgecolors=colour[keep], facecolors=colour[keep] if face is None else face,
                       label=f"{label}{'' if done else ', not converged'}")  # fmt: skip
    values = np.concatenate([x, model[np.isfinite(model)], footprint[np.isfinite(footprint)]])
    limits = [values.min() - 1.0, values.max() + 1.0]
    ax.plot(limits, limits, "k-", lw=0.6)
    ax.set_xlabel(f"{instrument.upper()} product RH98, in the model's convention (m)")
    ax.set_ylabel("posterior RH98 (m): median; the model's 90 % interval")
    ax.set_title(
        "blue: no warning; orange: a warning flag (misfit, canopy height, ground, step\n"
        "cap); hollow: stopped at the step cap",
        fontsize=8,
    )
    legend = ax.legend(fontsize=7, loc="upper left")
    for handle in getattr(legend, "legend_handles", []):  # shapes, not flags
        handle.set_edgecolor("0.4")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return True


def render_real_inversion(record, figures: Path, key: str) -> str:
    """Posteriors of real shots against the products (``studies/real_inversion.py``)."""
    s = record["summary"]
    text = (
        "Posterior medians against the products; *inside* is how often the product lies in "
        "the 90 % interval, *widened* in it widened by 1 m (the products' own errors are of "
        "that size); ``rh98_model_convention`` compares the posterior's RH98 (of the model "
        "waveform) with the product's moved by what the product's RH convention adds on the "
        "shot's own waveform; ``rh98_product`` is the posterior's RH98 in the product's "
        "convention (each sample's expected recorded waveform between the shot's signal end "
        "and start; on LVIS the noise level spread over that extent dominates it, so it "
        "says more about the extent than about the canopy); ``rh98_footprint`` is the RH98 "
        "of the footprint's own waveform (the expected one plus the discrepancy drawn given "
        "the data), in the model's convention, and ``rh98_footprint_model_convention`` sets "
        "it beside the product's moved into that convention. *Far off* counts the shots "
        "whose median lies more than 3 m (ground) or 5 m (RH98) from the product, and *no "
        "warning* those of them that carry no warning flag (misfit, canopy height, ground "
        "ambiguous in the posterior or hidden, terrain outlier, stopped at the step cap: "
        "``InversionResult.warnings``): wrong answers that pass as clean.\n\n"
    )
    if s.get("priors"):
        text += f"Priors file: ``{' '.join(s['priors'].split())}``.\n\n"
    for instrument in ("gedi", "lvis"):
        part = s.get(instrument)
        if not part:
            continue
        text += (
            f"**{instrument.upper()}.** {part['inverted']} of {part['shots']} shots inverted, "
            f"{part['converged']} converged (the rest flagged: "
            f"{part['not_converged_flagged']}); median {_cell(part.get('median_seconds'))} s "
            f"a shot, 90th percentile {_cell(part.get('p90_seconds'))} s."
        )
        if part.get("median_cpu_seconds") is not None:
            text += (
                f" CPU time of the inverting process (what one core of its own would take, "
                f"whatever else shared the machine): median {_cell(part['median_cpu_seconds'])} "
                f"s, 90th percentile {_cell(part.get('p90_cpu_seconds'))} s."
            )
        if part.get("median_residual_scale") is not None:
            text += (
                f" Misfit flagged on {part.get('misfit_flagged')}; residuals "
                f"{_cell(part['median_residual_scale'])}× the modelled scatter at the median "
                f"shot, {_cell(part.get('p90_residual_scale'))}× at the 90th percentile."
            )
        if part.get("misfit_local") is not None:
            text += (
                f" Flagged as a misfit on any count: {part.get('misfit_any_flag')} shots, "
                f"{part['misfit_local']} of them by the local check (a stretch of the waveform "
                f"whose residual sum leaves the replicated spread)."
            )
        floor = part.get("median_instrument_floor")
        if part.get("model_error_raised") or floor is not None:  # runs that had the raise
            text += (
                f" The instrument model's error was raised above its least value on "
                f"{part['model_error_raised']} shots"
                + (f" (median η {_cell(floor)} of the signal per bin)." if floor else ".")
            )
        if part.get("median_realisation_spread") is not None:
            text += (
                " Another draw of the discrepancy's realisations would move the quantiles "
                f"(the largest over the reported quantities, by bootstrap) by "
                f"{_cell(part['median_realisation_spread'])} posterior sd at the median shot, "
                f"{_cell(part.get('p90_realisation_spread'))} at the 90th percentile."
            )
        if part.get("two_cohorts_bic_over_10") is not None:
            text += (
                f" {part['two_cohorts']} shots chose two height cohorts, "
                f"{part['two_cohorts_bic_over_10']} of them with a BIC lower by more than 10."
            )
        text += "\n\n"
        differences = {q: d for q, d in part.items() if isinstance(d, dict) and "median_abs" in d}
        coverage = {"inside": "inside_90", "widened": "inside_90_widened",
                    "far off": "far_off", "far off, no warning": "far_off_unwarned"}  # fmt: skip
        text += difference_table("posterior", differences, coverage) + "\n"
        text += per_shot_section(part.get("per_shot"), figures, key, instrument)
        text += _reference_agreement(part.get("reference_agreement"), instrument)
        text += _prior_dominated(part.get("prior_dominated"), instrument)
    return text + provenance(record)


def _prior_dominated(counts, instrument) -> str:
    """Per parameter, the shots whose posterior stayed at its prior."""
    if not counts or not counts.get("compared"):
        return ""
    if not counts["shots"]:
        return f"No parameter stayed at its prior on any of the {counts['compared']} shots.\n\n"
    body = [[literal(name), n, n / counts["compared"]] for name, n in counts["shots"].items()]
    title = (
        f"{instrument.upper()} parameters whose posterior stayed at their prior, of "
        f"{counts['compared']} shots"
    )
    return table(["parameter", "shots", "share"], body, title) + "\n"


def _reference_agreement(rows, instrument) -> str:
    """The shots with a long reference run: CPU time against the largest quantile error."""
    if not rows:
        return ""
    header = ["shot", "CPU (s)", "steps", "stopped on the rule", "same posterior",
              "largest quantile error (sd)", "reference's own error (sd)"]  # fmt: skip
    body = [[r["shot"], r["cpu_seconds"], r["steps"], r["converged"],
             r.get("same_posterior_as_reference"), r.get("max_error_sd"),
             r.get("reference_error_sd")] for r in rows]  # fmt: skip
    title = f"{instrument.upper()} shots with a long reference run (inverted with its seed)"
    return table(header, body, title) + "\n"
