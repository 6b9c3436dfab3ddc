"""Inversion of real GEDI and LVIS shots against the NASA products of the same shots.

Inverts every quality shot of the real files with default settings (GEDI: L2A
``quality_flag == 1``; LVIS: the shots in the L2 file) and compares the posterior ground,
RH98 and cover with GEDI L2A/L2B and LVIS L2: median |posterior median − product|, how
often the product lies inside the 90 % interval (and inside it widened by 1 m, the size
of the products' own published errors: L2A ground RMSE about 1.4 m), convergence and wall
time. Writes ``studies/output/real_inversion{tag}/`` with ``summary.json``, ``shots.json``
(one record a shot), ``rh98.png`` (posterior RH98 against the product's, with intervals)
and ``predictive_*.png`` (typical, worst and multi-layer shots). LVIS shots are also
reported per flight line (the ``LFID`` the file gives each shot), so that the tall line
stands apart; every LVIS shot's fit is drawn as it finishes (``shots/shot_<id>.png``:
waveform, both ground candidates of the analysis, the product's ground, the fit and its
residuals), and the summary names each line's worst shots and copies their figures
(``worst_<lfid>_<rank>.png``). Each instrument's summary also lists every shot in one
compact row (``per_shot``: :func:`real_inversion_table.shot_rows`), from which the
validation page draws its per-shot figure and table. ``shots.json`` is
rewritten after every shot, so a run stopped early keeps what it finished;
``--skip-shots`` and ``--max-shots`` split a file's shots into runs that ``--combine``
joins. At default settings, a shot that has a long reference run
(``studies/reference_posteriors.py``, ``tests/data/reference_posteriors.json``) is
inverted with the reference's seed, so that both sample one posterior; its record and
the summary's ``reference_agreement`` give the CPU time against the largest distance of
its 5/50/95 % quantiles from the reference's, in posterior sd, and ``time_vs_error.png``
plots them.

    python studies/real_inversion.py [--data ../shared/data/real | examples]
                                     [--instrument gedi lvis] [--skip-shots N]
                                     [--max-shots N]
                                     [--max-steps 20000] [--walkers 128] [--workers 1]
                                     [--seed 1] [--priors FILE] [--cohorts 1|2|auto]
                                     [--tag _NAME]

Two runs of the same shots (e.g. ``--walkers 64`` against the default) are compared shot
by shot with ``studies/compare_runs.py``.
"""

import json
import time
from collections import Counter
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import harness
import numpy as np
from real_inversion_figures import predictive_figures, rh98_figure, shot_figure
from real_inversion_table import shot_rows, warned
from reference_posteriors import STORE as REFERENCE_STORE
from speed_real_shots import plot_time_vs_error, read_store, reference_agreement

from lidarinv.inference.passes.model_error import MISFIT_FLAG, MODEL_ERROR_FLAG
from lidarinv.inference.results.footprint import CANOPY_HEIGHT_FLAG, STAND_RH98_FLAG
from lidarinv.inference.results.realisation_spread import largest_spread
from lidarinv.io import iter_observations, read_gedi_l2a, read_gedi_l2b, read_lvis_l2
from lidarinv.observe import Observation, analyse

HERE = Path(__file__).resolve().parent
#: Comparisons: label → (posterior quantity, product value). ``rh98`` is the model
#: waveform's RH98; ``rh98_model_convention`` the product's moved by what its convention
#: adds on the shot's own waveform; ``rh98_product`` the posterior's RH98 in the product's
#: convention (:func:`lidarinv.inference.results.product_metrics.product_relative_heights`);
#: ``rh98_footprint`` the RH98 of the footprint's own waveform, the expected one plus the
#: discrepancy drawn given the data (:mod:`lidarinv.inference.likelihood.conditional`).
QUANTITIES = {
    "ground": ("ground", "ground"),
    "rh98": ("rh98", "rh98"),
    "rh98_model_convention": ("rh98", "rh98_model_convention"),
    "rh98_footprint": ("rh98_footprint", "rh98"),
    "rh98_footprint_model_convention": ("rh98_footprint", "rh98_model_convention"),
    "rh98_product": ("rh98_product", "rh98"),
    "cover": ("cover", "cover"),
}
#: Margin (m) by which a height interval is widened before asking if it holds the
#: product: the products' own errors are of that size.
WIDENING_M = 1.0
#: Posterior medians this far from the product (m) count as wrong answers, which should
#: carry a warning (:attr:`lidarinv.inference.InversionResult.warnings`): three times the products' own
#: errors for the ground (L2A's RMSE is about 1.4 m), and for RH98 five metres, beyond the
#: conventions' differences that the model-convention comparisons leave.
FAR_OFF_M = {"ground": 3.0, "rh98_model_convention": 5.0, "rh98_product": 5.0,
             "rh98_footprint_model_convention": 5.0}  # fmt: skip
