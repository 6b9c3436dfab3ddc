"""Run time against error of the explicit engine, per kind of stand (issue 30).

Stands on 100 m × 100 m plots, seen by GEDI (σf 5.5 m, 1 ns bins, 15 ns pulse) with
150–400 trees in the truncated footprint:

- ``sparse``: 1000 stems/ha, 5–15 m tall, crown radius 0.6–1.4 m, cones and ellipsoids,
  FAVD 0.8;
- ``mixed``: 1200 stems/ha, 10–30 m, crown radius 0.5 + 0.08·h, all four shapes, FAVD 0.6;
- ``dense``: 1800 stems/ha of cones 12–25 m tall, crown radius 2–3.5 m, FAVD 1.5: crowns
  overlap everywhere;
- ``hotspot``: the dense stand with k = 2 (two-way attenuation, no hot spot);

and ``slicer``: SLICER (σf 2.5 m, 4 ns pulse) over 1200 stems/ha of hemi-ellipsoids.

The converged reference is the column engine at 0.03 m spacing (SLICER 0.015 m),
truncation 1e-7 and four times the default fine layers; the brute-force model of
``lidarinv/testing/reference_model.py`` (0.1 m columns, exact in z, independent code) is run on the
first footprint of each stand as a check and as a point on the figure. The old engine is
the per-crown quadrature (4 × 8 nodes, its default, 8 × 16 and 16 × 32); the new one the
column engine at tolerances 1e-2, 3e-3 (its default), 1e-3 and 3e-4. Errors: relative L1
Σ|W − W_ref| / ΣW_ref and the relative error of the ground energy ρg·P̄(0), mean and
maximum over the footprints. Times: per footprint on one core, per-stand work done once,
every setting timed in turn within each repeat (old and new interleaved in one process),
the minimum over repeats, as the thread's CPU time (``ms_per_footprint``: the machine is
shared, and CPU time leaves out the time other processes hold the core) and as wall time;
a speed probe (a fixed compiled loop) at start and end records how loaded the machine
was.

    python studies/forward_runtime_vs_error.py [--quick]

Writes studies/output/forward_runtime_vs_error/{runtime_vs_error.png,summary.json}.
"""

import harness

harness.pin_threads()

import os  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

import forward as fw  # noqa: E402
from lidarinv.testing.reference_model import reference_waveform  # noqa: E402

OUT = harness.OUTPUT / "forward_runtime_vs_error"
HALF_WIDTH = 50.0  # m: the plots are 100 m × 100 m
OLD = [(4, 8), (8, 16), (16, 32)]
TOLERANCES = [1e-2, 3e-3, 1e-3, 3e-4]
TARGET = {"relative_l1": 3e-3, "ground": 3e-3, "ms_per_footprint": 5.0}


def _stems(rng, per_ha, half_width=HALF_WIDTH):
    n = rng.poisson(per_ha * (2 * half_width) ** 2 / 1e4)
    return n, rng.uniform(-half_width, half_width, n), rng.uniform(-half_width, half_width, n)


def sparse_stand(rng):
    n, x, y = _stems(rng, 1000)
    h = rng.uniform(5.0, 15.0, n)
    return fw.Stand.from_arrays(
        x=x, y=y, height=h, crown_length=0.6 * h, crown_radius=rng.uniform(0.6, 1.4, n),
        favd=0.8, shape=rng.choice(["cone", "ellipsoid"], n),
    )  # fmt: skip


def mixed_stand(rng):
    n, x, y = _stems(rng, 1200)
    h = rng.uniform(10.0, 30.0, n)
    return fw.Stand.from_arrays(
        x=x, y=y, height=h, crown_length=0.5 * h, crown_radius=0.5 + 0.08 * h,
        favd=0.6, shape=rng.choice(list(fw.SHAPE_NAMES), n),
    )  # fmt: skip


def dense_stand(rng):
    n, x, y = _stems(rng, 1800)
    h = rng.uniform(12.0, 25.0, n)
    return fw.Stand.from_arrays(
        x=x, y=y, height=h, crown_length=0.6 * h, crown_radius=rng.uniform(2.0, 3.5, n),
        favd=1.5, shape="cone",
    )  # fmt: skip


def slicer_stand(rng):
    n, x, y = _stems(rng, 1200, half_width=25.0)
    h = rng.uniform(8.0, 16.0, n)
    return fw.Stand.from_arrays(
        x=x, y=y, height=h, crown_length=0.5 * h, crown_radius=rng.uniform(1.2, 2.4, n),
        favd=0.8, shape="hemi-ellipsoid",
    )  # fmt: skip


#: Stand kind → (stand maker, instrument, spread of footprint centres (m), reference spacing).
KINDS = {
    "sparse": (sparse_stand, fw.instrument_preset("gedi"), 15.0, 0.03),
    "mixed": (mixed_stand, fw.instrument_preset("gedi"), 15.0, 0.03),
    "dense": (dense_stand, fw.instrument_preset("gedi"), 15.0, 0.03),
    "hotspot": (dense_stand, fw.instrument_preset("gedi", hotspot_k=2.0), 15.0, 0.03),
    "slicer": (slicer_stand, fw.instrument_preset("slicer"), 8.0, 0.015),
}


