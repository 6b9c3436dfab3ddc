"""Throughput of batch inversion (issue 7): footprints per core-hour, overhead, GEDI orbit.

Shots: GEDI-like synthetic observations (1 ns bins, 15 ns pulse, σf 5.5 m, a 600-bin
window from 20 m below to 70 m above the ground) of footprints over random mixed stands,
simulated with the explicit forward model and ``lidarinv.observe.observe`` (baseline 230,
read-noise σ 2.5 digitiser units, as in GEDI L1B files).

For each number of local worker processes (1 and 2 by default) the batch runs once; its
steady-state wall time per shot is measured between the first and the last shot stored,
and the rest of the wall time is start-up (spawning the pool, importing). A plain serial
loop over the same inversion, with no pool and no file, is the baseline for the overhead;
storing its results into a file on its own gives the coordinator's cost per shot, which
caps the throughput however many workers there are. The inversion is
``lidarinv.inference.invert_shot`` with default settings, or with ``--fake`` the
stand-in ``lidarinv.testing.fake_inversion.fake_invert`` (``--delay`` s per shot; 0 measures the
batch machinery alone).

    python studies/batch_throughput.py --fake [--shots 400] [--workers 1 2]
    python studies/batch_throughput.py [--shots 16] [--max-steps 2000]

Writes studies/output/batch_throughput.json.

GEDI orbit (an assumption, from the instrument description in Dubayah et al. 2020,
Science of Remote Sensing 1, 100002): three lasers fire 242 times a second; one is split
into two beams, so four beams fire at 242 Hz (968 shots/s; dithering spreads them over
eight ground tracks 60 m apart along track). One ISS orbit lasts about 92.7 min (5560 s),
so an orbit holds ≈ 5.4 million shots if GEDI records all the way round; the share over
land and cloud-free is lower, so the figures are an upper bound.
"""

import json
import os
import tempfile
import time
from pathlib import Path

import h5py
import harness
import numpy as np

import forward as fw
from lidarinv.batch import ResultStore, invert_many
from lidarinv.observe import observe
from lidarinv.testing.fake_inversion import FakeSettings, fake_invert

OUT = harness.OUTPUT / "batch_throughput.json"

#: Assumed GEDI shots per orbit: 4 beams × 242 Hz × 5560 s (see the module docstring).
GEDI_SHOTS_PER_SECOND = 4 * 242
ISS_ORBIT_SECONDS = 5560.0
GEDI_SHOTS_PER_ORBIT = GEDI_SHOTS_PER_SECOND * ISS_ORBIT_SECONDS


def random_stand(rng, density_per_ha=600, half_width=40.0):
    n = rng.poisson(density_per_ha * (2 * half_width) ** 2 / 1e4)
    height = rng.uniform(8.0, 35.0, n)
    return fw.Stand.from_arrays(
        x=rng.uniform(-half_width, half_width, n),
        y=rng.uniform(-half_width, half_width, n),
        height=height,
        crown_length=rng.uniform(0.3, 0.6, n) * height,
        crown_radius=0.5 + rng.uniform(0.05, 0.1, n) * height,
        favd=0.6,
        shape=rng.choice(["cone", "ellipsoid", "hemi-ellipsoid", "cylinder"], n),
    )


def gedi_like_observations(n, rng, per_stand=8):
    """``n`` GEDI-like observations, ``per_stand`` footprints per random stand."""
    sim = fw.WaveformSimulator(fw.instrument_preset("gedi"))
    dz = sim.instrument.bin_height
    heights = np.arange(np.floor(-20.0 / dz), np.floor(-20.0 / dz) + 600) * dz
    shots = []
    while len(shots) < n:
        prepared = sim.prepare(random_stand(rng))
        centers = rng.uniform(-15.0, 15.0, (per_stand, 2))
        for wf in sim.simulate_many(prepared, centers, heights=heights):
            obs = observe(wf, gain=4000.0, baseline=230.0, noise_sigma=2.5, shot_factor=0.5,
                          rng=rng, shot_id=len(shots), instrument=sim.instrument)  # fmt: skip
            shots.append(obs)
    return shots[:n]


def serial_seconds(observations, invert, settings):
    """Wall time of a plain loop over the inversion (no pool, no file), and the results."""
    seeds = np.random.SeedSequence(1).spawn(len(observations))
    start = time.perf_counter()
    results = [invert(obs, settings, rng=np.random.default_rng(seed), progress=False)
               for seed, obs in zip(seeds, observations)]  # fmt: skip
    return time.perf_counter() - start, results


def store_seconds_per_shot(results, folder):
    """Coordinator time per shot to store results (group, attributes, flush)."""
    with ResultStore(Path(folder) / "store.h5", "timing") as store:
        start = time.perf_counter()
        for i, result in enumerate(results):
            store.write_done(result.shot_id, result, index=i, attempts=1, seconds=0.0,
                             worker="-", seed_key="-")  # fmt: skip
        return (time.perf_counter() - start) / len(results)


def orbit_hours(core_s_per_shot, store_s_per_shot, cores):
    """Hours for one orbit on ``cores`` worker cores, with one coordinator writing."""
    per_shot = max(core_s_per_shot / cores, store_s_per_shot)
    return GEDI_SHOTS_PER_ORBIT * per_shot / 3600.0