#: Worst shots (by |ground − product|) of each LVIS flight line named in the summary.
WORST_SHOTS = 4


def _files(data: str) -> dict:
    from real_products import data_files as product_files

    return product_files(data)


def products(files) -> dict:
    """{(instrument, shot): product values} for the comparison."""
    out = {}
    l2a, l2b = read_gedi_l2a(files["gedi-l2a"]), read_gedi_l2b(files["gedi-l2b"])
    for shot, a in l2a.items():
        if a["quality_flag"] != 1:
            continue
        b = l2b.get(shot, {})
        out[("gedi", shot)] = {
            "ground": float(a["elev_lowestmode"]),
            "rh98": float(a["rh"][98]),
            "cover": float(b.get("cover", np.nan)),
        }
    for shot, record in read_lvis_l2(files["lvis-l2"]).items():
        out[("lvis", shot)] = {
            "ground": float(record["zg"]),
            "rh98": float(record["rh"][98]),
            "cover": np.nan,
        }
    return out


def invert_one(job):
    """One shot: its posterior summary against the product, or why it failed, and against
    its long reference run where the job carries one."""
    obs, product, sampler, seed, priors, cohorts = job[:6]
    figures = job[6] if len(job) > 6 else None
    reference = job[7] if len(job) > 7 else None
    from dataclasses import replace

    from lidarinv.inference import InversionSettings, invert_shot

    settings = InversionSettings() if priors is None else InversionSettings.from_priors_file(priors)
    if sampler:  # SamplerSettings changes: the step cap, the walkers
        settings = replace(settings, sampler=replace(settings.sampler, **sampler))
    if cohorts is not None:
        settings = replace(settings, cohorts=cohorts if cohorts == "auto" else int(cohorts))
    record = {"shot": obs.shot_id, "instrument": obs.instrument, "product": product}
    if "lfid" in obs.metadata:  # the LVIS flight line, as the file gives it
        record["lfid"] = str(obs.metadata["lfid"])
    analysis = analyse(obs)
    offset = convention_offset(obs, analysis)
    record["product"] = {**product, "rh98_model_convention": product["rh98"] + offset}
    record["analysis"] = {"status": analysis.status, "ground": analysis.ground,
                          "rh98": None if analysis.rh is None else float(analysis.rh[98]),
                          "n_modes": analysis.n_modes, "flags": analysis.flags,
                          "ground_alternative": analysis.ground_alternative}  # fmt: skip
    start, cpu = time.perf_counter(), time.process_time()
    try:
        result = invert_shot(obs, settings, rng=np.random.default_rng(seed))
    except ValueError as error:
        record.update(error=str(error), seconds=time.perf_counter() - start)
        return record, None
    record["seconds"] = time.perf_counter() - start
    # the worker's own CPU time: what one dedicated core takes, whatever else shares them
    record["cpu_seconds"] = time.process_time() - cpu
    record["converged"] = result.converged
    record["flags"] = list(result.flags)
    record["steps"] = int(result.diagnostics.get("n_steps", 0))
    record["cohorts"] = result.settings["cohorts"]
    # BIC(one cohort) − BIC(two) at their MAPs; NaN where two storeys were not searched
    bic = result.diagnostics.get("cohorts", {}).get("bic", {})
    record["bic_two_cohorts_gain"] = float(bic[1] - bic[2]) if 2 in bic else np.nan
    record["predictive_p_value"] = result.diagnostics["predictive_p_value"]
    record["residual_scale"] = result.diagnostics.get("residual_scale", np.nan)
    record["instrument_floor"] = float(result.diagnostics.get("instrument_floor", np.nan))
    # how far another draw of the discrepancy's realisations moves the quantiles (sd)
    record["realisation_spread"] = largest_spread(result.diagnostics)
    needed = result.diagnostics.get("model_error_needed")
    record["model_error_needed"] = float("nan") if needed is None else float(needed)
    record["misfit"] = any(f.startswith(MISFIT_FLAG) for f in result.flags)
    record["prior_dominated"] = result.prior_dominated  # left at their prior by the data
    for name in ("local_z", "local_threshold", "local_window_m"):  # the local misfit check
        if name in result.diagnostics:
            record[name] = result.diagnostics[name]
    if "ground_modes" in result.diagnostics:  # the evidence for each of two grounds
        record["ground_modes"] = result.diagnostics["ground_modes"]
    if "recentring" in result.diagnostics:  # a following discrepancy's centre
        record["recentring"] = result.diagnostics["recentring"]
    if "realisations" in result.diagnostics:  # asked, simulated, the first ones' spread
        record["realisations"] = result.diagnostics["realisations"]
    # the chain's draws, or importance draws from a t fitted to its early steps
    record["sampling"] = result.diagnostics.get("sampling", "chain")
    record["importance_tries"] = result.diagnostics.get("importance_tries", [])
    if reference is not None:
        record["reference"] = reference_agreement(result, reference)
    canopy = result.footprint_canopy()
    if canopy is not None:
        record["no_tree_probability"] = canopy["no_tree_probability"]
    record["posterior"] = {}
    names = {"ground": "ground_elevation", "rh98": "rh98", "rh98_product": "rh98_product",
             "rh98_footprint": "rh98_footprint", "cover": _cover_name(result),
             "rh50": "rh50", "rh50_product": "rh50_product",
             "canopy_height": "footprint_top_height"}  # fmt: skip
    for quantity, name in names.items():
        values = result.column(name) if name else np.array([])
        q = np.percentile(values, (5, 50, 95)) if values.size else np.full(3, np.nan)
        record["posterior"][quantity] = [float(v) for v in q]
    if figures is not None and record.get("lfid") is not None:
        shot_figure(result, record, figures / f"shot_{obs.shot_id}.png")
    return record, result


