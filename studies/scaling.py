"""Cost follows the scene: run time of the forward models against what they simulate.

Measured (single thread, ``time.perf_counter``, minimum over repeats):

1. explicit engine vs number of trees in the footprint, at a fixed stem density and crown
   size (the footprint grows with the tree count) and a fixed column spacing: expected
   linear (log–log slope ≈ 1: the columns, and the crowns over each, grow with the area);
2. vs the length of the waveform window at a fixed canopy: expected flat once the window
   holds the canopy (vertical work spans only the layers that hold crowns);
3. vs trees placed beyond the footprint's truncation radius: expected ≈ no extra cost;
4. an empty scene vs the ground return alone (the pulse placed on the bins);
5. vs the footprint truncation tolerance at a fixed uniform stand: expected to flatten,
   since the columns thin out as the footprint weight falls (the grid's cells are of
   equal probability under a Gaussian twice as wide as the footprint);
6. the expected (stand) model with and without the uniform understory.

Writes ``studies/output/scaling/scaling.json`` and ``scaling.png``, plus a copy of the
JSON at ``studies/output/scaling.json``. ``--quick`` uses fewer sizes and repeats.
The machine this ran on may be shared: the minimum over repeats is reported, and the
JSON records the load average at the start and end.
"""

import harness

harness.pin_threads()

import json  # noqa: E402
import os  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

import forward as fw  # noqa: E402
from forward.expected import ExpectedWaveformModel  # noqa: E402
from forward.explicit.render import ground_samples  # noqa: E402
from forward.stand_params import StandParams  # noqa: E402

OUT = harness.OUTPUT
INSTRUMENT = fw.instrument_preset("gedi")
DENSITY = 0.1  # stems per m² (1000 stems/ha)


def best_time(call, repeats):
    """Minimum wall time (s) of ``call()`` over ``repeats`` runs (after one warm-up)."""
    call()
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        call()
        times.append(time.perf_counter() - start)
    return min(times)


def uniform_stand(rng, n, half_width, x0=0.0):
    """``n`` cone-crowned trees, 10–25 m tall, crown radius 1–2 m, in a square."""
    h = rng.uniform(10.0, 25.0, n)
    return fw.Stand.from_arrays(
        x=x0 + rng.uniform(-half_width, half_width, n),
        y=rng.uniform(-half_width, half_width, n),
        height=h,
        crown_length=0.5 * h,
        crown_radius=rng.uniform(1.0, 2.0, n),
        favd=0.8,
        shape="cone",
    )


def fit_power(x, y):
    """Exponent b of y = a·x^b by least squares in log–log."""
    return float(np.polyfit(np.log(x), np.log(y), 1)[0])


def trees_in_footprint(rng, quick, repeats):
    """Cost vs number of trees inside the truncated footprint at a fixed density."""
    counts = [50, 100, 200, 400, 800] if quick else [50, 100, 200, 400, 800, 1600, 3200]
    accuracy = fw.AccuracySettings(column_spacing=0.3)
    tol = accuracy.footprint_tolerance
    rows = []
    for n in counts:
        radius = np.sqrt(n / DENSITY / np.pi)  # truncation radius holding n trees
        sigma = radius / np.sqrt(-2.0 * np.log(tol))
        sim = fw.WaveformSimulator(INSTRUMENT.with_overrides(footprint_sigma_m=sigma), accuracy)
        prepared = sim.prepare(uniform_stand(rng, int(4 * n / np.pi), radius))
        inside = int(np.sum(np.hypot(prepared.stand.x, prepared.stand.y) < radius))
        seconds = best_time(lambda s=sim, p=prepared: s.simulate(p), repeats)
        rows.append({"trees_inside": inside, "sigma_f_m": sigma, "seconds": seconds})
    x = [r["trees_inside"] for r in rows]
    y = [r["seconds"] for r in rows]
    half = len(rows) // 2
    return {
        "rows": rows,
        "exponent": fit_power(x, y),
        "exponent_upper_half": fit_power(x[half:], y[half:]),
        "expected": "linear (exponent ≈ 1)",
    }


def window_length(rng, quick, repeats):
    """Cost vs window length at a fixed canopy (200 trees, σf 5.5 m)."""
    sim = fw.WaveformSimulator(INSTRUMENT)
    prepared = sim.prepare(uniform_stand(rng, 400, 25.0))
    dz = INSTRUMENT.bin_height
    rows = []
    for factor in [1, 4, 16, 64] if quick else [1, 2, 4, 8, 16, 32, 64, 128]:
        heights = np.arange(-100, -100 + 300 * factor) * dz  # 300 bins ≈ 45 m: the canopy
        seconds = best_time(lambda h=heights: sim.simulate(prepared, heights=h), repeats)
        rows.append({"bins": heights.size, "window_m": heights.size * dz, "seconds": seconds})
    return {
        "rows": rows,
        "ratio_longest_to_shortest": rows[-1]["seconds"] / rows[0]["seconds"],
        "exponent": fit_power([r["bins"] for r in rows], [r["seconds"] for r in rows]),
        "expected": "flat beyond the canopy (ratio ≈ 1; only the O(bins) output arrays grow)",
    }


