"""Cost of the expected-waveform model against its error (issue: parameterised stands).

Scene: GEDI (1 ns bins, 15 ns pulse), a Weibull stand of cones and ellipsoids (50/50),
a 40 m window. A batch of 64 parameter vectors is drawn around the template (±20 % on
every stand parameter, ground elevation ±2 m). For each setting (radial nodes, height
nodes, depth nodes) the cost is the best of several timed batch calls divided by 64, on
one core (BLAS threads pinned to 1); the error is the relative L1 distance to the model's
converged settings (:data:`forward.expected.CONVERGED`), mean and max over the batch.
Target: ≤ 20 µs per waveform at ≤ 0.1 % error.

    python studies/stand_model_runtime_vs_error.py [--quick]

Writes studies/output/stand_model_runtime_vs_error/{pareto.png,summary.json}.
"""

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import itertools  # noqa: E402
import json  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

import forward as fw  # noqa: E402
from forward.expected import CONVERGED, ExpectedWaveformModel, ModelSettings  # noqa: E402
from forward.stand_params import StandParams  # noqa: E402

OUT = Path(__file__).parent / "output" / "stand_model_runtime_vs_error"
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
    model(theta)
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        model(theta)
        times.append(time.perf_counter() - start)
    return float(np.min(times)) / theta.shape[0]


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer settings and repeats")
    args = parser.parse_args()
    OUT.mkdir(parents=True, exist_ok=True)
    template, instrument, heights = scene()
    rng = np.random.default_rng(64)
    reference = ExpectedWaveformModel(instrument, heights, template, settings=CONVERGED)
    theta = batch(reference, rng)
    ref = reference(theta)
    if args.quick:
        grid = list(itertools.product((3, 4, 6), (16, 24, 32), (16, 24)))
        repeats = 5
    else:
        grid = list(
            itertools.product((3, 4, 5, 6, 8), (12, 16, 24, 32, 48), (12, 16, 24, 32, None))
        )
        repeats = 15
    rows = []
    for radial, nodes, depth in grid:
        settings = ModelSettings(radial_nodes=radial, height_nodes=nodes, depth_nodes=depth)
        model = ExpectedWaveformModel(instrument, heights, template, settings=settings)
        errors = np.abs(model(theta) - ref).sum(1) / ref.sum(1)
        rows.append(
            {
                "radial_nodes": radial,
                "height_nodes": nodes,
                "depth_nodes": depth,
                "us_per_waveform": 1e6 * best_time(model, theta, repeats),
                "l1_error_mean": float(errors.mean()),
                "l1_error_max": float(errors.max()),
            }
        )
    meeting = [r for r in rows if r["l1_error_max"] <= TARGET_ERROR]
    best = min(meeting, key=lambda r: r["us_per_waveform"]) if meeting else None
    default = ModelSettings()
    default_model = ExpectedWaveformModel(instrument, heights, template)
    default_errors = np.abs(default_model(theta) - ref).sum(1) / ref.sum(1)
    summary = {
        "scene": "GEDI, Weibull 18±4 m, 600 stems/ha, 50/50 cone/ellipsoid, 267 bins",
        "batch": int(theta.shape[0]),
        "target": {"us_per_waveform": TARGET_US, "l1_error": TARGET_ERROR},
        "default_settings": {
            "radial_nodes": default.radial_nodes,
            "height_nodes": default.height_nodes,
            "depth_nodes": default.depth_nodes,
            "us_per_waveform": 1e6 * best_time(default_model, theta, repeats),
            "l1_error_max": float(default_errors.max()),
        },
        "fastest_meeting_error_target": best,
        "target_met": bool(best and best["us_per_waveform"] <= TARGET_US),
        "settings": rows,
    }
    (OUT / "summary.json").write_text(json.dumps(summary, indent=2))
    plot(rows, OUT / "pareto.png")
    print(
        json.dumps(
            {
                k: summary[k]
                for k in ("default_settings", "fastest_meeting_error_target", "target_met")
            },
            indent=2,
        )
    )


def plot(rows, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 4.5))
    for radial in sorted({r["radial_nodes"] for r in rows}):
        sel = [r for r in rows if r["radial_nodes"] == radial]
        ax.scatter(
            [r["us_per_waveform"] for r in sel],
            [r["l1_error_max"] for r in sel],
            label=f"{radial} radial nodes",
            s=18,
        )
    ax.axvline(TARGET_US, color="k", ls=":", lw=1)
    ax.axhline(TARGET_ERROR, color="k", ls=":", lw=1)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("µs per waveform (batch of 64, one core)")
    ax.set_ylabel("max relative L1 error vs converged")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


if __name__ == "__main__":
    main()