def convention_offset(obs, analysis) -> float:
    """RH98 of the shot's own waveform in the posterior's convention (the energy above the
    noise, unsmoothed, as the model waveform's) minus RH98 in the product's convention
    (GEDI L2A: smoothed; LVIS L2: recorded counts, noise included): what the product's
    convention adds, measured on the shot (NaN where the analysis has no RH)."""
    if analysis.rh is None:
        return np.nan
    from dataclasses import replace

    from lidarinv.observe import processing_settings

    model = replace(processing_settings(obs.instrument), rh_energy="above-noise", rh_smoothed=False)
    plain = analyse(obs, model)
    return float(plain.rh[98] - analysis.rh[98]) if plain.rh is not None else np.nan


def _cover_name(result):
    """The posterior's gap-based cover if it has one, else its crown cover."""
    names = set(result.quantity_names)
    for name in ("gap_cover", "cover"):
        if name in names:
            return name
    return None


def statistics(records, instrument, per_shot=True) -> dict:
    rows = [r for r in records if r["instrument"] == instrument]
    done = [r for r in rows if "posterior" in r]
    out = {
        "shots": len(rows),
        "inverted": len(done),
        "failed": {str(r["shot"]): r["error"] for r in rows if "error" in r},
        "converged": int(sum(r["converged"] for r in done)),
        "not_converged_flagged": int(sum((not r["converged"]) and bool(r["flags"]) for r in done)),
        "median_seconds": _percentile_of(done, "seconds", 50),
        "p90_seconds": _percentile_of(done, "seconds", 90),
        "median_cpu_seconds": _percentile_of(done, "cpu_seconds", 50),
        "p90_cpu_seconds": _percentile_of(done, "cpu_seconds", 90),
        "two_cohorts": int(sum(r.get("cohorts") == 2 for r in done)),
        # two storeys chosen with "very strong" evidence (Kass & Raftery 1995: ΔBIC > 10),
        # among the shots whose run recorded the gain (None where none did)
        "two_cohorts_bic_over_10": _count_over(done, "bic_two_cohorts_gain", 10.0),
        "misfit_flagged": int(sum(r.get("predictive_p_value", 1.0) < 0.01 for r in done)),
        # the fit needs a model error above the ceiling, or fails its predictive check
        "misfit_any_flag": int(sum(bool(r.get("misfit")) for r in done)),
        # residual sums over a stretch of the waveform beyond their replicated spread
        "misfit_local": int(
            sum(abs(r.get("local_z", 0.0)) > r.get("local_threshold", np.inf) for r in done)
        ),
        # where the error was sized at all (not on a window with censored samples)
        "model_error_above_ceiling": int(
            sum(
                r.get("model_error_needed", 0.0) > 0.5
                and np.isfinite(r.get("instrument_floor", np.nan))
                for r in done
            )
        ),
        "contradictions_unflagged": _contradictions(done),
        "model_error_raised": _count_flagged(done, MODEL_ERROR_FLAG),
        # the footprint's tallest stem far below its own waveform's RH98 in most draws
        "canopy_height_below_rh98": _count_flagged(done, CANOPY_HEIGHT_FLAG),
        # the expected stand's RH98 far below the footprint's own in most draws
        "stand_rh98_below_footprint": _count_flagged(done, STAND_RH98_FLAG),
        "median_instrument_floor": _percentile_of(done, "instrument_floor", 50),
        # a following discrepancy centred on the fixed covariance's optimum, not the pilot
        "centred_on_refound": int(
            sum(r.get("recentring", {}).get("chosen") == "refound" for r in done)
        ),
        # per parameter, the shots whose posterior stayed at its prior (records made
        # before the comparison existed have none)
        "prior_dominated": _prior_dominated_counts(done),
        "median_residual_scale": _percentile_of(done, "residual_scale", 50),
        # the first share of the realisations sufficed (the rest were not simulated)
        "first_realisations_sufficed": int(
            sum(
                r["realisations"]["simulated"] < r["realisations"]["asked"]
                for r in done
                if "realisations" in r
            )
        ),
        # the shots whose importance draws ended the run (not the chain's rule)
        "importance_sampled": int(sum(r.get("sampling") == "importance" for r in done)),
        "median_realisation_spread": _percentile_of(done, "realisation_spread", 50),
        "p90_realisation_spread": _percentile_of(done, "realisation_spread", 90),
        "p90_residual_scale": _percentile_of(done, "residual_scale", 90),
        # CPU time against the quantiles' largest error from the shot's long reference run
        "reference_agreement": [
            {
                "shot": str(r["shot"]),
                "cpu_seconds": r["cpu_seconds"],
                "steps": r["steps"],
                "converged": r["converged"],
                **r["reference"],
            }
            for r in done
            if "reference" in r
        ],
    }
    if per_shot:  # one compact row a shot: the validation page's per-shot figure and table
        out["per_shot"] = shot_rows(done)
    for q, (name, key) in QUANTITIES.items():
        triples = [
            (r["posterior"][name], r["product"][key], r)
            for r in done
            if name in r["posterior"]
            and np.isfinite(r["product"][key])
            and np.all(np.isfinite(r["posterior"][name]))
        ]
        if not triples:
            continue
        d = np.array([post[1] - prod for post, prod, _ in triples])
        widen = 0.0 if q == "cover" else WIDENING_M
        inside = [post[0] <= prod <= post[2] for post, prod, _ in triples]
        widened = [post[0] - widen <= prod <= post[2] + widen for post, prod, _ in triples]
        out[q] = {
            "n": len(triples),
            "median": float(np.median(d)),
            "median_abs": float(np.median(np.abs(d))),
            "p90_abs": float(np.percentile(np.abs(d), 90)),
            "max_abs": float(np.max(np.abs(d))),
            "inside_90": float(np.mean(inside)),
            "inside_90_widened": float(np.mean(widened)),
        }
        if q in FAR_OFF_M:  # wrong answers, and those that pass without a warning
            far = [r for post, prod, r in triples if abs(post[1] - prod) > FAR_OFF_M[q]]
            out[q]["far_off_m"] = FAR_OFF_M[q]
            out[q]["far_off"] = len(far)
            out[q]["far_off_unwarned"] = sum(not warned(r["flags"]) for r in far)
    return out


