"""Cost of the expected-waveform model against its error (issue: parameterised stands).

Scene: GEDI (1 ns bins, 15 ns pulse), a Weibull stand of cones and ellipsoids (50/50),
a 40 m window. A batch of 64 parameter vectors is drawn around the template (±20 % on
every stand parameter, ground elevation ±2 m). For each setting (radial nodes, height
nodes, depth nodes) the cost is the best of several timed batch calls divided by 64, on
one core (BLAS threads pinned to 1); the error is the relative L1 distance to the model's
converged settings (:data:`forward.expected.CONVERGED`), mean and max over the batch.
The default settings are timed with both backends (numpy only, and numba when it is
installed); the grid uses the default backend. Target: ≤ 20 µs per waveform at ≤ 0.1 %
error. Timings on a shared machine are noisy: each is the minimum of several repeats and
the load average is recorded with them.

    python studies/stand_model_runtime_vs_error.py [--quick] [--repeats N]

Writes studies/output/stand_model_runtime_vs_error/{pareto.png,summary.json} and prints
a table.
"""

import harness

harness.pin_threads()

import dataclasses  # noqa: E402
import itertools  # noqa: E402
import os  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

import forward as fw  # noqa: E402
from forward.backends import AVAILABLE as NUMBA_AVAILABLE  # noqa: E402
from forward.expected import CONVERGED, ExpectedWaveformModel, ModelSettings  # noqa: E402
from forward.stand_params import StandParams  # noqa: E402

OUT = harness.OUTPUT / "stand_model_runtime_vs_error"
TARGET_US, TARGET_ERROR = 20.0, 1e-3


def scene():
    template = StandParams(
        density=600.0,
        height_mean=18.0,
        height_sd=4.0,
        height_family="weibull",
        shape_mix={"cone": 0.5, "ellipsoid": 0.5},
        crown_length_ratio=0.5,
        crown_radius_intercept=0.3,
        crown_radius_slope=0.1,
        favd=0.7,
    )
    instrument = fw.instrument_preset("gedi")
    heights = np.arange(-60, 207) * instrument.bin_height  # −9 m to 31 m
    return template, instrument, heights


def batch(model, rng, n=64):
    theta = np.repeat(model.vector(model.template)[None, :], n, axis=0)
    theta *= 1.0 + 0.2 * rng.uniform(-1, 1, theta.shape)
    theta[:, model.parameter_names.index("ground_elevation")] = rng.uniform(-2, 2, n)
    return theta


def best_time(model, theta, repeats):
    """Seconds per waveform: the fastest of ``repeats`` batch calls over the batch size."""
    model(theta)
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        model(theta)
        times.append(time.perf_counter() - start)
    return float(np.min(times)) / theta.shape[0]


def measure(instrument, heights, template, settings, theta, ref, repeats):
    """One row of the summary: settings, backend, µs per waveform and L1 errors."""
    model = ExpectedWaveformModel(instrument, heights, template, settings=settings)
    errors = np.abs(model(theta) - ref).sum(1) / ref.sum(1)
    return {
        "radial_nodes": settings.radial_nodes,
        "height_nodes": settings.height_nodes,
        "depth_nodes": settings.depth_nodes,
        "backend": model.backend,
        "us_per_waveform": 1e6 * best_time(model, theta, repeats),
        "l1_error_mean": float(errors.mean()),
        "l1_error_max": float(errors.max()),
    }


def pareto(rows):
    """Rows that no other row beats on both cost and (max) error."""
    front, best_error = [], np.inf
    for row in sorted(rows, key=lambda r: (r["us_per_waveform"], r["l1_error_max"])):
        if row["l1_error_max"] < best_error:
            front.append(row)
            best_error = row["l1_error_max"]
    return front


def table(rows, title):
    lines = [title, "radial height depth backend   µs/waveform  L1 max    L1 mean"]
    for r in rows:
        lines.append(
            f"{r['radial_nodes']:>6} {r['height_nodes']:>6} {r['depth_nodes']!s:>5} "
            f"{r['backend']:<8} {r['us_per_waveform']:>11.1f}  {r['l1_error_max']:.2e}  "
            f"{r['l1_error_mean']:.2e}"
        )
    return "\n".join(lines)


