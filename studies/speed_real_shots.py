"""Real shots against long reference runs, for ``studies/inversion_speed.py --data``.

Each named shot is inverted under every stopping rule asked for; where the reference
store (``studies/reference_posteriors.py``) holds the shot, the run uses the reference's
seed, so that both sample the same prepared posterior, and the reported quantities'
5/50/95 % quantiles are compared with the reference's in its posterior sd. Time per shot
is plotted against that agreement (the time-versus-error curve of issue 46).
"""

import json
import time
from dataclasses import replace
from pathlib import Path

import harness
import numpy as np

from forward.expected import NUMERICS_REVISION
from lidarinv.inference import invert_shot
from lidarinv.inference.results.realisation_spread import largest_spread
from lidarinv.inference.results.reported import REPORTED

#: Quantities whose quantiles are compared with the reference runs: those the stopping
#: rule monitors, and RH98 in the product's convention.
AGREEMENT_QUANTITIES = (*REPORTED, "rh98_product")
#: Quantiles (%) compared.
AGREEMENT_QUANTILES = (5, 50, 95)


def reported_quantiles(result) -> dict:
    """{name: {"quantiles": 5/50/95 %, "sd": posterior sd}} of the compared quantities a
    result has."""
    out = {}
    for name in AGREEMENT_QUANTITIES:
        if name not in result.quantity_names:
            continue
        values = result.column(name)
        values = values[np.isfinite(values)]
        if values.size > 1:
            q = np.percentile(values, AGREEMENT_QUANTILES)
            out[name] = {"quantiles": [float(v) for v in q], "sd": float(np.std(values))}
    return out


def agreement(run: dict, reference: dict) -> dict:
    """|run − reference| of each quantity's 5/50/95 % quantiles, in the reference's
    posterior sd ({name: [three values]}); quantities the reference holds fixed (sd 0)
    are left out."""
    out = {}
    for name, ref in reference.items():
        if name in run and ref["sd"] > 0:
            pairs = zip(run[name]["quantiles"], ref["quantiles"])
            out[name] = [abs(a - b) / ref["sd"] for a, b in pairs]
    return out


def real_observations(data, instrument, ids):
    """The shots ``ids`` of an instrument's L1B file among the real files (in the
    order given), refusing ids the file does not hold."""
    from real_products import data_files as product_files

    from lidarinv.io import iter_observations
    from lidarinv.observe import Observation

    path = product_files(data)[f"{instrument}-l1b"]
    wanted = [int(i) for i in ids]
    found = {
        o.shot_id: o
        for o in iter_observations(path)
        if isinstance(o, Observation) and o.shot_id in wanted
    }
    missing = [i for i in wanted if i not in found]
    if missing:
        raise SystemExit(f"{path}: no shot(s) {missing}")
    return [found[i] for i in wanted]


def stopping_variants(rules, min_taus, quantile_mcse=(None,)) -> dict:
    """{name: SamplerSettings changes} for each stopping rule asked for (one ``ess-rhat``
    variant per ``min_taus`` and ``quantile_mcse`` value)."""
    out = {}
    for rule in rules:
        if rule == "tau":
            out["tau"] = {"stop_rule": "tau"}
            continue
        for m in min_taus:
            for mcse in quantile_mcse:
                name = f"{rule}-{m:g}tau" + ("" if mcse is None else f"-mcse{mcse:g}")
                out[name] = {"stop_rule": rule, "min_taus": m, "quantile_mcse_max": mcse}
    return out


def _timed_result(obs, settings, seed):
    """One inversion: its result, wall and CPU seconds."""
    start, cpu = time.perf_counter(), time.process_time()
    result = invert_shot(obs, settings, rng=np.random.default_rng(seed))
    return result, time.perf_counter() - start, time.process_time() - cpu


def posterior_identity(result) -> dict:
    """What decides which posterior a run sampled, as :func:`compare_with_reference` checks
    it against a reference: the stand model's cohorts, the discrepancy's realisation
    count, the tallest-stem latent and the instrument model's error."""
    return {
        "cohorts": result.settings.get("cohorts"),
        "realisations": result.settings.get("realisations", {}).get("count"),
        "tallest_stem": bool(result.settings.get("tallest_stem")),
        "instrument_floor": result.diagnostics.get("instrument_floor"),
    }