def _prior_dominated_counts(done) -> dict:
    """Per parameter, the shots where the posterior stayed at the prior, of those
    compared."""
    compared = [r for r in done if "prior_dominated" in r]
    counts = Counter(name for r in compared for name in r["prior_dominated"])
    return {"compared": len(compared), "shots": dict(counts.most_common())}


def _contradictions(done) -> int:
    """Shots without a flag whose posterior median contradicts itself in the product's
    convention (the model waveform's where a record lacks it): RH50 below the ground, or
    no cover under an RH98 above 5 m."""
    count = 0
    for r in done:
        p, missing = r["posterior"], [np.nan] * 3
        rh50 = p.get("rh50_product", p.get("rh50", missing))[1]
        rh98 = p.get("rh98_product", p.get("rh98", missing))[1]
        bare = p.get("cover", missing)[1] == 0.0 and rh98 > 5.0
        count += int((rh50 < 0.0 or bare) and not r["flags"])
    return count


def flight_lines(records, out=None) -> dict:
    """The LVIS statistics per flight line (the file's LFID), with each line's worst
    shots; their figures copied to ``out`` where they were drawn."""
    import shutil

    lines = {}
    for lfid in sorted({r["lfid"] for r in records if r.get("lfid") is not None}):
        members = [r for r in records if r.get("lfid") == lfid]
        stats = statistics(members, "lvis", per_shot=False)  # the instrument's hold them
        rh98 = [r["product"]["rh98"] for r in members if np.isfinite(r["product"]["rh98"])]
        stats["product_rh98_median"] = float(np.median(rh98)) if rh98 else None
        done = [r for r in members if "posterior" in r]
        if done:
            ground = [r["posterior"]["ground"][1] - r["product"]["ground"] for r in done]
            near = [abs(d) <= 1.0 or bool(r["flags"]) for d, r in zip(ground, done)]
            stats["ground_within_1m_or_flagged"] = float(np.mean(near))
        order = sorted(
            done, key=lambda r: -abs(r["posterior"]["ground"][1] - r["product"]["ground"])
        )
        worst = []
        for rank, r in enumerate(order[:WORST_SHOTS]):
            entry = {"shot": r["shot"], "ground_error": r["posterior"]["ground"][1]
                     - r["product"]["ground"], "flags": r["flags"]}  # fmt: skip
            figure = None if out is None else out / "shots" / f"shot_{r['shot']}.png"
            if figure is not None and figure.exists():
                entry["figure"] = f"worst_{lfid}_{rank + 1}.png"
                shutil.copy(figure, out / entry["figure"])
            worst.append(entry)
        stats["worst"] = worst
        lines[lfid] = stats
    return lines