def main():
    parser = harness.parser(__doc__, tag=False)
    parser.add_argument("--quick", action="store_true", help="fewer settings and repeats")
    parser.add_argument("--repeats", type=int, default=None, help="timed calls per setting")
    args = parser.parse_args()
    OUT.mkdir(parents=True, exist_ok=True)
    template, instrument, heights = scene()
    rng = np.random.default_rng(64)
    load_start = os.getloadavg()[0]
    reference = ExpectedWaveformModel(instrument, heights, template, settings=CONVERGED)
    theta = batch(reference, rng)
    ref = reference(theta)
    if args.quick:
        grid = list(itertools.product((4, 5, 6), (24, 32), (24, 32)))
        repeats = 5
    else:
        grid = list(
            itertools.product((3, 4, 5, 6, 8), (12, 16, 24, 32, 48), (12, 16, 24, 32, None))
        )
        repeats = 15
    repeats = args.repeats or repeats
    rows = []
    for radial, nodes, depth in grid:
        settings = ModelSettings(radial_nodes=radial, height_nodes=nodes, depth_nodes=depth)
        rows.append(measure(instrument, heights, template, settings, theta, ref, repeats))
    backends = ["numpy"] + (["numba"] if NUMBA_AVAILABLE else [])
    defaults = [
        measure(
            instrument,
            heights,
            template,
            dataclasses.replace(ModelSettings(), backend=backend),
            theta,
            ref,
            3 * repeats,
        )
        for backend in backends
    ]
    meeting = [r for r in rows if r["l1_error_max"] <= TARGET_ERROR]
    best = min(meeting, key=lambda r: r["us_per_waveform"]) if meeting else None
    default = defaults[-1]
    summary = {
        "scene": "GEDI, Weibull 18±4 m, 600 stems/ha, 50/50 cone/ellipsoid, 267 bins",
        "batch": int(theta.shape[0]),
        "repeats": repeats,
        "cpu_count": os.cpu_count(),
        "load_average_1min": {"start": load_start, "end": os.getloadavg()[0]},
        "target": {"us_per_waveform": TARGET_US, "l1_error": TARGET_ERROR},
        "default_settings": defaults,
        "fastest_meeting_error_target": best,
        "default_meets_target": bool(
            default["us_per_waveform"] <= TARGET_US and default["l1_error_max"] <= TARGET_ERROR
        ),
        "pareto_front": pareto(rows),
        "settings": rows,
    }
    harness.write_json(OUT / "summary.json", summary, indent=2)
    plot(rows, defaults, OUT / "pareto.png")
    print(table(defaults, "default ModelSettings()"))
    print()
    print(table(summary["pareto_front"], f"Pareto front of the grid ({len(rows)} settings)"))
    print()
    print(
        f"target ≤ {TARGET_US:g} µs at ≤ {TARGET_ERROR:g} L1: default "
        f"{'meets' if summary['default_meets_target'] else 'misses'} it; load average "
        f"{load_start:.1f} → {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores"
    )
    print(f"wrote {OUT / 'summary.json'} and {OUT / 'pareto.png'}")


def plot(rows, defaults, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import FuncFormatter

    fig, ax = plt.subplots(figsize=(6, 4.5))
    for radial in sorted({r["radial_nodes"] for r in rows}):
        sel = [r for r in rows if r["radial_nodes"] == radial]
        ax.scatter(
            [r["us_per_waveform"] for r in sel],
            [r["l1_error_max"] for r in sel],
            label=f"{radial} radial nodes",
            s=18,
        )
    for row in defaults:
        ax.scatter(
            row["us_per_waveform"],
            row["l1_error_max"],
            marker="*",
            s=120,
            color="k" if row["backend"] == "numba" else "0.5",
            label=f"default ({row['backend']})",
        )
    ax.axvline(TARGET_US, color="k", ls=":", lw=1)
    ax.axhline(TARGET_ERROR, color="k", ls=":", lw=1)
    ax.set_xscale("log")
    ax.set_yscale("log")
    plain = FuncFormatter(lambda x, _: f"{x:g}")
    ax.xaxis.set_major_formatter(plain)
    ax.xaxis.set_minor_formatter(plain)
    ax.set_xlabel("µs per waveform (batch of 64, one core)")
    ax.set_ylabel("max relative L1 error vs converged")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


if __name__ == "__main__":
    main()