def trees_outside(rng, quick, repeats):
    """Extra cost of trees beyond the truncation radius."""
    sim = fw.WaveformSimulator(INSTRUMENT)
    r_max = sim.footprint_radius
    inside = uniform_stand(rng, 150, r_max / np.sqrt(2))
    rows = []
    for n_out in [0, 1000, 10000] if quick else [0, 1000, 10000, 100000]:
        ring = rng.uniform(r_max + 5.0, r_max + 200.0, n_out)
        angle = rng.uniform(0, 2 * np.pi, n_out)
        far = uniform_stand(rng, n_out, 1.0)
        far = fw.Stand.from_arrays(
            x=ring * np.cos(angle),
            y=ring * np.sin(angle),
            height=far.height,
            crown_length=far.crown_length,
            crown_radius=far.crown_radius,
            favd=0.8,
            shape="cone",
        )
        stand = fw.Stand(
            *(np.concatenate([getattr(inside, c), getattr(far, c)]) for c in _COLUMNS[:5]),
            shape=np.concatenate([inside.shape, far.shape]),
            favd=np.concatenate([inside.favd, far.favd]),
        )
        prepared = sim.prepare(stand)
        seconds = best_time(lambda p=prepared: sim.simulate(p), repeats)
        rows.append({"trees_outside": n_out, "seconds": seconds})
    return {
        "rows": rows,
        "ratio_most_outside_to_none": rows[-1]["seconds"] / rows[0]["seconds"],
        "expected": "≈ 1 (a k-d tree query skips them; per-stand preparation not timed)",
    }


_COLUMNS = ("x", "y", "height", "crown_length", "crown_radius")


def empty_scene(repeats):
    """An empty scene against the ground return alone (the pulse on the bins)."""
    sim = fw.WaveformSimulator(INSTRUMENT)
    prepared = sim.prepare(fw.Stand.empty())
    wf = sim.simulate(prepared)
    heights = wf.heights
    scene = best_time(lambda: sim.simulate(prepared), repeats)
    ground = best_time(
        lambda: ground_samples(sim, np.zeros(1), np.ones(1), heights), max(repeats, 20)
    )
    trees = best_time(lambda: sim.simulate(sim.prepare(uniform_stand(_rng(), 200, 20.0))), 3)
    return {
        "empty_scene_seconds": scene,
        "ground_return_alone_seconds": ground,
        "ratio": scene / ground,
        "stand_of_200_trees_seconds": trees,
        "expected": "the empty scene costs about the ground return plus fixed call overhead",
    }


def _rng():
    return np.random.default_rng(7)


def truncation(rng, quick, repeats):
    """Cost vs the footprint truncation tolerance on a wide uniform stand."""
    stand = uniform_stand(rng, 40000, 100.0)
    rows = []
    for tol in [1e-1, 1e-2, 1e-3, 1e-5, 1e-9] if quick else [1e-1, 1e-2, 1e-3, 1e-4, 1e-6, 1e-9]:
        sim = fw.WaveformSimulator(INSTRUMENT, fw.AccuracySettings(truncation_tolerance=tol))
        prepared = sim.prepare(stand)
        seconds = best_time(lambda s=sim, p=prepared: s.simulate(p), repeats)
        n_in = int(np.sum(np.hypot(stand.x, stand.y) < sim.footprint_radius + 2.0))
        rows.append({"tolerance": tol, "radius_m": sim.footprint_radius, "trees_reached": n_in,
                     "seconds": seconds})  # fmt: skip
    x = [-np.log(r["tolerance"]) for r in rows]
    return {
        "rows": rows,
        "exponent_vs_minus_ln_tol": fit_power(x, [r["seconds"] for r in rows]),
        "exponent_vs_trees_reached": fit_power(
            [r["trees_reached"] for r in rows], [r["seconds"] for r in rows]
        ),
        "expected": "flattening: the columns of the low-weight rim are few",
    }


