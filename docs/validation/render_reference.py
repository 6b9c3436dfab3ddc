"""Sections against long reference runs (``studies/reference_posteriors.py``): real shots'
time against error (``studies/inversion_speed.py --data``), and sampling coordinates
compared on the same posteriors (``studies/sampling_coordinates.py --reference-file``);
the answer's spread over the seeds that prepare it (``studies/preparation_spread.py``); and
the log-likelihood's steps on real shots (``studies/continuity.py``)."""

from pathlib import Path

import numpy as np

from .render import literal, provenance, table


def render_time_vs_error(record, figures: Path, key: str) -> str:
    """Per stopping variant: CPU time per shot and the largest quantile error against the
    reference runs; then the references themselves."""
    s = record["summary"]
    text = (
        "Each shot is inverted at default settings with the seed of its reference, so that "
        "both sample the same prepared posterior (stand model, simulated discrepancy, "
        "model error). *Error* is the largest distance between a run's quantile and the "
        "reference's, over the 5/50/95 % quantiles of every reported quantity, in the "
        "reference's posterior sd; the target is 0.2 (issue 46). The reference's own error "
        "is its restarts' spread over √restarts, the largest over the quantities. A variant "
        "ending in -seed+K was prepared with the reference's seed plus K: its error also "
        "holds what another MAP search and another set of discrepancy realisations move. "
        "*Same posterior* is no where the reference was sampled with another stand model, "
        "count of realisations, model error or revision of the model's numerics: the error "
        "then holds the change of model, and the variants' errors leave such runs out.\n\n"
    )
    rows = [
        [name, v["shots"], v.get("compared", v["shots"]), v["median_cpu_seconds"],
         v["converged_fraction"], v["median_max_error_sd"], v["max_error_sd"]]
        for name, v in s.get("variants", {}).items()
    ]  # fmt: skip
    header = ["variant, instrument", "shots", "compared", "median CPU (s)",
              "stopped on the rule", "median error (sd)", "largest error (sd)"]  # fmt: skip
    text += table(header, rows) + "\n"
    shots = s.get("shots", [])
    rows = [
        [r["instrument"], r["shot"], r["variant"], r.get("cohorts"), r["cpu_seconds"],
         r["steps"], r["converged"], r.get("same_posterior_as_reference"),
         r.get("max_error_sd"), _worst(r.get("error_sd", {})), r.get("reference_error_sd")]
        for r in shots
    ]  # fmt: skip
    header = ["instrument", "shot", "variant", "storeys", "CPU (s)", "steps", "stopped on the rule",
              "same posterior", "error (sd)", "worst quantity",
              "reference's own error (sd)"]  # fmt: skip
    text += table(header, rows, "runs") + "\n"
    figure = _figure(shots, figures / f"{key}.png")
    if figure:
        text += f".. image:: {figure}\n   :width: 600\n   :alt: CPU time against error\n\n"
    return text + _references_table(s.get("references", {})) + provenance(record)


def render_coordinates_vs_reference(record, figures: Path, key: str) -> str:
    """Per shot and set of sampling coordinates: steps, CPU time, acceptance, the largest
    τ and the largest quantile error against the reference runs."""
    s = record["summary"]
    text = (
        "Each shot is prepared once, as ``invert_shot`` prepares it with its reference's "
        "seed, and that one posterior is sampled to the default stopping rule in each set "
        "of sampling coordinates from the same physical start and generator state: the "
        "posterior is the same, only the coordinates the sampler moves in differ. "
        "``default`` is the run ``invert_shot`` gives. τ is the monitored quantities' "
        "(walkers × steps over ArviZ's bulk ESS after burn-in), in physical units, so it "
        "compares across coordinates. *Error* as in the section above.\n\n"
    )
    rows = []
    for r in s.get("runs", []):
        taus = {name: q["tau"] for name, q in r.get("quantities", {}).items()}
        slowest = max(taus, key=taus.get) if taus else None
        rows.append([
            r["shot"], r.get("cohorts"), r["coordinates"], r["steps"], r["converged"],
            r["cpu_seconds"], r.get("acceptance"),
            None if slowest is None else f"{taus[slowest]:.0f} ({slowest})",
            r.get("max_error_sd"), _worst(r.get("error_sd", {})),
        ])  # fmt: skip
    header = ["shot", "storeys", "coordinates", "steps", "stopped on the rule", "CPU (s)",
              "acceptance", "largest τ (steps)", "error (sd)", "worst quantity"]  # fmt: skip
    text += table(header, rows, "runs") + "\n"
    return text + _references_table(s.get("references", {})) + provenance(record)


def _references_table(references: dict) -> str:
    """The reference runs compared with: restarts, largest τ and their own error."""
    if not references:
        return ""
    rows = [
        [
            r["instrument"],
            r["shot"],
            r["cohorts"],
            f"{r['restarts']} × {r['steps_per_restart']}",
            max(r["largest_tau"]),
            max(r["reference_error_sd"].values()),
            r["cpu_seconds"] / 3600,
        ]
        for r in references.values()
    ]
    header = ["instrument", "shot", "storeys", "restarts × steps", "largest τ (steps)",
              "reference's own error (sd)", "CPU (h)"]  # fmt: skip
    return table(header, rows, "reference runs") + "\n"


