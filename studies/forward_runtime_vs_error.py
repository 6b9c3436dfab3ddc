"""Run time against accuracy of the explicit engine (issue: explicit forward model).

Scene: GEDI footprints (σf 5.5 m, 1 ns bins, 15 ns pulse) over a 800 trees/ha stand with
heights 10–30 m and mixed crown shapes. Error is the relative L1 distance to a converged
run of the same engine (32 × 128 nodes per crown, truncation 1e-8, 4× vertical
oversampling), averaged over footprints; time is the median per-footprint wall time on
one core with per-stand work done once.

    python studies/forward_runtime_vs_error.py [--quick]

Writes studies/output/forward_runtime_vs_error/{pareto.png,summary.json}.
"""

import argparse
import json
import time
from pathlib import Path

import numpy as np

import forward as fw

OUT = Path(__file__).parent / "output" / "forward_runtime_vs_error"


def benchmark_stand(rng, density_per_ha=800, half_width=60.0):
    n = rng.poisson(density_per_ha * (2 * half_width) ** 2 / 1e4)
    height = rng.uniform(10.0, 30.0, n)
    return fw.Stand.from_arrays(
        x=rng.uniform(-half_width, half_width, n),
        y=rng.uniform(-half_width, half_width, n),
        height=height,
        crown_length=0.5 * height,
        crown_radius=0.5 + 0.08 * height,
        favd=0.6,
        shape=rng.choice(["cone", "ellipsoid", "hemi-ellipsoid", "cylinder"], n),
    )


def time_per_footprint(sim, prepared, centers, heights, repeats):
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        for c, h in zip(centers, heights):
            sim.simulate(prepared, center=c, heights=h)
        times.append((time.perf_counter() - start) / len(centers))
    return float(np.median(times))


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer settings and footprints")
    args = parser.parse_args()
    OUT.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(2000)
    stand = benchmark_stand(rng)
    instrument = fw.instrument_preset("gedi")
    n_fp = 3 if args.quick else 8
    centers = rng.uniform(-30, 30, (n_fp, 2))
    reference_settings = fw.AccuracySettings(
        radial_nodes=16 if args.quick else 32,
        angular_nodes=64 if args.quick else 128,
        truncation_tolerance=1e-8,
        vertical_oversampling=4,
    )
    reference_sim = fw.WaveformSimulator(instrument, reference_settings)
    references = [reference_sim.simulate(stand, center=c) for c in centers]
    heights = [r.heights for r in references]

    nodes = [(2, 4), (3, 6), (4, 8), (6, 12), (8, 16)]
    tolerances = [1e-2, 1e-3, 1e-4]
    oversampling = [None, 2]
    if args.quick:
        nodes, tolerances, oversampling = nodes[:4], [1e-2, 1e-3], [None]
    default = fw.AccuracySettings()
    rows = []
    for radial, angular in nodes:
        for tol in tolerances:
            for m in oversampling:
                settings = fw.AccuracySettings(
                    radial_nodes=radial,
                    angular_nodes=angular,
                    truncation_tolerance=tol,
                    vertical_oversampling=m,
                )
                sim = fw.WaveformSimulator(instrument, settings)
                prepared = sim.prepare(stand)
                errors = []
                for c, h, ref in zip(centers, heights, references):
                    wf = sim.simulate(prepared, center=c, heights=h)
                    errors.append(np.abs(wf.samples - ref.samples).sum() / ref.samples.sum())
                seconds = time_per_footprint(
                    sim, prepared, centers, heights, 3 if args.quick else 7
                )
                rows.append(
                    {
                        "radial_nodes": radial,
                        "angular_nodes": angular,
                        "truncation_tolerance": tol,
                        "vertical_oversampling": sim.oversampling,
                        "relative_l1_error": float(np.mean(errors)),
                        "max_relative_l1_error": float(np.max(errors)),
                        "ms_per_footprint": 1e3 * seconds,
                        "is_default": settings == default,
                    }
                )
                print(
                    f"{radial:>2}x{angular:<3} tol={tol:g} m={sim.oversampling}: "
                    f"L1 {100 * rows[-1]['relative_l1_error']:.3f}% "
                    f"in {rows[-1]['ms_per_footprint']:.2f} ms"
                )
    pareto = []
    for row in sorted(rows, key=lambda r: r["ms_per_footprint"]):
        if not pareto or row["relative_l1_error"] < pareto[-1]["relative_l1_error"]:
            pareto.append(row)
    for row in rows:
        row["on_pareto_front"] = any(row is p for p in pareto)
    default_row = next((r for r in rows if r["is_default"]), None)
    meets = [r for r in rows if r["relative_l1_error"] <= 5e-3 and r["ms_per_footprint"] <= 5]
    summary = {
        "scene": {
            "instrument": "gedi",
            "footprint_sigma_m": 5.5,
            "bin_ns": 1.0,
            "pulse_fwhm_ns": 15.0,
            "trees": stand.n_trees,
            "density_per_ha": 800,
            "heights_m": [10, 30],
            "footprints": n_fp,
        },
        "reference_settings": {
            k: getattr(reference_settings, k)
            for k in (
                "radial_nodes",
                "angular_nodes",
                "truncation_tolerance",
                "vertical_oversampling",
            )
        },
        "target": {"relative_l1_error": 5e-3, "ms_per_footprint": 5.0},
        "default": default_row,
        "settings_meeting_target": meets,
        "pareto_front": pareto,
        "all": rows,
    }
    (OUT / "summary.json").write_text(json.dumps(summary, indent=2))
    plot(rows, pareto, default_row)
    print(f"wrote {OUT / 'summary.json'} and {OUT / 'pareto.png'}")


def plot(rows, pareto, default_row):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 4.5))
    ax.scatter(
        [r["ms_per_footprint"] for r in rows],
        [100 * r["relative_l1_error"] for r in rows],
        s=14,
        c="0.6",
        label="settings",
    )
    ax.plot(
        [r["ms_per_footprint"] for r in pareto],
        [100 * r["relative_l1_error"] for r in pareto],
        "-o",
        ms=4,
        label="Pareto front",
    )
    if default_row:
        ax.plot(
            default_row["ms_per_footprint"],
            100 * default_row["relative_l1_error"],
            "r*",
            ms=14,
            label="default",
        )
    ax.axhline(0.5, ls=":", c="k")
    ax.axvline(5.0, ls=":", c="k")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("time per footprint (ms, one core)")
    ax.set_ylabel("relative L1 error (%)")
    ax.set_title("Explicit engine: GEDI footprint, 800 trees/ha")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(OUT / "pareto.png", dpi=120)
    plt.close(fig)


if __name__ == "__main__":
    main()