def speed_probe():
    """Nanoseconds per step of a fixed compiled multiply-add loop (machine load)."""
    from numba import njit

    @njit(cache=True)
    def loop(x):
        total = 0.0
        for v in x:
            total += v * 1.0000001
        return total

    x = np.linspace(0.0, 1.0, 5_000_000)
    loop(x)
    best = np.inf
    for _ in range(5):
        start = time.perf_counter()
        loop(x)
        best = min(best, time.perf_counter() - start)
    return 1e9 * best / x.size


def relative_l1(samples, reference):
    return float(np.abs(samples - reference).sum() / reference.sum())


def settings_list(quick):
    old = OLD[:2] if quick else OLD
    rows = [
        ("old", f"{r}x{a}", fw.AccuracySettings(radial_nodes=r, angular_nodes=a)) for r, a in old
    ]
    rows += [("new", f"{t:g}", fw.AccuracySettings(tolerance=t)) for t in TOLERANCES]
    return rows


def study_kind(kind, n_footprints, repeats, quick):
    make, instrument, spread, spacing = KINDS[kind]
    rng = np.random.default_rng(2024)
    stand = make(rng)
    centers = rng.uniform(-spread, spread, (n_footprints, 2))
    default = fw.WaveformSimulator(instrument)
    reference = fw.WaveformSimulator(
        instrument,
        fw.AccuracySettings(
            column_spacing=spacing,
            truncation_tolerance=1e-7,
            vertical_oversampling=4 * default.oversampling,
        ),
    )
    refs = [reference.simulate(stand, center=c) for c in centers]
    trees = [
        default.prepare(stand).crowns_near(*c, default.footprint_radius, fw.Ground()).size
        for c in centers
    ]
    runs = []
    for engine, label, accuracy in settings_list(quick):
        sim = fw.WaveformSimulator(instrument, accuracy)
        prepared = sim.prepare(stand)
        waveforms = [
            sim.simulate(prepared, center=c, heights=r.heights) for c, r in zip(centers, refs)
        ]
        runs.append((engine, label, accuracy, sim, prepared, waveforms))
    seconds = {label: [] for _, label, *_ in runs}
    wall = {label: [] for _, label, *_ in runs}
    for _ in range(repeats):  # every setting in turn within each repeat
        for _, label, _, sim, prepared, _ in runs:
            start, start_wall = time.thread_time(), time.perf_counter()
            for c, r in zip(centers, refs):
                sim.simulate(prepared, center=c, heights=r.heights)
            seconds[label].append((time.thread_time() - start) / len(centers))
            wall[label].append((time.perf_counter() - start_wall) / len(centers))
    rows = []
    for engine, label, accuracy, _, _, waveforms in runs:
        errors = [relative_l1(w.samples, r.samples) for w, r in zip(waveforms, refs)]
        ground = [abs(w.ground_gap / r.ground_gap - 1.0) for w, r in zip(waveforms, refs)]
        rows.append(
            {
                "engine": engine,
                "setting": label,
                "is_default": accuracy == fw.AccuracySettings(radial_nodes=4, angular_nodes=8)
                if engine == "old"
                else accuracy == fw.AccuracySettings(),
                "relative_l1_mean": float(np.mean(errors)),
                "relative_l1_max": float(np.max(errors)),
                "ground_error_mean": float(np.mean(ground)),
                "ground_error_max": float(np.max(ground)),
                "ms_per_footprint": 1e3 * float(np.min(seconds[label])),
                "wall_ms_per_footprint": 1e3 * float(np.min(wall[label])),
                "columns": waveforms[0].settings.get("columns"),
                "column_spacing_m": waveforms[0].settings.get("column_spacing_m"),
                "ground_column_spacing_m": waveforms[0].settings.get("ground_column_spacing_m"),
            }
        )
    rows.append(brute_force(stand, instrument, centers[0], refs[0], quick))
    old_default = next(r for r in rows if r["engine"] == "old" and r["is_default"])
    new_default = next(r for r in rows if r["engine"] == "new" and r["is_default"])
    return {
        "instrument": instrument.describe(),
        "stems": stand.n_trees,
        "trees_in_footprint": [int(min(trees)), int(max(trees))],
        "ground_gap_range": [
            float(min(r.ground_gap for r in refs)),
            float(max(r.ground_gap for r in refs)),
        ],
        "footprints": n_footprints,
        "reference_spacing_m": spacing,
        "rows": rows,
        "old_over_new_default_time": old_default["ms_per_footprint"]
        / new_default["ms_per_footprint"],
        "old_over_new_default_error": old_default["relative_l1_mean"]
        / new_default["relative_l1_mean"],
        "default_meets_target": bool(
            new_default["relative_l1_max"] <= TARGET["relative_l1"]
            and new_default["ms_per_footprint"] <= TARGET["ms_per_footprint"]
        ),
        "default_ground_within_target": bool(new_default["ground_error_max"] <= TARGET["ground"]),
    }