def _worst(errors: dict) -> str:
    """The quantity with the largest quantile error."""
    if not errors:
        return "–"
    return max(errors, key=lambda name: max(errors[name]))


def _figure(shots, path: Path) -> str | None:
    """CPU seconds against the largest quantile error, one colour per variant."""
    points = [r for r in shots if r.get("max_error_sd") is not None]
    if not points:
        return None
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.0, 3.6))
    variants = list(dict.fromkeys(r["variant"] for r in points))
    markers = {"gedi": "o", "lvis": "s"}
    for k, variant in enumerate(variants):
        for instrument, marker in markers.items():
            picked = [
                r for r in points if r["variant"] == variant and r["instrument"] == instrument
            ]
            if picked:
                cpu = [r["cpu_seconds"] for r in picked]
                error = [r["max_error_sd"] for r in picked]
                ax.scatter(
                    cpu, error, color=f"C{k}", marker=marker, label=f"{variant}, {instrument}"
                )
    ax.axhline(0.2, color="k", lw=0.8, ls="--")
    ax.set_xscale("log")
    ax.set_xlabel("CPU time per shot (s, one core)")
    ax.set_ylabel("largest quantile error (posterior sd)")
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path.name


def render_preparation_spread(record, figures: Path, key: str) -> str:
    """Per shot and count of realisations: the quantiles' spread over the seeds that
    prepare the posterior, against what the runs stated of themselves."""
    s = record["summary"]
    text = (
        "Each shot is inverted at default settings with several seeds; each seed prepares "
        "the posterior again (another MAP search, other explicit stands for the model "
        "discrepancy) and samples it. *Spread* is the sd over the seeds of a quantity's "
        "5/50/95 % quantiles, the largest of the three, in posterior sd: it holds the "
        "preparation's randomness and the sampler's. *Stated* is what each run said of "
        "itself, averaged over the runs: its realisation spread (bootstrap resamples of its "
        "stands, reweighted) and its quantile Monte Carlo error, in quadrature. Six seeds "
        "measure a spread to about ±30 %.\n\n"
    )
    rows = [
        [r["instrument"], r["shot"], r["count"], len(r["runs"]), r["largest_spread_sd"],
         literal(r["largest_quantity"]), r.get("largest_stated_spread_sd"),
         r["median_cpu_seconds"]]
        for r in s.get("shots", [])
    ]  # fmt: skip
    header = ["instrument", "shot", "stands", "seeds", "largest spread (sd)", "quantity",
              "largest stated (sd)", "median CPU (s)"]  # fmt: skip
    text += table(header, rows, "spread over seeds") + "\n"
    rows = []
    for r in s.get("shots", []):
        for name, spread in r["spread_sd"].items():
            boot = [run.get("realisation_spread", {}).get(name) for run in r["runs"]]
            boot = [b for b in boot if b is not None and np.isfinite(b)]
            rows.append([
                r["shot"], r["count"], literal(name), max(spread),
                r.get("stated_spread_sd", {}).get(name), float(np.mean(boot)) if boot else None,
            ])  # fmt: skip
    header = ["shot", "stands", "quantity", "spread (sd)", "stated (sd)",
              "of which the stands' (sd)"]  # fmt: skip
    return text + table(header, rows, "per quantity") + "\n" + provenance(record)


def render_continuity(record, figures: Path, key: str) -> str:
    """Per shot, the coordinates whose log-likelihood scans stepped most, now and, where
    the summary holds it, at the earlier run set beside it."""
    s = record["summary"]
    settings = s.get("settings", {})
    text = (
        f"Through the MAP and {settings.get('points')} points of its Laplace approximation, "
        "the log-likelihood of each shot is scanned along every sampled coordinate "
        f"({settings.get('scan_points')} points over ±{settings.get('half_width')} in "
        "unbounded units). A *step* is the largest third difference of a scan: near zero "
        "where the log-likelihood is smooth, the jump itself where it jumps. Steps above "
        f"{s.get('threshold')} are what a finite-difference gradient or a sampler meets as "
        "a cliff. *Before* is the same scan at an earlier commit, where the summary holds "
        "it; each shot's three coordinates with the largest steps, now or before, are "
        "shown.\n\n"
    )
    rows = []
    for shot in s.get("shots", []):

        def largest(c):
            return max(c["largest_step"] or 0.0, c.get("largest_step_before") or 0.0)

        worst = sorted(shot["coordinates"], key=largest, reverse=True)[:3]
        for c in worst:
            rows.append([
                shot["instrument"], shot["shot"], shot["cohorts"], literal(c["coordinate"]),
                c["largest_step"], c.get("largest_step_before"),
                f"{c['points_past_threshold']}/{c['points_scanned']}",
            ])  # fmt: skip
    header = ["instrument", "shot", "storeys", "coordinate", "largest step",
              "before", "points past the threshold"]  # fmt: skip
    return (
        text
        + table(header, rows, "the three largest steps of each shot")
        + "\n"
        + provenance(record)
    )
