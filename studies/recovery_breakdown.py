"""Where a recovery run's intervals miss: coverage and centring by kind of stand.

Reads the shots of a ``studies/recovery.py`` run and splits one quantity's 68 % coverage
and standardised error z = (truth − median)/(half the 68 % interval) by the true top
height, the true cover, the chain's largest τ and the footprint gap (the stand's top
height less the tallest stem within the footprint, which explicit stands record); for top
height it also compares the posterior median with the footprint's tallest stem.

    python studies/recovery_breakdown.py [--tag _calibration] [--quantity top_height]

Writes studies/output/recovery{TAG}/breakdown_{QUANTITY}.{json,png}.
"""

import json
from itertools import pairwise

import matplotlib

matplotlib.use("Agg")
import harness
import matplotlib.pyplot as plt
import numpy as np
from recovery import QUANTITIES, calibration_of, coverage_of, known_rows, standardised_errors

#: Bins (lower edges, the last an upper edge) of what the shots are split by.
SPLITS = {
    "top_height": [10.0, 16.0, 22.0, 28.0, 34.0],
    "cover": [0.0, 0.3, 0.6, 1.0],
    "max_tau": [0.0, 40.0, 60.0, 100.0, np.inf],
    "footprint_gap": [0.0, 0.25, 0.6, 1.2, np.inf],
}


def _value(row, key):
    """What a shot is split by; NaN where the run did not record it (no explicit stand)."""
    if key == "max_tau":
        return row["max_tau"]
    if key == "footprint_gap":
        return footprint_gap(row)
    return row["truth"][key]


def footprint_gap(row) -> float:
    """True top height less the tallest stem within the footprint (m), NaN if unknown."""
    truth = row["truth"]
    return float(truth["top_height"]) - float(truth.get("footprint_top_height", np.nan))


def breakdown(rows, quantity) -> dict:
    """Per split and bin: shots, 68 % coverage and z median of ``quantity``."""
    rows = known_rows([r for r in rows if "posterior" in r], quantity)
    out = {"quantity": quantity, "n": len(rows), "all": _summary(rows, quantity)}
    for key, edges in SPLITS.items():
        out[key] = []
        for low, high in pairwise(edges):
            part = [r for r in rows if low <= _value(r, key) < high]
            bounds = [low, high if np.isfinite(high) else None]  # JSON has no infinity
            out[key].append({"range": bounds, **_summary(part, quantity)})
    if quantity == "top_height" and all("footprint_top_height" in r["truth"] for r in rows):
        top = np.array([r["truth"]["top_height"] for r in rows])
        tallest = np.array([r["truth"]["footprint_top_height"] for r in rows])
        median = np.array([r["posterior"]["top_height"]["median"] for r in rows])
        out["tallest_stem_below_top_m"] = np.percentile(top - tallest, [25, 50, 75]).tolist()
        out["median_above_tallest_stem_m"] = float(np.median(median - tallest))
        out["median_below_top_m"] = float(np.median(top - median))
    return out


def _summary(rows, quantity) -> dict:
    if not rows:
        return {"n": 0}
    return {
        "n": len(rows),
        "coverage_68": coverage_of(rows, quantity, "p16", "p84"),
        "z_median": calibration_of(rows, quantity)["z_median"],
    }


def plot(rows, quantity, path):
    rows = known_rows([r for r in rows if "posterior" in r], quantity)
    z = standardised_errors(rows, quantity)
    top = np.array([r["truth"]["top_height"] for r in rows])
    cover = np.array([r["truth"]["cover"] for r in rows])
    gap = np.array([footprint_gap(r) for r in rows])
    fig, axes = plt.subplots(1, 2, figsize=(10, 4), sharey=True)
    for ax, x, label in zip(
        axes, (top, gap), ("true top height (m)", "top height − footprint's tallest stem (m)")
    ):
        points = ax.scatter(x, z, c=cover, cmap="viridis", s=14, vmin=0, vmax=1)
        ax.axhspan(-1, 1, color="0.9", zorder=0)
        ax.axhline(0, color="0.4", lw=0.8)
        ax.set(xlabel=label, ylim=(-4, 4))
    axes[0].set_ylabel(f"z of {quantity}")
    fig.colorbar(points, ax=axes, label="true cover")
    fig.savefig(path, dpi=120, bbox_inches="tight")
    plt.close(fig)


def main():
    parser = harness.parser(__doc__, tag=False)
    parser.add_argument("--tag", default="_calibration", help="suffix of the recovery run")
    parser.add_argument("--quantity", default="top_height", choices=QUANTITIES)
    args = parser.parse_args()
    folder = harness.OUTPUT / f"recovery{args.tag}"
    shots = folder / "shots.json"
    if not shots.exists():
        raise SystemExit(f"no recovery run at {shots}; run studies/recovery.py --tag {args.tag}")
    rows = json.loads(shots.read_text())
    summary = breakdown(rows, args.quantity)
    harness.write_json(folder / f"breakdown_{args.quantity}.json", summary)
    plot(rows, args.quantity, folder / f"breakdown_{args.quantity}.png")
    print(json.dumps(summary, indent=1))


if __name__ == "__main__":
    main()
