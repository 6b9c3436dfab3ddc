"""Two runs of ``studies/real_inversion.py`` on the same shots, compared shot by shot.

A change of settings (``--walkers``, ``--max-steps``, a priors file) or of code is judged
on the shots both runs inverted. Per instrument: each run's median CPU seconds and steps,
how many shots converged and how many carry a warning; per reported quantity, how far the
second run's 5/50/95 % quantiles lie from the first's, in the first run's posterior sd
((q95 − q5)/3.29, the sd of a normal posterior), as the median, 90th percentile and
largest over the shots; and each run's median |posterior median − product| for the
comparisons of ``real_inversion.QUANTITIES``. Two runs of one posterior with other seeds
differ by their Monte Carlo error alone, about 0.1 sd at the stopping rule's ESS of 400.

    python studies/compare_runs.py FIRST_TAG SECOND_TAG [--tag _NAME]

Reads ``studies/output/real_inversion{TAG}/shots.json`` of each run; writes
``studies/output/compare_runs{_NAME}/summary.json``.
"""

import json

import harness
import numpy as np
from real_inversion import QUANTITIES, statistics
from real_inversion_table import warned
from speed_real_shots import agreement

#: The sd of a normal posterior from its 5–95 % interval.
INTERVAL_SDS = 3.29


def read_records(tag) -> dict:
    """The inverted shots of a real_inversion run, by (instrument, shot)."""
    path = harness.OUTPUT / f"real_inversion{tag}" / "shots.json"
    if not path.exists():
        raise FileNotFoundError(f"no run {tag!r}: {path} is missing")
    records = json.loads(path.read_text())
    return {(r["instrument"], r["shot"]): r for r in records if "posterior" in r}


def _quantiles(record) -> dict:
    """A record's posterior 5/50/95 % as :func:`speed_real_shots.agreement` takes them,
    the sd from the interval's width; quantities with a non-finite quantile left out."""
    return {
        name: {"quantiles": q, "sd": (q[2] - q[0]) / INTERVAL_SDS}
        for name, q in record["posterior"].items()
        if np.all(np.isfinite(q))
    }


def quantile_shifts(first, second, quantity) -> np.ndarray:
    """|second − first| of the 5/50/95 % quantiles of ``quantity``, in the first run's
    posterior sd, one row per shot (n, 3); shots with a zero or unknown sd left out."""
    rows = []
    for a, b in zip(first, second, strict=True):
        shift = agreement(_quantiles(b), _quantiles(a)).get(quantity)
        if shift is not None:
            rows.append(shift)
    return np.array(rows, float).reshape(-1, 3)


def compare(first: dict, second: dict) -> dict:
    """The comparison of two runs' records (:func:`read_records`), per instrument."""
    out = {}
    for instrument in sorted({key[0] for key in first}):
        keys = sorted(k for k in first if k[0] == instrument and k in second)
        if not keys:
            continue
        a, b = [first[k] for k in keys], [second[k] for k in keys]
        entry = {"shots": len(keys)}
        for name, records in (("first", a), ("second", b)):
            stats = statistics(records, instrument, per_shot=False)
            entry[name] = {
                "cpu_seconds_median": stats["median_cpu_seconds"],
                "steps_median": float(np.median([r["steps"] for r in records])),
                "converged": stats["converged"],
                "warned": sum(warned(r["flags"]) for r in records),
                "product_error_median": {
                    label: stats[label]["median_abs"] for label in QUANTITIES if label in stats
                },
            }
        shifts = {}
        for quantity in a[0]["posterior"]:
            d = quantile_shifts(a, b, quantity)
            if d.size:
                shifts[quantity] = {
                    "median": np.median(d, axis=0).round(3).tolist(),
                    "p90": np.percentile(d, 90, axis=0).round(3).tolist(),
                    "largest": d.max(axis=0).round(3).tolist(),
                }
        entry["quantile_shift_sd"] = shifts  # per quantity: the 5, 50 and 95 % quantiles
        out[instrument] = entry
    return out


def main(argv=None):
    parser = harness.parser(__doc__)
    parser.add_argument("first", help="the first run's --tag (the reference)")
    parser.add_argument("second", help="the second run's --tag")
    args = parser.parse_args(argv)
    summary = {"first": args.first, "second": args.second}
    summary.update(compare(read_records(args.first), read_records(args.second)))
    out = harness.output_folder("compare_runs", args.tag)
    harness.write_json(out / "summary.json", summary)
    print(json.dumps(summary, indent=1))
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
