"""Sun & Ranson (2000) Fig. 1, 6, 7, 9 and 10, and a check of their qualitative findings.

- Fig. 1: expected waveform and crown-volume profile of the jack pine stand (ellipsoids).
- Fig. 6: first jack pine footprint (explicit stand of ``forward.examples``), cones,
  ellipsoids and hemi-ellipsoids: crown volume (solid) and waveform (dotted).
- Fig. 7: the nine footprints averaged after alignment on the ground peak, per shape.
- Fig. 9: the four successional stands (mixed cones/ellipsoids), expected waveform and
  crown volume, normalised by the maxima over all stands; one explicit realisation dotted.
- Fig. 10: the 200-year stand as cones, ellipsoids and hemi-ellipsoids.

The JSON summary records the findings as booleans with the numbers behind them, and the
relative L1 error of the explicit footprints of Fig. 6 and 7 against the engine run to
convergence.

    python studies/paper_figures.py [--quick]

Writes studies/output/paper_figures/{fig1,fig6,fig7,fig9,fig10}.png and summary.json.
"""

import json

import matplotlib

matplotlib.use("Agg")
import harness
import matplotlib.pyplot as plt
import numpy as np

import forward as fw
from forward import derived
from forward.examples import jack_pine
from forward.expected import ExpectedWaveformModel
from forward.paper_stands import (
    SUCCESSIONAL,
    jack_pine_instrument,
    jack_pine_params,
    successional_instrument,
    successional_params,
    successional_scene,
)

OUT = harness.OUTPUT / "paper_figures"
SHAPES = ("cone", "ellipsoid", "hemi-ellipsoid")
#: The explicit engine run to convergence, against which the figures' footprints are
#: checked (their relative L1 error is recorded in the summary).
CONVERGED = fw.AccuracySettings(tolerance=1e-4, truncation_tolerance=1e-7)


def expected(params, instrument, heights):
    model = ExpectedWaveformModel(instrument, heights, params)
    return model.evaluate(params)


def relative_l1(samples, reference):
    """Σ|W − W_ref| / ΣW_ref."""
    return float(np.abs(samples - reference).sum() / reference.sum())


def rise_distance(heights, canopy, fraction=0.1):
    """Height (m) from where the canopy return first reaches ``fraction`` of its peak,
    coming down from the top, to the peak: larger means a slower rising slope."""
    peak = int(np.argmax(canopy))
    above = np.flatnonzero(canopy >= fraction * canopy[peak])
    return float(heights[above.max()] - heights[peak])


def ground_peak(heights, samples, floor_fraction=0.05):
    """Lowest local maximum above a floor, located by a parabola through three bins (m)."""
    floor = floor_fraction * samples.max()
    for j in range(1, samples.size - 1):
        if samples[j] >= floor and samples[j] >= samples[j - 1] and samples[j] > samples[j + 1]:
            a, b, c = samples[j - 1 : j + 2]
            offset = 0.5 * (a - c) / (a - 2 * b + c) if (a - 2 * b + c) != 0 else 0.0
            return float(heights[j] + offset * (heights[1] - heights[0]))
    return float(heights[np.argmax(samples)])


