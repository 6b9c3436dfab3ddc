"""Tables, figures and sections of the validation pages, one renderer per kind of study
summary (:data:`.generate.PAGES` names which renderer each section takes)."""

from pathlib import Path

from .labels import LABELS

#: Binomial 95 % range of a coverage, computed where a summary lacks it.
LEVELS = ("68", "90")


def _cell(value) -> str:
    if value is None:
        return "–"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, float):
        return f"{value:.4g}"
    if isinstance(value, list | tuple):
        return ", ".join(_cell(v) for v in value)
    return str(value).replace("|", "/")


def literal(name) -> str:
    """A quantity's name as the code and the posterior files spell it."""
    return f"``{name}``"


def label(key) -> str:
    """The page's words for a summary key (:data:`LABELS`)."""
    return LABELS.get(key, str(key).replace("_", " "))


def table(header, rows, title="") -> str:
    """An rst list-table."""
    lines = [f".. list-table:: {title}".rstrip(), "   :header-rows: 1", ""]
    for row in [header, *rows]:
        lines.append(f"   * - {_cell(row[0])}")
        lines += [f"     - {_cell(value)}" for value in row[1:]]
    return "\n".join(lines) + "\n"


def provenance(record) -> str:
    return (
        f"Measured with ``{record['command']}`` (summary ``{record['source']}``, commit "
        f"``{record['commit']}``, published {record['published']}; the figures are those "
        "of that run on the machine it ran on).\n"
    )


def missing(key, how) -> str:
    return (
        ".. note::\n\n"
        f"   No summary published for ``{key}`` yet. Run ``{how}``, then "
        f'``python studies/publish.py {key} --command "..."`` and rebuild the docs.\n'
    )


# -- renderers: summary → rst (and figures) ---------------------------------------------


def render_coverage(record, figures: Path, key: str) -> str:
    """Recovery and calibration (``studies/recovery.py``): coverage, centring, errors."""
    s = record["summary"]
    quantities = s.get("quantities", {})
    if not quantities:
        return f"The run inverted {s.get('n_inverted', 0)} shots: nothing to show.\n"
    ranges = s.get("binomial_95_range", {})
    text = (
        f"{s['n_inverted']} of {s['n_shots']} shots inverted; "
        f"{_cell(s.get('converged_fraction'))} of the chains reached 50 τ; median "
        f"{_cell(s.get('median_seconds_per_shot'))} s a shot. Truths drawn from "
        f"``{s.get('truth', '?')}``; explicit stands: {_cell(s.get('explicit_realisations'))}.\n\n"
    )
    ground = quantities.get("ground_elevation", {})
    if "missed_90_hidden_ground_flagged" in ground:
        missed = round((1.0 - ground["coverage_90"]) * ground["n"])
        text += (
            f'{s["hidden_ground_flagged"]} shots are flagged "ground may be hidden" (their '
            "lowest return is wider than a ground return); "
            f"{ground['missed_90_hidden_ground_flagged']} of the {missed} ground elevations "
            "outside their 90 % interval carry that flag.\n\n"
        )
    outside = {n: q for n, q in quantities.items() if q.get("outside_prior_support")}
    for name, q in outside.items():
        count, rest = q["outside_prior_support"], q["n"] - q["outside_prior_support"]
        text += (
            f"{count} true values of ``{name}`` lie outside its prior's support, where no "
            f"interval can hold them; the 90 % coverage of the other {rest} is "
            f"{_cell(q['coverage_90_inside_support'])}.\n\n"
        )
    if ranges:
        text += (
            "A coverage is consistent with its nominal level when it lies in the binomial "
            f"95 % range for this many shots: {_cell(ranges.get('68'))} at 68 %, "
            f"{_cell(ranges.get('90'))} at 90 %. z is the truth minus the posterior median "
            "over half the 68 % interval: median 0 and spread 1 when calibrated.\n\n"
        )
    header = [
        "quantity",
        "68 % coverage",
        "90 % coverage",
        "z median",
        "z spread",
        "bias",
        "RMSE",
        "direct metric RMSE",
    ]
    rows = [
        [
            literal(name),
            q.get("coverage_68"),
            q.get("coverage_90"),
            q.get("z_median"),
            q.get("z_spread"),
            q.get("bias"),
            q.get("rmse"),
            q.get("direct_rmse"),
        ]
        for name, q in quantities.items()
    ]
    text += table(header, rows) + "\n"
    figure = _coverage_figure(quantities, ranges, figures / f"{key}.png")
    text += f".. image:: {figure}\n   :width: 600\n   :alt: coverage per quantity\n\n"
    if s.get("by_kind"):
        text += _coverage_by_kind(s["by_kind"])
    return text + provenance(record)