def brute_force(stand, instrument, center, ref, quick):
    """The brute-force model on one footprint: its error and run time."""
    spacing = 0.2 if quick else 0.1
    start, start_wall = time.thread_time(), time.perf_counter()
    samples, ground_gap = reference_waveform(
        stand, instrument, ref.heights, center=center, spacing=spacing, fine=0.01
    )
    seconds, wall = time.thread_time() - start, time.perf_counter() - start_wall
    error = relative_l1(samples, ref.samples)
    return {
        "engine": "brute force",
        "setting": f"{spacing} m columns",
        "is_default": False,
        "relative_l1_mean": error,
        "relative_l1_max": error,
        "ground_error_mean": abs(ground_gap / ref.ground_gap - 1.0),
        "ground_error_max": abs(ground_gap / ref.ground_gap - 1.0),
        "ms_per_footprint": 1e3 * seconds,
        "wall_ms_per_footprint": 1e3 * wall,
        "columns": None,
        "column_spacing_m": spacing,
        "ground_column_spacing_m": spacing,
    }


def main():
    parser = harness.parser(__doc__, tag=False)
    parser.add_argument("--quick", action="store_true", help="fewer footprints and settings")
    parser.add_argument("--kinds", default=",".join(KINDS), help="comma-separated stand kinds")
    args = parser.parse_args()
    OUT.mkdir(parents=True, exist_ok=True)
    probe_start, load_start = speed_probe(), os.getloadavg()[0]
    n_footprints, repeats = (3, 2) if args.quick else (8, 5)
    results = {}
    for kind in args.kinds.split(","):
        results[kind] = study_kind(kind, n_footprints, repeats, args.quick)
        for row in results[kind]["rows"]:
            print(
                f"{kind:8s} {row['engine']:11s} {row['setting']:>12s}: "
                f"L1 {100 * row['relative_l1_mean']:.3f}/{100 * row['relative_l1_max']:.3f} %, "
                f"ground {100 * row['ground_error_mean']:.3f}/{100 * row['ground_error_max']:.3f} %, "
                f"{row['ms_per_footprint']:.2f} ms",
                flush=True,
            )
    summary = {
        "target": TARGET,
        "speed_probe_ns_per_step": [probe_start, speed_probe()],
        "load_average": [load_start, os.getloadavg()[0]],
        "kinds": results,
    }
    harness.write_json(OUT / "summary.json", summary, indent=2)
    plot(results)
    print(f"wrote {OUT / 'summary.json'} and {OUT / 'runtime_vs_error.png'}")


def plot(results):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = len(results)
    fig, axes = plt.subplots(2, n, figsize=(3.6 * n, 7.0), squeeze=False)
    style = {"old": ("C0", "o-"), "new": ("C3", "s-"), "brute force": ("k", "*")}
    labels = {"old": "per-crown quadrature", "new": "columns (tolerance)"}
    for column, (kind, result) in enumerate(results.items()):
        for row, key in enumerate(("relative_l1_mean", "ground_error_mean")):
            ax = axes[row][column]
            for engine, (colour, marker) in style.items():
                rows = [r for r in result["rows"] if r["engine"] == engine]
                ax.plot(
                    [r["ms_per_footprint"] for r in rows],
                    [100 * r[key] for r in rows],
                    marker,
                    color=colour,
                    ms=9 if engine == "brute force" else 4,
                    label=labels.get(engine, "brute force"),
                )
                for r in rows:
                    if r["is_default"]:
                        ax.plot(r["ms_per_footprint"], 100 * r[key], "o", mfc="none",
                                mec=colour, ms=12)  # fmt: skip
            ax.axhline(100 * TARGET["relative_l1" if row == 0 else "ground"], ls=":", c="k")
            ax.axvline(TARGET["ms_per_footprint"], ls=":", c="k")
            ax.set_xscale("log")
            ax.set_yscale("log")
        low, high = result["trees_in_footprint"]
        axes[0][column].set_title(f"{kind} ({low}–{high} trees)", fontsize=9)
        axes[1][column].set_xlabel("CPU ms per footprint (one core)")
    axes[0][0].set_ylabel("relative L1 error (%)")
    axes[1][0].set_ylabel("ground energy error (%)")
    axes[0][0].legend(fontsize=7)
    fig.suptitle("Explicit engine: run time against error, mean over footprints (circled: "
                 "defaults)", fontsize=10)  # fmt: skip
    fig.tight_layout()
    fig.savefig(OUT / "runtime_vs_error.png", dpi=120)
    plt.close(fig)


if __name__ == "__main__":
    main()