def jack_pine_figures(quick):
    instrument = jack_pine_instrument()
    sim = fw.WaveformSimulator(instrument)
    heights = sim.default_heights(17.0, -1.0)
    results = {}
    # Fig. 1: expected waveform vs crown volume profile
    fig, ax = plt.subplots(figsize=(4, 5))
    params = jack_pine_params("ellipsoid")
    out = expected(params, instrument, heights)
    volume = derived.crown_volume_profile(params, heights)
    ax.plot(volume / volume.max(), heights, "k-", label="crown volume")
    ax.plot(out.samples[0] / out.samples[0].max(), heights, "k:", label="waveform")
    ax.set_xlabel("normalised")
    ax.set_ylabel("height (m)")
    ax.legend()
    ax.set_title("Fig. 1: jack pine, ellipsoids")
    fig.tight_layout()
    fig.savefig(OUT / "fig1.png", dpi=110)
    plt.close(fig)
    results["fig1"] = {
        "waveform_canopy_peak_m": float(heights[np.argmax(out.canopy[0])]),
        "crown_volume_peak_m": float(heights[np.argmax(volume)]),
    }
    # Fig. 6 and 7: explicit stands, nine 10 m footprints, per shape
    fig6, axes6 = plt.subplots(1, 3, figsize=(10, 4.5), sharey=True)
    fig7, ax7 = plt.subplots(figsize=(4.5, 5))
    centres = slice(0, 3) if quick else slice(0, 9)
    for k, shape in enumerate(SHAPES):
        scene = jack_pine(shape)
        waves = sim.simulate_many(
            scene.stand,
            scene.centers[centres],
            heights=heights,
            ground=scene.ground,
            canopy_reflectance=scene.canopy_reflectance,
        )
        converged = fw.WaveformSimulator(instrument, CONVERGED).simulate_many(
            scene.stand,
            scene.centers[centres],
            heights=heights,
            ground=scene.ground,
            canopy_reflectance=scene.canopy_reflectance,
        )
        errors = [relative_l1(w.samples, c.samples) for w, c in zip(waves, converged)]
        first = waves[0]
        axes6[k].plot(first.crown_volume / first.crown_volume.max(), heights, "k-")
        axes6[k].plot(first.samples / first.samples.max(), heights, "k:")
        axes6[k].set_title(shape)
        axes6[k].set_xlabel("normalised")
        # align on the ground peak, then average
        aligned = []
        for w in waves:
            shift = ground_peak(heights, w.samples)
            aligned.append(np.interp(heights, heights - shift, w.samples, left=0, right=0))
        mean = np.mean(aligned, axis=0)
        ax7.plot(mean / mean.max(), heights, label=shape)
        model = expected(jack_pine_params(shape), instrument, heights)
        prof = derived.crown_volume_profile(jack_pine_params(shape), heights)
        results[shape] = {
            "rise_distance_m_nine_footprints": rise_distance(
                heights, np.where(heights > 2.0, mean, 0.0)
            ),
            "rise_distance_m_expected": rise_distance(heights, model.canopy[0]),
            "waveform_canopy_peak_m": float(heights[np.argmax(model.canopy[0])]),
            "crown_volume_peak_m": float(heights[np.argmax(prof)]),
            "explicit_l1_against_converged_mean_max": [float(np.mean(errors)), max(errors)],
            "crown_volume_per_10m_footprint_m3": derived.crown_volume_per_ha(
                jack_pine_params(shape)
            )
            * np.pi
            * 25
            / 1e4,
        }
    axes6[0].set_ylabel("height (m)")
    fig6.suptitle("Fig. 6: first jack pine footprint (solid: crown volume, dotted: waveform)")
    fig6.tight_layout()
    fig6.savefig(OUT / "fig6.png", dpi=110)
    plt.close(fig6)
    ax7.set_xlabel("normalised")
    ax7.set_ylabel("height above ground peak (m)")
    ax7.legend()
    ax7.set_title("Fig. 7: nine footprints, aligned on the ground")
    fig7.tight_layout()
    fig7.savefig(OUT / "fig7.png", dpi=110)
    plt.close(fig7)
    return results


def tier_split(heights, volume):
    """Height (m) of the crown-volume minimum between the two tiers."""
    peaks = [
        j
        for j in range(1, volume.size - 1)
        if volume[j] > volume[j - 1]
        and volume[j] >= volume[j + 1]
        and volume[j] > 0.05 * volume.max()
    ]
    if len(peaks) < 2:
        return None
    lo, hi = peaks[0], peaks[-1]
    return float(heights[lo + int(np.argmin(volume[lo : hi + 1]))])


