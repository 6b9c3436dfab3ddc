"""Long reference runs of real shots: the posteriors a faster sampler must agree with.

Usage::

    python studies/reference_posteriors.py --data DATA --gedi-shots ID [ID ...]
        --lvis-shots ID [ID ...] [--restarts 4] [--steps 25000] [--seed 0]
        [--store tests/data/reference_posteriors.json] [--extend]
    python studies/reference_posteriors.py --merge STORE.json ... [--store PATH]

Each shot is prepared once, at default settings, with the generator ``--seed`` (the
stand model's choice, the simulated discrepancy, the instrument model's error and the
MAP start: :func:`lidarinv.inference.prepare_problem`), exactly as
``invert_shot(observation, rng=numpy.random.default_rng(seed))`` prepares it. The
prepared posterior is then sampled ``--restarts`` times, independently, each run for
``--steps`` steps whatever its diagnostics say (issue 46 asks for 100 000 steps or
independent restarts; four restarts of 25 000 steps are both). Per shot the store keeps
the reported quantities' 5/50/95 % quantiles and sd, of each restart and of the restarts
pooled (each quantile averaged over the restarts), the largest difference between a
restart's quantile and the pooled one, and the pooled quantiles' Monte Carlo error (the
restarts' sd over √restarts), both in posterior sd. ``--extend`` adds restarts (with
generators of their own) to a shot the store holds; ``--merge`` joins stores written by
separate calls.

The store (JSON, merged shot by shot so that shots may run in separate calls) is test
data: ``tests/lidarinv/inference/test_reference_posteriors.py`` checks default runs of
the shipped shots against it, and ``studies/inversion_speed.py --reference-file`` can
compare any stopping rule or parameterisation with it.
"""

import harness

harness.pin_threads()

import json  # noqa: E402
import time  # noqa: E402
from dataclasses import replace  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
from speed_real_shots import (  # noqa: E402
    AGREEMENT_QUANTITIES,
    read_store,
    real_observations,
    reported_quantiles,
)

from forward.expected import NUMERICS_REVISION  # noqa: E402
from lidarinv.inference import InversionSettings, prepare_problem, sample_prepared  # noqa: E402
from lidarinv.inference.sampling import ImportanceSettings  # noqa: E402

#: Default store of the references: test data.
STORE = Path(__file__).resolve().parent.parent / "tests" / "data" / "reference_posteriors.json"


def pooled_quantiles(restarts: list) -> dict:
    """{name: {"quantiles", "sd"}}: each quantile and the sd averaged over the restarts
    (equal runs of one posterior), so that restarts added later join the same way."""
    out = {}
    names = set.intersection(*(set(run) for run in restarts))
    for name in [n for n in AGREEMENT_QUANTITIES if n in names]:
        quantiles = np.mean([run[name]["quantiles"] for run in restarts], axis=0)
        sd = float(np.mean([run[name]["sd"] for run in restarts]))
        out[name] = {"quantiles": [float(v) for v in quantiles], "sd": sd}
    return out


def restart_spread(restarts: list, pooled: dict) -> dict:
    """Per quantity, the largest |restart quantile − pooled quantile| in pooled sd."""
    out = {}
    for name, ref in pooled.items():
        if ref["sd"] > 0:
            gaps = [
                abs(a - b) / ref["sd"]
                for run in restarts
                if name in run
                for a, b in zip(run[name]["quantiles"], ref["quantiles"])
            ]
            out[name] = float(max(gaps))
    return out


def largest_tau(result) -> float:
    """The largest τ (steps) of the quantities a run monitored."""
    return float(np.nanmax([q["tau"] for q in result.diagnostics["quantities"].values()]))


def pooled_error(restarts: list, pooled: dict) -> dict:
    """Per quantity, the Monte Carlo error of the pooled quantiles: the restarts' sd about
    each other over √restarts, the largest of the three quantiles, in pooled sd."""
    out = {}
    for name, ref in pooled.items():
        runs = [run[name]["quantiles"] for run in restarts if name in run]
        if ref["sd"] > 0 and len(runs) > 1:
            spread = np.std(runs, axis=0, ddof=1) / np.sqrt(len(runs))
            out[name] = float(np.max(spread) / ref["sd"])
    return out


def finish(record: dict) -> dict:
    """A record with the quantities derived from its restarts' quantiles."""
    restarts = record["restart_reported"]
    record["reported"] = pooled = pooled_quantiles(restarts)
    record["restart_spread_sd"] = restart_spread(restarts, pooled)
    record["reference_error_sd"] = pooled_error(restarts, pooled)
    return record


def long_run_settings(sampler, steps: int):
    """``sampler`` (SamplerSettings) run for ``steps`` steps whatever the chain shows: the
    rule asks for a chain longer than any, and no importance draws are tried."""
    return replace(sampler, max_steps=steps, min_taus=1e9, importance=ImportanceSettings(draws=0))


