"""How far a shot's posterior moves with the seed that prepares it (issue 46).

Usage::

    python studies/preparation_spread.py --data DATA --gedi-shots ID ... --lvis-shots ID ...
        [--counts 64 256] [--seeds 6] [--seed 100] [--tag _NAME]

A shot is inverted at default settings with ``--seeds`` generators (``--seed``,
``--seed`` + 1, …), once for each count of discrepancy realisations in ``--counts``
(``RealisationSettings.count``). Each generator prepares the posterior again (the MAP
search, the realisations of the discrepancy) and samples it. Per shot and count, the
reported quantities' 5/50/95 % quantiles are compared across the seeds: their sd over the
runs, in the runs' mean posterior sd. That spread holds the sampler's own Monte Carlo
error and the preparation's; a count that shrinks it shrinks the preparation's share.
Each run also states both shares of its own (the realisations' bootstrap spread,
:mod:`lidarinv.inference.results.realisation_spread`, and the quantile MCSE); the record
compares their sum in quadrature with the spread measured over the seeds.

Writes studies/output/preparation_spread[_TAG]/summary.json.
"""

import harness

harness.pin_threads()

import json  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402
from speed_real_shots import real_observations, reported_quantiles  # noqa: E402

from lidarinv.inference import InversionSettings, invert_shot  # noqa: E402
from lidarinv.inference.settings import RealisationSettings  # noqa: E402


def quantile_spread(runs: list) -> dict:
    """{name: [sd over the runs of the 5, 50 and 95 % quantiles] / mean posterior sd}."""
    out = {}
    for name in set.intersection(*(set(run) for run in runs)):
        quantiles = np.array([run[name]["quantiles"] for run in runs])
        sd = np.mean([run[name]["sd"] for run in runs])
        if sd > 0:
            out[name] = [float(v) for v in np.std(quantiles, axis=0, ddof=1) / sd]
    return dict(sorted(out.items()))


def stated_spread(runs: list, name: str) -> float:
    """The spread the runs themselves state for a quantity: the realisations' bootstrap
    spread and the sampler's quantile Monte Carlo error added in quadrature, averaged over
    the runs (NaN where a run lacks either)."""
    values = []
    for run in runs:
        parts = [run["realisation_spread"].get(name), run["quantile_mcse"].get(name)]
        parts = [p for p in parts if p is not None and np.isfinite(p)]
        values.append(float(np.hypot(*parts)) if len(parts) == 2 else np.nan)
    return float(np.mean(values))


def shot_spread(observation, count: int, seeds) -> dict:
    """One shot's runs at one count of realisations, and their spread."""
    settings = InversionSettings(realisations=RealisationSettings(count=count))
    runs = []
    for seed in seeds:
        cpu = time.process_time()
        result = invert_shot(observation, settings, rng=np.random.default_rng(seed))
        quantities = result.diagnostics.get("quantities", {})
        runs.append({
            "seed": int(seed), "steps": int(result.diagnostics["n_steps"]),
            "converged": result.converged, "cpu_seconds": time.process_time() - cpu,
            "reported": reported_quantiles(result),
            # the run's own estimates of the two shares: the realisations' (bootstrap)
            # and the sampler's (quantile Monte Carlo error), in posterior sd
            "realisation_spread": result.diagnostics.get("realisation_spread", {}).get("spread", {}),
            "quantile_mcse": {n: q.get("quantile_mcse") for n, q in quantities.items()},
        })  # fmt: skip
        print(json.dumps({k: runs[-1][k] for k in ("seed", "steps", "cpu_seconds")}), flush=True)
    spread = quantile_spread([run["reported"] for run in runs])
    largest = max(spread, key=lambda name: max(spread[name]))
    stated = {name: stated_spread(runs, name) for name in spread}
    return {
        "instrument": observation.instrument,
        "shot": str(observation.shot_id),
        "count": count,
        "runs": runs,
        "spread_sd": spread,
        "largest_spread_sd": max(spread[largest]),
        "largest_quantity": largest,
        # per quantity, what the runs said of themselves: √(bootstrap² + MCSE²), mean over runs
        "stated_spread_sd": stated,
        "largest_stated_spread_sd": max(
            (v for v in stated.values() if np.isfinite(v)), default=None
        ),
        "median_cpu_seconds": float(np.median([run["cpu_seconds"] for run in runs])),
    }


def main():
    parser = harness.parser(__doc__, seed=100)
    parser.add_argument("--data", required=True, help="folder of the real files, or 'examples'")
    parser.add_argument("--gedi-shots", nargs="*", default=[])
    parser.add_argument("--lvis-shots", nargs="*", default=[])
    parser.add_argument("--counts", nargs="+", type=int, default=[64, 256])
    parser.add_argument("--seeds", type=int, default=6, help="preparations of each shot")
    args = parser.parse_args()
    if args.seeds < 2:
        raise SystemExit("--seeds must be at least 2 to measure a spread")
    shots = [
        *real_observations(args.data, "gedi", args.gedi_shots),
        *real_observations(args.data, "lvis", args.lvis_shots),
    ]
    folder = harness.output_folder("preparation_spread", args.tag)
    records = []
    seeds = range(args.seed, args.seed + args.seeds)
    for observation in shots:
        for count in args.counts:
            print(f"{observation.instrument} {observation.shot_id}, {count} realisations")
            records.append(shot_spread(observation, count, seeds))
            harness.write_json(folder / "summary.json", {"shots": records})
            brief = {k: records[-1][k] for k in ("shot", "count", "largest_spread_sd",
                                                 "largest_quantity", "median_cpu_seconds")}  # fmt: skip
            print(json.dumps(brief), flush=True)


if __name__ == "__main__":
    main()