def _coverage_by_kind(by_kind) -> str:
    """The 90 % coverage of each quantity per stand kind (out-of-family truths)."""
    names = list(dict.fromkeys(n for part in by_kind.values() for n in part.get("quantities", {})))
    rows = []
    for kind, part in by_kind.items():
        ranges = part.get("binomial_95_range", {}).get("90")
        quantities = part.get("quantities", {})
        rows.append(
            [
                kind,
                f"{part.get('n_inverted', 0)} of {part.get('n_shots', 0)}",
                ranges,
                part.get("converged_fraction"),
                *(quantities.get(n, {}).get("coverage_90") for n in names),
            ]
        )
    header = ["stand kind", "inverted", "binomial 95 % range", "converged", *map(literal, names)]
    return (
        "Per stand kind, the share of the truths inside the 90 % intervals (a few shots "
        "each: read it against the binomial range):\n\n" + table(header, rows) + "\n"
    )


def difference_table(ours, differences, extra) -> str:
    """A table of differences from a product: one row a quantity ({name: its summary}),
    the columns shared by the product studies and then ``extra`` ({header: key})."""
    header = ["quantity", "shots", f"median ({ours} − product)", "median |d|", "90th pct |d|"]
    keys = ["n", "median", "median_abs", "p90_abs", *extra.values()]
    rows = [[literal(q), *(d.get(k) for k in keys)] for q, d in differences.items()]
    return table([*header, *extra], rows)


def render_real_products(record, figures: Path, key: str) -> str:
    """Direct metrics against the NASA products (``studies/real_products.py``)."""
    s = record["summary"]
    text = ""
    names = {"gedi": "GEDI against L2A and L2B (L2A quality shots)", "lvis": "LVIS against L2"}
    for instrument, title in names.items():
        part = s.get(instrument)
        if not part:
            continue
        statuses = ", ".join(f"{k} {v}" for k, v in part.get("statuses", {}).items())
        flags = ", ".join(f"{k} {v}" for k, v in part.get("flags", {}).items()) or "none"
        text += (
            f"**{title}.** {part['shots']} shots; statuses: {statuses}; flags: {flags}; "
            f"median {_cell(part.get('seconds_per_shot'))} s a shot.\n\n"
        )
        differences = part.get("differences", {})
        text += difference_table("ours", differences, {"within 1 m": "within_1m"}) + "\n"
    ratio = s.get("gedi", {}).get("cover_ratio")
    if ratio:
        text += (
            "Cover takes ρv/ρg = 1.5, the ratio of GEDI L2B's own ρv and ρg (median in the "
            f"file {_cell(ratio.get('product_ratio_median'))}), so the assumed ratio carries "
            "none of the cover difference; the rest comes from how each estimates the ground "
            "energy. Had the ratio been 1 or 2, the median cover would have been "
            f"{_cell(ratio.get('median_cover_at_1'))} or {_cell(ratio.get('median_cover_at_2'))}"
            f" instead of {_cell(ratio.get('median_cover_at_1_5'))}.\n\n"
        )
    return text + provenance(record)


def _coverage_figure(quantities, ranges, path: Path) -> str:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = list(quantities)
    fig, ax = plt.subplots(figsize=(7.0, 3.2))
    for offset, level, colour in ((-0.15, "68", "tab:blue"), (0.15, "90", "tab:green")):
        x = [i + offset for i in range(len(names))]
        values = [quantities[n].get(f"coverage_{level}") for n in names]
        ax.plot(x, values, "o", color=colour, label=f"{level} % intervals")
        if level in ranges:
            ax.axhspan(*ranges[level], color=colour, alpha=0.15, lw=0)
        ax.axhline(int(level) / 100, color=colour, ls="--", lw=0.8)
    ax.set_xticks(
        range(len(names)), [n.replace("_", " ") for n in names], rotation=30, ha="right", fontsize=8
    )
    ax.set_ylabel("coverage (fraction of shots)")
    ax.set_title(
        "coverage of the credible intervals; dashed: nominal; bands: binomial 95 % ranges",
        fontsize=9,
    )
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path.name


def render_speed(record, figures: Path, key: str) -> str:
    """Inversion speed (``studies/inversion_speed.py``): wall time to convergence."""
    s = record["summary"]
    configs = {k: v for k, v in s.items() if isinstance(v, dict) and "median_seconds" in v}
    rows = [
        [
            name,
            c["median_seconds"],
            c.get("median_cpu_seconds"),
            c["within_target_fraction"],
            c["median_ms_per_step"],
            c["converged_fraction"],
            len(c.get("shots", [])),
        ]
        for name, c in configs.items()
    ]
    header = ["configuration", "median run (s)", "median CPU (s)", "within 10 s", "ms a step",
              "converged", "runs"]  # fmt: skip
    text = table(header, rows) + "\n"
    for name, c in configs.items():
        shots = c.get("shots", [])
        if shots:
            wanted = ("shot", "seconds", "cpu_seconds", "steps", "max_tau", "converged")
            keys = [k for k in wanted if k in shots[0]]
            header = [label(k) for k in keys]
            text += table(header, [[r.get(k) for k in keys] for r in shots], f"runs of {name}")
            text += "\n"
    settings = {k: v for k, v in s.items() if not isinstance(v, dict)}
    if settings:
        text += table(["setting", "value"], [[label(k), v] for k, v in settings.items()]) + "\n"
    return text + provenance(record)


