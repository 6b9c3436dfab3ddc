"""How one random arrangement of trees departs from the expected stand (issue: inversion).

For three GEDI stands (medium, dense and tall, sparse and short), many explicit random
realisations are simulated with the explicit engine, footprint at the plot centre. Per
bin, their spread around their mean is compared with that of a Poisson stand seen
through the Gaussian footprint: relative variance 1/N(z) for the canopy, N(z) the
footprint-weighted number of crowns spanning the bin's height
(:meth:`lidarinv.inference.model.stand.StandMapping.crowns_spanning`), and the
gap-fraction spread (1 − P̄)/P̄ · ā/A for the ground return
(:func:`forward.poisson_stand.footprint_gap_cv2`). Reported: the ratio of measured to
Poisson variance at the deciles of the canopy bins, the median relative spread of the
crown bins (the η of the ``discrepancy`` setting), and the ground return's measured and
modelled relative spread.

    python studies/discrepancy.py [--realisations 300] [--seed 0]

Writes studies/output/discrepancy/{summary.json,discrepancy.png}.
"""

import json
from dataclasses import replace

import matplotlib

matplotlib.use("Agg")
import harness
import matplotlib.pyplot as plt
import numpy as np

from forward import derived
from forward.expected import ExpectedWaveformModel
from forward.explicit import WaveformSimulator
from forward.instrument import instrument_preset
from forward.poisson_stand import crown_count, footprint_gap_cv2
from forward.realise import realise, scene_extras
from lidarinv.examples import SYNTHETIC_SHOTS
from lidarinv.inference.model.stand import TOP_SDS, StandMapping, default_template

BASE = SYNTHETIC_SHOTS["gedi-mixed"].params
STANDS = {
    "medium": BASE,
    "dense-tall": replace(
        BASE, density=1200.0, height_mean=22.0, height_sd=2.0, crown_length_ratio=0.35, favd=0.9
    ),
    "sparse-short": replace(
        BASE, density=250.0, height_mean=10.0, height_sd=1.5, crown_length_ratio=0.6, favd=0.4
    ),
}


def realisations(params, instrument, n, rng):
    """Canopy and ground parts (n, bins) of explicit realisations, and the heights."""
    top = params.height_mean + 2.0 * params.height_sd
    heights = np.arange(-5.0, top + 5.0, instrument.bin_height)
    side = 3.0 * instrument.footprint_diameter_m
    simulator = WaveformSimulator(instrument)
    ground, understory, rho_v = scene_extras(params)
    canopy, ground_part = [], []
    for _ in range(n):
        stand = realise(params, side, rng)
        w = simulator.simulate(stand, (side / 2, side / 2), heights, ground, rho_v, understory)
        canopy.append(w.canopy)
        ground_part.append(w.samples - w.canopy)
    return np.array(canopy), np.array(ground_part), heights


def crowns_spanning(params, heights, area):
    """Footprint-weighted number of crowns spanning each height, N(z)."""
    v = {
        "top_height": np.array([params.height_mean + TOP_SDS * params.height_sd]),
        "height_sd": np.array([params.height_sd]),
        "crown_length_ratio": np.array([params.crown_length_ratio]),
        "density_m2": np.array([params.density * 1e-4]),
    }
    return area * StandMapping(default_template()).crowns_spanning(v, heights[None, :])[0]


def main():
    parser = harness.parser(__doc__, seed=0, tag=False)
    parser.add_argument("--realisations", type=int, default=300)
    args = parser.parse_args()
    rng = np.random.default_rng(args.seed)
    instrument = instrument_preset("gedi")
    area = instrument.footprint_effective_area_m2
    summary = {"realisations": args.realisations, "footprint_area_m2": area, "stands": {}}
    fig, axes = plt.subplots(1, len(STANDS), figsize=(4 * len(STANDS), 4.5), sharey=False)
    for ax, (name, params) in zip(axes, STANDS.items()):
        canopy, ground, heights = realisations(params, instrument, args.realisations, rng)
        mean, var = canopy.mean(axis=0), canopy.var(axis=0)
        crowns = crowns_spanning(params, heights, area)
        in_crowns = (mean > 0.02 * mean.max()) & (crowns > 0)
        ratio = var[in_crowns] * np.maximum(crowns[in_crowns], 1.0) / mean[in_crowns] ** 2
        energy = ground.sum(axis=1)
        model = ExpectedWaveformModel(instrument, heights, params)
        understory_gap = np.exp(-instrument.extinction_per_favd * params.understory_lai)
        gap = model.evaluate(model.vector(params)).gap_ground / understory_gap
        crown_area = crown_count(derived.canopy_cover(params)) / (params.density * 1e-4)
        summary["stands"][name] = {
            "canopy_variance_ratio_deciles": np.percentile(ratio, np.arange(10, 100, 10)).tolist(),
            "median_crown_cv": float(np.median(np.sqrt(var[in_crowns]) / mean[in_crowns])),
            "max_crowns": float(crowns.max()),
            "ground_energy_cv": float(energy.std() / energy.mean()),
            "ground_cv_model": float(np.sqrt(footprint_gap_cv2(gap, crown_area, area))[0]),
        }
        ax.plot(np.sqrt(var), heights, label="realisations sd")
        poisson = np.where(in_crowns, mean / np.sqrt(np.maximum(crowns, 1.0)), np.nan)
        ax.plot(poisson, heights, "--", label="mean / √N(z), crown heights")
        ax.set_title(name)
        ax.set_xlabel("canopy return sd (apparent reflectance per bin)")
    axes[0].set_ylabel("height above ground (m)")
    axes[0].legend()
    folder = harness.output_folder("discrepancy")
    fig.tight_layout()
    fig.savefig(folder / "discrepancy.png", dpi=100)
    harness.write_json(folder / "summary.json", summary)
    print(json.dumps(summary, indent=1))


if __name__ == "__main__":
    main()