def main(argv=None):
    parser = harness.parser(__doc__, seed=1, workers=1)
    parser.add_argument("--data", default=str(HERE.parent.parent / "shared" / "data" / "real"))
    parser.add_argument("--instrument", nargs="+", default=["gedi", "lvis"])
    parser.add_argument("--skip-shots", type=int, default=0,
                        help="leave out an instrument's first N quality shots")  # fmt: skip
    parser.add_argument("--max-shots", type=int, help="at most this many shots an instrument")
    parser.add_argument("--max-steps", type=int, help="sampler step cap (default: settings')")
    parser.add_argument("--walkers", type=int, help="ensemble walkers (default: settings')")
    parser.add_argument("--priors", type=Path, help="priors file (default settings without)")
    parser.add_argument("--cohorts", choices=("1", "2", "auto"), help="height cohorts")
    parser.add_argument(
        "--combine", nargs="+", metavar="TAG",
        help="write one summary of earlier runs (their --tag) instead of inverting",
    )  # fmt: skip
    args = parser.parse_args(argv)
    if args.skip_shots < 0:
        parser.error(f"--skip-shots must be ≥ 0, got {args.skip_shots}")
    if args.combine:
        return combine(args.combine, harness.output_folder("real_inversion", args.tag))
    files = _files(args.data)
    wanted = products(files)
    out = harness.output_folder("real_inversion", args.tag)
    jobs = []
    # shots with a long reference run are inverted with its seed, at default settings only
    sampler = {"max_steps": args.max_steps, "n_walkers": args.walkers}
    sampler = {name: value for name, value in sampler.items() if value is not None}
    default = args.priors is None and not sampler and args.cohorts is None
    references = read_store(REFERENCE_STORE) if default else {}
    for instrument in args.instrument:
        shots = [o for o in iter_observations(files[f"{instrument}-l1b"])
                 if isinstance(o, Observation) and (instrument, o.shot_id) in wanted]  # fmt: skip
        seeds = np.random.SeedSequence(args.seed).spawn(len(shots))
        end = args.skip_shots + args.max_shots if args.max_shots else len(shots)
        for o, s in list(zip(shots, seeds))[args.skip_shots : end]:
            reference = references.get(f"{instrument}:{o.shot_id}")
            seed = s if reference is None else reference["seed"]  # the same posterior
            jobs.append((o, wanted[(instrument, o.shot_id)], sampler, seed, args.priors,
                         args.cohorts, out / "shots", reference))  # fmt: skip
    print(f"{len(jobs)} shots to invert")
    records, results = [], {}
    with ProcessPoolExecutor(args.workers) as pool:
        for record, result in pool.map(invert_one, jobs):
            records.append(record)
            results[(record["instrument"], record["shot"])] = result
            post = record.get("posterior", {})
            print(f"{record['instrument']} {record['shot']}: {record.get('error', '')}"
                  f"{'' if not post else _line(record)}", flush=True)  # fmt: skip
            _write_shots(out, records)
    summary = {
        "data": {k: Path(v).name for k, v in files.items()},
        "max_steps": args.max_steps,
        "walkers": args.walkers,
        "priors": None if args.priors is None else args.priors.read_text(),
        "cohorts": args.cohorts,
        **{i: statistics(records, i) for i in args.instrument},
        "lvis_flight_lines": flight_lines(records, out),
    }
    _write(out, summary, records)
    predictive_figures(records, results, out)
    print(json.dumps(summary, indent=1, default=float))
    print(f"wrote {out}")