def render_forward_accuracy(record, figures: Path, key: str) -> str:
    """The explicit engine's error and time per stand kind (``forward_runtime_vs_error``)."""
    s = record["summary"]
    kinds = s.get("kinds")
    if not kinds:
        return render_generic(record, figures, key)
    target = s.get("target", {})
    text = (
        f"Targets: relative L1 ≤ {_cell(target.get('relative_l1'))} and ground energy within "
        f"{_cell(target.get('ground'))} (relative) at ≤ {_cell(target.get('ms_per_footprint'))}"
        " ms a GEDI footprint on one core. Errors are against a converged run, as mean / max "
        "over the footprints; ``old`` is the per-crown quadrature of earlier versions, "
        "``new`` the column engine at the tolerance given, ``*`` the default.\n\n"
    )
    header = ["stand", "engine", "setting", "L1 mean", "L1 max", "ground mean", "ground max",
              "ms a footprint"]  # fmt: skip
    rows = []
    for name, kind in kinds.items():
        for row in kind["rows"]:
            mark = " *" if row.get("is_default") else ""
            rows.append([name, row["engine"], f"{row['setting']}{mark}",
                         row.get("relative_l1_mean"), row.get("relative_l1_max"),
                         row.get("ground_error_mean"), row.get("ground_error_max"),
                         row.get("ms_per_footprint")])  # fmt: skip
    return text + table(header, rows) + "\n" + provenance(record)


def render_batch(record, figures: Path, key: str) -> str:
    """Batch throughput (``studies/batch_throughput.py``), real or stand-in inversion."""
    s = record["summary"]
    text = ""
    if s.get("fake_delay_s") is not None:
        text = (
            f"A stand-in inversion (``tests/fake_inversion.py``, {_cell(s['fake_delay_s'])} s "
            "a shot) measures the batch machinery alone: what a batch adds to each shot over "
            "a plain loop (pool, scheduling, one HDF5 group stored and flushed a shot), and "
            "the coordinator's ceiling, the most shots an hour one ``batch`` process can "
            "store however many workers it has. A real shot's own time is in the section "
            "above; a batch of real shots takes it plus this overhead, per worker.\n\n"
        )
    if "orbit_hours_formula" in s:  # in words, below
        text += (
            "An orbit's hours on c worker cores: its shots × max(core-seconds a shot / c, "
            "the coordinator's seconds to store a shot) / 3600, since one coordinating "
            "process stores every shot.\n\n"
        )
        s = {k: v for k, v in s.items() if k != "orbit_hours_formula"}
    return text + render_generic({**record, "summary": s}, figures, key)


def render_generic(record, figures: Path, key: str) -> str:
    """Any summary: its scalars, its flat sections and its lists of records as tables."""
    s = record["summary"]
    text = ""
    scalars = [[label(k), v] for k, v in s.items() if not isinstance(v, dict | list)]
    if scalars:
        text += table(["field", "value"], scalars) + "\n"
    for name, value in s.items():
        text += _section(name, value)
    return text + provenance(record)


def _records(value) -> bool:
    return isinstance(value, list) and bool(value) and all(isinstance(v, dict) for v in value)


def _section(name, value) -> str:
    """A summary's section: a flat dict as fields, a list of records as a table, or a dict
    of both (a study's part: its rows, then its scalars)."""
    if _records(value):
        keys = [k for k in value[0] if not isinstance(value[0][k], dict | list)]
        rows = [[row.get(k) for k in keys] for row in value]
        return table([label(k) for k in keys], rows, label(name)) + "\n"
    if not isinstance(value, dict):
        return ""
    flat = [[label(k), v] for k, v in value.items() if not isinstance(v, dict | list)]
    flat += [[label(k), v] for k, v in value.items() if isinstance(v, list) and not _records(v)]
    parts = [v for v in value.values() if _records(v)]
    if not parts:
        return table(["field", "value"], flat, label(name)) + "\n" if flat else ""
    text = f"**{label(name)}**\n\n"
    for part in parts:
        keys = [k for k in part[0] if not isinstance(part[0][k], dict | list)]
        text += table([label(k) for k in keys], [[r.get(k) for k in keys] for r in part]) + "\n"
    if flat:
        text += table(["field", "value"], flat) + "\n"
    return text