def successional_figures(quick):
    instrument = successional_instrument()
    sim = fw.WaveformSimulator(instrument)
    heights = sim.default_heights(30.0, -2.0)
    stands = {}
    for age in SUCCESSIONAL:
        params = successional_params(age)
        out = expected(params, instrument, heights)
        volume = derived.crown_volume_profile(params, heights)
        stands[age] = (params, out, volume)
    wmax = max(o.samples.max() for _, o, _ in stands.values())
    vmax = max(v.max() for _, _, v in stands.values())
    fig, axes = plt.subplots(1, 4, figsize=(12, 4.5), sharey=True)
    results = {}
    for ax, (age, (params, out, volume)) in zip(axes, stands.items()):
        ax.plot(volume / vmax, heights, "k-", label="crown volume")
        ax.plot(out.samples[0] / wmax, heights, "k:", label="expected waveform")
        if not quick:
            scene = successional_scene(age)
            w = sim.simulate(
                scene.stand,
                scene.centers[0],
                heights=heights,
                ground=scene.ground,
                canopy_reflectance=scene.canopy_reflectance,
            )
            ax.plot(w.samples / wmax, heights, color="0.6", lw=0.8, label="one realisation")
        ax.set_title(f"{age} years")
        ax.set_xlabel("normalised")
        split = tier_split(heights, volume)
        canopy = out.canopy[0]
        entry = {
            "mean_height_m": derived.mean_height(params),
            "expected_max_height_25m_m": derived.expected_max_height(params, 25.0),
            "lai": derived.leaf_area_index(params),
            "canopy_cover": derived.canopy_cover(params),
            "trees_per_25m_plot": params.density * np.pi * 12.5**2 / 1e4,
            "waveform_max": float(out.samples[0].max()),
            "ground_peak_is_waveform_max": bool(abs(heights[np.argmax(out.samples[0])]) < 1.0),
            "crown_volume_max": float(volume.max()),
            "tier_split_m": split,
        }
        if split is not None:
            below = heights < split
            upper_volume = volume[~below].sum() / volume.sum()
            entry["upper_tier_volume_fraction"] = float(upper_volume)
            entry["upper_tier_waveform_fraction"] = float(
                canopy[~below & (heights > 1.5)].sum() / canopy[heights > 1.5].sum()
            )
            # waveform share over volume share in the lower tier
            entry["lower_tier_visibility"] = float(
                (1 - entry["upper_tier_waveform_fraction"]) / (1 - upper_volume)
            )
            # E[P] at the split: the beam fraction that reaches the lower tier
            model = ExpectedWaveformModel(instrument, heights, params)
            entry["transmission_to_lower_tier"] = float(model.gap(params, [split])[0, 0])
        results[str(age)] = entry
    axes[0].set_ylabel("height (m)")
    axes[-1].legend(fontsize=7)
    fig.suptitle("Fig. 9: successional stands, conifers as cones, deciduous as ellipsoids")
    fig.tight_layout()
    fig.savefig(OUT / "fig9.png", dpi=110)
    plt.close(fig)
    # Fig. 10: the 200-year stand per shape
    fig, axes = plt.subplots(1, 3, figsize=(10, 4.5), sharey=True)
    shapes = {}
    for ax, shape in zip(axes, SHAPES):
        params = successional_params(200, shape)
        out = expected(params, instrument, heights)
        volume = derived.crown_volume_profile(params, heights)
        ax.plot(volume / volume.max(), heights, "k-")
        ax.plot(out.samples[0] / out.samples[0].max(), heights, "k:")
        ax.set_title(shape)
        ax.set_xlabel("normalised")
        shapes[shape] = {"rise_distance_m": rise_distance(heights, out.canopy[0])}
    axes[0].set_ylabel("height (m)")
    fig.suptitle("Fig. 10: 200-year stand (solid: crown volume, dotted: waveform)")
    fig.tight_layout()
    fig.savefig(OUT / "fig10.png", dpi=110)
    plt.close(fig)
    results["fig10"] = shapes
    return results


def main():
    parser = harness.parser(__doc__, tag=False)
    parser.add_argument("--quick", action="store_true", help="three footprints, no realisations")
    args = parser.parse_args()
    OUT.mkdir(parents=True, exist_ok=True)
    jp = jack_pine_figures(args.quick)
    su = successional_figures(args.quick)
    rise = {s: jp[s]["rise_distance_m_expected"] for s in SHAPES}
    rise9 = {s: jp[s]["rise_distance_m_nine_footprints"] for s in SHAPES}
    rise200 = {s: su["fig10"][s]["rise_distance_m"] for s in SHAPES}
    ages = [str(a) for a in SUCCESSIONAL]
    checks = {
        "cones_rise_slower_than_ellipsoids_and_hemi_ellipsoids_jack_pine": bool(
            rise["cone"] > max(rise["ellipsoid"], rise["hemi-ellipsoid"])
        ),
        "cones_rise_slower_nine_footprint_average": bool(
            rise9["cone"] > max(rise9["ellipsoid"], rise9["hemi-ellipsoid"])
        ),
        "cones_rise_slower_200_year_stand": bool(
            rise200["cone"] > max(rise200["ellipsoid"], rise200["hemi-ellipsoid"])
        ),
        "waveform_peak_above_crown_volume_peak": bool(
            all(jp[s]["waveform_canopy_peak_m"] > jp[s]["crown_volume_peak_m"] for s in SHAPES)
            and jp["fig1"]["waveform_canopy_peak_m"] > jp["fig1"]["crown_volume_peak_m"]
        ),
        "five_year_ground_peak_is_the_largest_return": bool(
            su["5"]["ground_peak_is_waveform_max"]
            and su["5"]["waveform_max"] == max(su[a]["waveform_max"] for a in ages)
        ),
        "two_hundred_year_stand_has_the_largest_crown_volume": bool(
            su["200"]["crown_volume_max"] == max(su[a]["crown_volume_max"] for a in ages)
        ),
        "lower_tier_holds_more_volume_at_20_and_60_years": bool(
            all(su[a].get("upper_tier_volume_fraction", 1.0) < 0.5 for a in ("20", "60"))
        ),
        "upper_tier_of_200_year_stand_occults_the_lower": bool(
            su["200"].get("transmission_to_lower_tier", 1.0) < 0.5
            and min(su[a].get("transmission_to_lower_tier", 0.0) for a in ("20", "60")) > 0.7
        ),
    }
    summary = {
        "checks": checks,
        "all_hold": all(checks.values()),
        "jack_pine": jp,
        "successional": su,
        "quick": args.quick,
    }
    harness.write_json(OUT / "summary.json", summary, indent=2)
    print(json.dumps(checks, indent=2))


if __name__ == "__main__":
    main()