def batch_run(observations, invert, settings, workers, folder):
    """Wall time of a batch run, and its steady-state wall time per shot.

    The steady state is measured between the first and the last shot stored (their
    ``finished_at`` times), so it leaves out the pool start-up.
    """
    output = Path(folder) / f"batch-{workers}.h5"
    summary = invert_many(observations, settings, output=output, workers=workers,
                          invert=invert, rng=1, progress=False)  # fmt: skip
    if summary.n_done != len(observations):
        raise RuntimeError(f"{summary.n_failed} shot(s) failed: {summary.failed}")
    with h5py.File(output, "r") as handle:
        records = [json.loads(g.attrs["batch"]) for g in handle["shots"].values()]
    done = np.sort([r["finished_at"] for r in records])
    return summary.seconds, (done[-1] - done[0]) / (done.size - 1)


def main():
    parser = harness.parser(__doc__, tag=False)
    parser.add_argument("--fake", action="store_true", help="stand-in inversion (overhead)")
    parser.add_argument("--delay", type=float, default=0.0, help="fake seconds per shot")
    parser.add_argument("--shots", type=int, help="shots in the large run (small: 1/4)")
    parser.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--output", type=Path, default=OUT)
    parser.add_argument(
        "--max-steps", type=int, help="real inversion: cap the sampler steps (a quick run)"
    )
    args = parser.parse_args()

    if args.fake:
        invert, settings, kind = fake_invert, FakeSettings(delay=args.delay), "fake"
    else:
        from lidarinv.inference import invert_shot

        invert, settings, kind = invert_shot, None, "invert_shot (default settings)"
        if args.max_steps:
            from dataclasses import replace

            from lidarinv.inference import InversionSettings

            default = InversionSettings()
            sampler = replace(default.sampler, max_steps=args.max_steps)
            settings = replace(default, sampler=sampler)
            kind = f"invert_shot (max_steps={args.max_steps})"
    n_shots = args.shots or (400 if args.fake else 16)
    rng = np.random.default_rng(20261122)
    observations = gedi_like_observations(n_shots, rng)

    t_serial, results = serial_seconds(observations, invert, settings)
    serial_per_shot = t_serial / n_shots
    runs = []
    with tempfile.TemporaryDirectory() as folder:
        store_per_shot = store_seconds_per_shot(results, folder)
        for workers in args.workers:
            wall, steady = batch_run(observations, invert, settings, workers, folder)
            per_core_hour = 3600.0 / (steady * workers)
            runs.append({
                "workers": workers,
                "wall_s": wall,
                "steady_s_per_shot": steady,
                "startup_s": wall - steady * n_shots,
                "shots_per_s": 1.0 / steady,
                "footprints_per_core_hour": per_core_hour,
                "footprints_per_core_hour_incl_startup": 3600.0 * n_shots / (wall * workers),
                "overhead_core_ms_per_shot_vs_serial": 1e3 * (steady * workers - serial_per_shot),
                "orbit_hours_on": {str(c): orbit_hours(steady * workers, store_per_shot, c)
                                   for c in (16, 64, 256, 1024)},
            })  # fmt: skip
    serial_core_hour = 3600.0 / serial_per_shot
    result = {
        "inversion": kind,
        "fake_delay_s": args.delay if args.fake else None,
        "shots": n_shots,
        "bins_per_shot": int(observations[0].n_bins),
        "cpu_count": os.cpu_count(),
        "serial_s_per_shot": serial_per_shot,
        "serial_footprints_per_core_hour": serial_core_hour,
        "runs": runs,
        "gedi_orbit_assumption": {
            "shots_per_orbit": GEDI_SHOTS_PER_ORBIT,
            "basis": "4 beams x 242 Hz x 5560 s ISS orbit (Dubayah et al. 2020); "
            "all shots, no land or cloud screening: an upper bound",
        },
        "serial_orbit_core_hours": GEDI_SHOTS_PER_ORBIT / serial_core_hour,
        "store_s_per_shot": store_per_shot,
        "coordinator_ceiling_shots_per_hour": 3600.0 / store_per_shot,
        "orbit_hours_formula": "shots_per_orbit x max(core_s_per_shot / cores, "
        "store_s_per_shot) / 3600: the one coordinating process stores every shot",
        "note": "timings on a shared machine (2 cores, other jobs running); steady state "
        "between the first and the last stored shot; with the fake inversion the "
        "coordinator (one HDF5 group per shot, flushed) sets the rate",
    }
    args.output.parent.mkdir(parents=True, exist_ok=True)
    harness.write_json(args.output, result)
    print(f"{kind}: serial {1e3 * serial_per_shot:.2f} ms/shot "
          f"({serial_core_hour:,.0f} footprints/core-hour)")  # fmt: skip
    for run in runs:
        print(
            f"{run['workers']} worker(s): {1e3 * run['steady_s_per_shot']:.2f} ms/shot wall, "
            f"start-up {run['startup_s']:.1f} s, {run['footprints_per_core_hour']:,.0f} "
            f"footprints/core-hour, overhead {run['overhead_core_ms_per_shot_vs_serial']:+.2f} "
            f"core-ms/shot; GEDI orbit ({GEDI_SHOTS_PER_ORBIT / 1e6:.2f} M shots) on 64 cores: "
            f"{run['orbit_hours_on']['64']:.2f} h"
        )
    print(f"storing: {1e3 * store_per_shot:.2f} ms/shot on the coordinator "
          f"(ceiling {3600.0 / store_per_shot:,.0f} shots/hour)")  # fmt: skip
    print(f"wrote {args.output}")


if __name__ == "__main__":
    main()