def reference(observation, seed: int, restarts: int, steps: int, earlier=None) -> dict:
    """One shot's reference: ``restarts`` runs of ``steps`` steps of the posterior that
    ``seed`` prepares, joined to the ``earlier`` record's restarts where given."""
    clock, cpu = time.perf_counter(), time.process_time()
    prepared = prepare_problem(observation, InversionSettings(), np.random.default_rng(seed))
    settings = prepared.problem.settings.sampler
    long_run = long_run_settings(settings, steps)
    first = 0 if earlier is None else earlier["restarts"]
    seeds = np.random.SeedSequence(seed).spawn(first + restarts)[first:]
    results = []
    for k, child in enumerate(seeds):
        results.append(sample_prepared(prepared, np.random.default_rng(child), long_run))
        print(f"  restart {first + k + 1}: {time.perf_counter() - clock:.0f} s", flush=True)
    diagnostics = prepared.diagnostics()
    record = {
        "instrument": observation.instrument,
        "shot": str(observation.shot_id),
        "seed": seed,
        "restarts": first + restarts,
        "steps_per_restart": steps,
        "cohorts": prepared.problem.settings.cohorts,
        "realisations": prepared.problem.settings.realisations.count,
        "numerics_revision": NUMERICS_REVISION,
        "tallest_stem": bool(prepared.problem.settings.tallest_stem),
        "instrument_floor": diagnostics.get("instrument_floor"),
        "draws": int(sum(r.samples.shape[0] for r in results)),
        "largest_tau": [largest_tau(r) for r in results],
        "restart_reported": [reported_quantiles(r) for r in results],
        "seconds": time.perf_counter() - clock,
        "cpu_seconds": time.process_time() - cpu,
    }
    if earlier is not None:
        same = ("seed", "steps_per_restart", "cohorts", "instrument_floor", "realisations",
                "numerics_revision", "tallest_stem")  # fmt: skip
        if any(earlier.get(k) != record[k] for k in same):
            raise SystemExit(f"shot {record['shot']}: the stored reference differs in {same}")
        for key in ("draws", "seconds", "cpu_seconds"):
            record[key] += earlier[key]
        for key in ("largest_tau", "restart_reported"):
            record[key] = earlier[key] + record[key]
    return finish(record)


def main():
    parser = harness.parser(__doc__, seed=0)
    parser.add_argument(
        "--data", help="folder of the real files, or 'examples' for the shipped ones"
    )
    parser.add_argument("--gedi-shots", nargs="*", default=[])
    parser.add_argument("--lvis-shots", nargs="*", default=[])
    parser.add_argument("--restarts", type=int, default=4)
    parser.add_argument("--steps", type=int, default=25_000, help="steps of each restart")
    parser.add_argument("--store", default=str(STORE), help="JSON file the references join")
    parser.add_argument("--extend", action="store_true",
                        help="add the restarts to shots --store holds already")  # fmt: skip
    parser.add_argument("--merge", nargs="+", metavar="STORE",
                        help="join these stores' records into --store (no runs)")  # fmt: skip
    args = parser.parse_args()
    store_path = Path(args.store)
    if args.merge:
        store = read_store(store_path)
        for path in args.merge:
            store.update({k: finish(v) for k, v in json.loads(Path(path).read_text()).items()})
        harness.write_json(store_path, dict(sorted(store.items())))
        return
    if args.data is None:
        raise SystemExit("--data is needed to run references")
    if args.restarts < 2 or args.steps < 1000:
        raise SystemExit("--restarts must be at least 2 and --steps at least 1000")
    shots = [
        *real_observations(args.data, "gedi", args.gedi_shots),
        *real_observations(args.data, "lvis", args.lvis_shots),
    ]
    folder = harness.output_folder("reference_posteriors", args.tag)
    for observation in shots:
        print(f"{observation.instrument} {observation.shot_id}", flush=True)
        key = f"{observation.instrument}:{observation.shot_id}"
        earlier = read_store(store_path).get(key) if args.extend else None
        record = reference(observation, args.seed, args.restarts, args.steps, earlier)
        store = read_store(store_path)  # read again: another call may have written meanwhile
        store[key] = record
        store_path.parent.mkdir(parents=True, exist_ok=True)
        harness.write_json(store_path, dict(sorted(store.items())))
        harness.write_json(folder / "summary.json", store)
        brief = {k: record[k] for k in ("shot", "cohorts", "largest_tau", "cpu_seconds")}
        brief["reference_error_sd"] = max(record["reference_error_sd"].values(), default=np.nan)
        print(json.dumps(brief), flush=True)


if __name__ == "__main__":
    main()