def expected_model(quick, repeats):
    """The expected model (64 parameter vectors) with and without the understory layer."""
    heights = np.arange(-60, 340) * INSTRUMENT.bin_height
    free = ("density", "height_mean", "height_sd", "favd", "understory_lai")
    out = {}
    rows = 16 if quick else 64
    for label, lai in (("without_understory", 0.0), ("with_understory", 1.0)):
        template = StandParams(density=600.0, height_mean=18.0, height_sd=4.0,
                               understory_height=2.0, understory_lai=lai)  # fmt: skip
        model = ExpectedWaveformModel(INSTRUMENT, heights, template=template, free=free)
        theta = np.tile([600.0, 18.0, 4.0, 0.8, lai], (rows, 1))
        theta[:, 0] *= np.linspace(0.5, 1.5, rows)
        out[label] = best_time(lambda m=model, t=theta: m.evaluate(t), repeats) / rows
    out["ratio_with_to_without"] = out["with_understory"] / out["without_understory"]
    out["unit"] = "seconds per parameter vector"
    out["expected"] = "≈ 1 (the layer multiplies E[P] by one exponential)"
    out["changed"] = (
        "was ×1.69: an understory sent every row to the per-edge path; now the grid path "
        "adds it layer by layer below the understory top only (L1 ≤ 1e-3, "
        "tests/forward/expected/test_model.py)"
    )
    return out


def plot(summary, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 3, figsize=(13, 7.5))
    ms = lambda rows, key: [1e3 * r[key] for r in rows]  # noqa: E731
    t = summary["trees_in_footprint"]
    ax = axes[0, 0]
    ax.loglog([r["trees_inside"] for r in t["rows"]], ms(t["rows"], "seconds"), "o-")
    ax.set(xlabel="trees inside the truncated footprint", ylabel="ms per footprint",
           title=f"trees: slope {t['exponent']:.2f} (linear = 1)")  # fmt: skip
    w = summary["window_length"]
    ax = axes[0, 1]
    ax.semilogx([r["window_m"] for r in w["rows"]], ms(w["rows"], "seconds"), "o-")
    ax.set(xlabel="window length (m)", ylabel="ms", ylim=(0, None),
           title=f"window: ×{w['ratio_longest_to_shortest']:.2f} at the longest")  # fmt: skip
    o = summary["trees_outside"]
    ax = axes[0, 2]
    ax.plot([r["trees_outside"] for r in o["rows"]], ms(o["rows"], "seconds"), "o-")
    ax.set(xlabel="trees beyond the truncation radius", ylabel="ms", ylim=(0, None),
           title=f"outside: ×{o['ratio_most_outside_to_none']:.2f}")  # fmt: skip
    e = summary["empty_scene"]
    ax = axes[1, 0]
    labels = ["ground return\nalone", "empty scene", "200 trees"]
    values = [e["ground_return_alone_seconds"], e["empty_scene_seconds"],
              e["stand_of_200_trees_seconds"]]  # fmt: skip
    ax.bar(labels, [1e3 * v for v in values])
    ax.set(ylabel="ms", yscale="log", title="empty scene")
    r = summary["truncation"]
    ax = axes[1, 1]
    ax.semilogx([x["tolerance"] for x in r["rows"]], ms(r["rows"], "seconds"), "o-")
    ax.invert_xaxis()
    ax.set(xlabel="truncation tolerance", ylabel="ms",
           title=f"truncation: slope {r['exponent_vs_minus_ln_tol']:.2f} vs −ln tol")  # fmt: skip
    x = summary["expected_model"]
    ax = axes[1, 2]
    ax.bar(["without", "with"], [1e3 * x["without_understory"], 1e3 * x["with_understory"]])
    ax.set(ylabel="ms per parameter vector",
           title=f"expected model understory ×{x['ratio_with_to_without']:.2f}")  # fmt: skip
    fig.suptitle("Cost follows the scene (GEDI preset, single thread, min of repeats)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv=None):
    parser = harness.parser(__doc__, tag=False)
    parser.add_argument("--quick", action="store_true", help="fewer sizes and repeats")
    args = parser.parse_args(argv)
    repeats = 3 if args.quick else 7
    rng = np.random.default_rng(20260602)
    load_start = os.getloadavg()
    summary = {
        "quick": args.quick,
        "repeats": repeats,
        "cpu_count": os.cpu_count(),
        "trees_in_footprint": trees_in_footprint(rng, args.quick, repeats),
        "window_length": window_length(rng, args.quick, repeats),
        "trees_outside": trees_outside(rng, args.quick, repeats),
        "empty_scene": empty_scene(repeats),
        "truncation": truncation(rng, args.quick, repeats),
        "expected_model": expected_model(args.quick, repeats),
        "load_average_start_end": [load_start[0], os.getloadavg()[0]],
    }
    directory = harness.output_folder("scaling")
    harness.write_json(directory / "scaling.json", summary, indent=2)
    harness.write_json(OUT / "scaling.json", summary, indent=2)
    text = json.dumps(summary, indent=2, default=float)
    plot(summary, directory / "scaling.png")
    print(text)
    return summary


if __name__ == "__main__":
    main()