def combine(tags, out) -> None:
    """One summary, shot list and RH98 figure of earlier runs (e.g. the instruments run
    apart, or part of a file run again), with their predictive figures. A shot in more
    than one run keeps the record of the last tag that holds it."""
    import shutil

    out.mkdir(parents=True, exist_ok=True)
    by_shot, summary = {}, {"combined": list(tags), "data": {}}
    for tag in tags:
        folder = harness.OUTPUT / f"real_inversion{tag}"
        done = folder / "summary.json"
        part = json.loads(done.read_text()) if done.exists() else {"stopped_early": True}
        summary["data"].update(part.get("data", {}))
        for key in ("max_steps", "priors", "cohorts", "stopped_early"):
            if key in part:
                summary.setdefault(key, part[key])
        for record in json.loads((folder / "shots.json").read_text()):
            by_shot[record["instrument"], record["shot"]] = record
        for figure in folder.glob("predictive_*.png"):
            if folder.resolve() != out.resolve():
                shutil.copy(figure, out / figure.name)
    records = list(by_shot.values())
    for instrument in sorted({r["instrument"] for r in records}):
        summary[instrument] = statistics(records, instrument)
    for tag in tags:  # the per-shot figures, for the flight lines' worst shots
        for figure in (harness.OUTPUT / f"real_inversion{tag}" / "shots").glob("*.png"):
            if figure.parent.parent.resolve() != out.resolve():
                (out / "shots").mkdir(exist_ok=True)
                shutil.copy(figure, out / "shots" / figure.name)
    summary["lvis_flight_lines"] = flight_lines(records, out)
    _write(out, summary, records)
    print(f"wrote {out}")


def _write(out, summary, records) -> None:
    """The run's summary, its shots, the figure of RH98 against the product and, where
    shots have reference runs, of CPU time against the error from them."""
    harness.write_json(out / "summary.json", summary)
    _write_shots(out, records)
    rh98_figure(records, out / "rh98.png")
    agreed = [{"variant": "default settings", "instrument": r["instrument"],
               "cpu_seconds": r["cpu_seconds"], **r["reference"]}
              for r in records if "reference" in r]  # fmt: skip
    if agreed:
        plot_time_vs_error(agreed, ["default settings"], out / "time_vs_error.png")


def _write_shots(out, records) -> None:
    (out / "shots.json").write_text(json.dumps(records, indent=1, default=_json))


def _count_flagged(records, prefix) -> int:
    """Records with a flag that begins with ``prefix``."""
    return int(sum(any(f.startswith(prefix) for f in r["flags"]) for r in records))


def _count_over(records, key, threshold):
    """How many records hold a value of ``key`` above ``threshold``; None where none
    holds the key."""
    values = [r[key] for r in records if key in r]
    return int(sum(v > threshold for v in values)) if values else None


def _percentile_of(records, key, percentile):
    """A percentile of the records' finite values of ``key``; None where none has one."""
    values = [r[key] for r in records if np.isfinite(r.get(key, np.nan))]
    return float(np.percentile(values, percentile)) if values else None


def _line(record) -> str:
    p, q = record["posterior"], record["product"]
    return (
        f"ground {p['ground'][1]:.2f} ({q['ground']:.2f}), RH98 {p['rh98'][1]:.2f} "
        f"[{p['rh98'][0]:.2f}, {p['rh98'][2]:.2f}] ({q['rh98']:.2f}), cover {p['cover'][1]:.2f} "
        f"({q['cover']:.2f}), {record['seconds']:.1f} s, "
        f"{'converged' if record['converged'] else 'NOT converged'}"
    )


def _json(value):
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    raise TypeError(type(value).__name__)


if __name__ == "__main__":
    main()
