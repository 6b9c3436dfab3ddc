"""Peak memory of one footprint of the explicit engine in crowded scenes (issue 30).

Scenes:

- ``slabs100``: 100 slab-like crowns (cylinders 8–60 m wide, 0.5–3 m deep) within 30 m
  of a narrow beam (σf 2 m);
- ``slabs300``: 300 such crowns;
- ``deep_slabs100``: 100 crowns 8–60 m wide and 2–20 m deep over the same beam;
- ``crowds2000``: 2000 crowns 5–9 m wide within 25 m of a GEDI beam (σf 5.5 m).

Each scene and engine runs in a fresh process: the engine is imported and warmed up on a
small scene, then the footprint is simulated, and the study reports the growth of the
process's peak resident memory (``ru_maxrss``) over the warmed-up process, and the time.
The engines: the column engine (compiled kernel, and its numpy reference) and the
per-crown quadrature of earlier versions (4 × 8 nodes).

    python studies/forward_memory.py [--skip-old]

Writes studies/output/forward_memory/summary.json.
"""

import subprocess
import sys

import harness

OUT = harness.OUTPUT / "forward_memory"
LIMIT_MB = 200.0

SCENES = {
    "slabs100": "slabs(rng, 100)",
    "slabs300": "slabs(rng, 300)",
    "deep_slabs100": "slabs(rng, 100, depth=(2.0, 20.0))",
    "crowds2000": "crowds(rng, 2000)",
}
ENGINES = {
    "columns (numba)": "fw.AccuracySettings()",
    "columns (numpy)": "fw.AccuracySettings(backend='numpy')",
    "per-crown quadrature 4x8": "fw.AccuracySettings(radial_nodes=4, angular_nodes=8)",
}

CHILD = """
import resource, time
import numpy as np
import forward as fw

def slabs(rng, n, depth=(0.5, 3.0)):
    h = rng.uniform(5.0, 30.0, n)
    stand = fw.Stand.from_arrays(
        x=rng.uniform(-30, 30, n), y=rng.uniform(-30, 30, n), height=h,
        crown_length=np.minimum(rng.uniform(*depth, n), h), crown_radius=rng.uniform(4, 30, n),
        favd=rng.uniform(0.05, 0.5, n), shape="cylinder")
    return stand, fw.instrument_preset("gedi", footprint_sigma_m=2.0)

def crowds(rng, n):
    r = 25.0 * np.sqrt(rng.uniform(0, 1, n)); a = rng.uniform(0, 2 * np.pi, n)
    h = rng.uniform(10.0, 30.0, n)
    stand = fw.Stand.from_arrays(
        x=r * np.cos(a), y=r * np.sin(a), height=h, crown_length=0.5 * h,
        crown_radius=rng.uniform(2.5, 4.5, n), favd=0.6, shape=rng.choice(list(fw.SHAPE_NAMES), n))
    return stand, fw.instrument_preset("gedi")

rng = np.random.default_rng(30)
stand, instrument = {scene}
sim = fw.WaveformSimulator(instrument, {engine})
small = fw.Stand.from_arrays(x=[0.0, 1.0], y=[0.0, 0.5], height=[10.0, 12.0],
                             crown_length=[5.0, 6.0], crown_radius=[2.0, 9.0], favd=0.5)
sim.simulate(small)
base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
start = time.perf_counter()
try:
    wf = sim.simulate(stand)
    status = "ok"
except MemoryError as error:
    status = "MemoryError: " + str(error)[:120]
seconds = time.perf_counter() - start
peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
print(f"{{(peak - base) / 1024:.1f}} {{peak / 1024:.1f}} {{seconds:.3f}} {{status}}")
"""


def run(scene, engine):
    code = CHILD.format(scene=SCENES[scene], engine=ENGINES[engine])
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    if done.returncode != 0:
        return {"status": f"failed: {done.stderr.strip().splitlines()[-1][:200]}"}
    growth, peak, seconds, status = done.stdout.split(maxsplit=3)
    return {
        "peak_growth_mb": float(growth),
        "peak_rss_mb": float(peak),
        "seconds": float(seconds),
        "status": status.strip(),
    }


def main():
    parser = harness.parser(__doc__, tag=False)
    parser.add_argument("--skip-old", action="store_true", help="leave out the old engine")
    args = parser.parse_args()
    OUT.mkdir(parents=True, exist_ok=True)
    engines = [e for e in ENGINES if not (args.skip_old and e.startswith("per-crown"))]
    results = {}
    for scene in SCENES:
        results[scene] = {}
        for engine in engines:
            results[scene][engine] = row = run(scene, engine)
            print(f"{scene:11s} {engine:26s} {row}", flush=True)
    within = all(
        results[s][e].get("peak_growth_mb", float("inf")) <= LIMIT_MB
        for s in SCENES
        for e in engines
        if e.startswith("columns")
    )
    summary = {"limit_mb": LIMIT_MB, "columns_within_limit": within, "scenes": results}
    harness.write_json(OUT / "summary.json", summary, indent=2)
    print(f"wrote {OUT / 'summary.json'}")


if __name__ == "__main__":
    main()