def _run_record(result, seconds, cpu_seconds) -> dict:
    d = result.diagnostics
    return {
        "seconds": seconds,
        "cpu_seconds": cpu_seconds,
        "steps": int(d["n_steps"]),
        "burn": int(d["burn"]),
        "converged": result.converged,
        **posterior_identity(result),
        # how far another draw of the discrepancy's realisations moves the quantiles (sd)
        "realisation_spread": largest_spread(result.diagnostics),
        "quantities": {  # ESS, R̂ and τ of the monitored quantities
            name: {k: v for k, v in q.items()} for name, q in d.get("quantities", {}).items()
        },
        "flags": [f for f in result.flags if f.startswith("not converged")],
        "reported": reported_quantiles(result),
    }


def run_real(args, settings) -> dict:
    """Each real shot under each stopping variant, against its reference
    (``studies/reference_posteriors.py``) where the store holds one: the run then uses
    the reference's seed, so that both sample the same prepared posterior; or that seed
    plus ``args.seed_offset``, so that the posterior is prepared again (another MAP
    search and another set of discrepancy realisations)."""
    shots = [
        *real_observations(args.data, "gedi", args.gedi_shots or []),
        *real_observations(args.data, "lvis", args.lvis_shots or []),
    ]
    variants = stopping_variants(args.stop_rule, args.min_taus, args.quantile_mcse)
    if args.seed_offset:  # another preparation: a variant of its own in the table
        variants = {f"{name}-seed+{args.seed_offset}": c for name, c in variants.items()}
    store = read_store(args.reference_file)
    rows = []
    folder = harness.output_folder("inversion_speed", args.tag)
    seeds_of_shots = np.random.SeedSequence(args.seed).spawn(len(shots))
    for obs, seeds in list(zip(shots, seeds_of_shots))[args.skip_shots :]:
        reference = store.get(f"{obs.instrument}:{obs.shot_id}")
        run_seed = seeds if args.reference_seed is None else args.reference_seed
        run_seed = run_seed if reference is None else reference["seed"] + args.seed_offset
        for name, changes in variants.items():
            sampler = replace(settings.sampler, **changes)
            result, seconds, cpu = _timed_result(obs, replace(settings, sampler=sampler), run_seed)
            row = {"shot": str(obs.shot_id), "instrument": obs.instrument, "variant": name}
            row.update(_run_record(result, seconds, cpu))
            if reference is not None:
                compare_with_reference(row, reference)
            rows.append(row)
            compare_with_tau_rule(rows, obs.shot_id)
            brief = {k: row.get(k) for k in ("shot", "variant", "cpu_seconds", "steps",
                                             "converged", "max_error_sd", "max_error_vs_tau_sd",
                                             "flags")}  # fmt: skip
            print(json.dumps(brief), flush=True)
            harness.write_json(folder / "summary.json", {"shots": rows})
    return write_summary(rows, variants, store, folder)


def read_store(path) -> dict:
    """A JSON store of reference runs ({} where there is none yet)."""
    path = Path(path)
    return json.loads(path.read_text()) if path.exists() else {}


def write_summary(rows, variants, store: dict, folder) -> dict:
    """The variants' table, the runs and the references they were compared with, written
    to ``folder/summary.json`` with the time-versus-error figure; returns the summary."""
    summary = {"variants": variant_table(rows, variants), "shots": rows,
               "references": held_references(store, rows)}  # fmt: skip
    harness.write_json(folder / "summary.json", summary)
    plot_time_vs_error(rows, variants, folder / "time_vs_error.png")
    return summary


def compare_with_reference(row: dict, reference: dict) -> None:
    """Add a run's quantile errors against its reference (``error_sd``, ``max_error_sd``)."""
    floor, reference_floor = row["instrument_floor"], reference["instrument_floor"]
    same_count = row.get("realisations") == reference.get("realisations", row.get("realisations"))
    # records without a revision predate it: revision 1
    same_model = reference.get("numerics_revision", 1) == NUMERICS_REVISION
    # records without the latent's flag predate it being on for two storeys: off
    same_model &= row.get("tallest_stem", False) == reference.get("tallest_stem", False)
    row["same_posterior_as_reference"] = (
        row["cohorts"] == reference["cohorts"]
        and same_count
        and same_model
        and (floor == reference_floor or bool(np.isclose(floor, reference_floor, rtol=1e-3)))
    )
    row["error_sd"] = agreement(row["reported"], reference["reported"])
    row["reference_error_sd"] = max(reference["reference_error_sd"].values(), default=np.nan)
    row["max_error_sd"] = largest_error(row["error_sd"])


def reference_agreement(result, reference: dict) -> dict:
    """A result's quantile errors against its shot's reference run
    (:func:`compare_with_reference`): ``same_posterior_as_reference``, ``error_sd``,
    ``max_error_sd`` and the reference's own ``reference_error_sd``."""
    identity = posterior_identity(result)
    row = {**identity, "reported": reported_quantiles(result)}
    compare_with_reference(row, reference)
    return {key: value for key, value in row.items() if key not in identity and key != "reported"}


def largest_error(errors: dict) -> float:
    """The largest of :func:`agreement`'s quantile errors (NaN for none)."""
    values = [e for quantiles in errors.values() for e in quantiles]
    return float(np.max(values)) if values else np.nan


def held_references(store: dict, rows) -> dict:
    """The store's records of the shots in ``rows``."""
    shots = {f"{r['instrument']}:{r['shot']}" for r in rows}
    return {key: record for key, record in store.items() if key in shots}


def compare_with_tau_rule(rows, shot_id):
    """Each variant's quantile errors against the ``tau`` rule's run of the same shot and
    seed (``error_vs_tau_sd``): what the stopping rule alone changes, the start the same."""
    same = [r for r in rows if r["shot"] == str(shot_id)]
    baseline = [r for r in same if r["variant"] == "tau"]
    if not baseline:
        return
    for row in same:
        if row["variant"] != "tau":
            row["error_vs_tau_sd"] = agreement(row["reported"], baseline[0]["reported"])
            row["max_error_vs_tau_sd"] = largest_error(row["error_vs_tau_sd"])


def variant_table(rows, variants) -> dict:
    """Per variant and instrument: median CPU and wall seconds, the share converged, and
    the median and largest quantile error (reference sd) over the runs that sampled their
    reference's posterior (``same_posterior_as_reference`` not False; ``compared``)."""
    out = {}
    for name in variants:
        for instrument in sorted({r["instrument"] for r in rows}):
            picked = [r for r in rows if r["variant"] == name and r["instrument"] == instrument]
            if not picked:
                continue
            same = [r for r in picked if r.get("same_posterior_as_reference") is not False]
            errors = [r.get("max_error_sd", np.nan) for r in same] or [np.nan]
            against_tau = [r.get("max_error_vs_tau_sd", np.nan) for r in picked]
            out[f"{name} {instrument}"] = {
                "shots": len(picked),
                "compared": len(same),
                "median_cpu_seconds": float(np.median([r["cpu_seconds"] for r in picked])),
                "median_seconds": float(np.median([r["seconds"] for r in picked])),
                "converged_fraction": float(np.mean([r["converged"] for r in picked])),
                "median_max_error_sd": float(np.median(errors)),
                "max_error_sd": float(np.max(errors)),
                "median_max_error_vs_tau_sd": float(np.median(against_tau)),
                "max_error_vs_tau_sd": float(np.max(against_tau)),
            }
    return out


def plot_time_vs_error(rows, variants, path):
    """CPU seconds per shot against the largest quantile error (reference sd; against the
    ``tau`` rule's run of the shot where there is no reference run), one colour a stopping
    variant, one marker an instrument: the time-versus-error curve."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 4), constrained_layout=True)
    markers = {"gedi": "o", "lvis": "s"}
    for k, name in enumerate(variants):
        for instrument, marker in markers.items():
            picked = [r for r in rows if r["variant"] == name and r["instrument"] == instrument]
            for key, against, fill in (("max_error_sd", "long run", f"C{k}"),
                                       ("max_error_vs_tau_sd", "tau rule", "none")):  # fmt: skip
                error = np.array([r.get(key, np.nan) for r in picked], float)
                kept = np.isfinite(error)
                if np.any(kept):
                    ax.scatter(np.array([r["cpu_seconds"] for r in picked])[kept], error[kept],
                               facecolors=fill, edgecolors=f"C{k}", marker=marker,
                               label=f"{name}, {instrument}, against the {against}")  # fmt: skip
    ax.axhline(0.2, color="k", lw=0.8, ls="--")
    ax.set_xscale("log")
    ax.set_xlabel("CPU time per shot (s, one core)")
    ax.set_ylabel("largest |quantile − reference's| (posterior sd)")
    ax.legend(fontsize=7)
    fig.savefig(path, dpi=120)
    plt.close(fig)
