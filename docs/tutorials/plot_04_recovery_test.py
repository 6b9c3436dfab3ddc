"""
A synthetic recovery test
=========================

Before trusting an inversion on real data, check that it recovers known truths: draw
stands, simulate their shots with the explicit engine (not the model the inversion
uses), invert them and compare. ``studies/recovery.py`` does this on hundreds of shots
(:doc:`/validation/index`); here, three.
"""

# %%
# Stands with known structure
# ---------------------------
# :class:`forward.StandParams` describes a stand by its stem density, height
# distribution, crown shapes and allometry; a recipe adds the observation's gain and
# noise.
import matplotlib.pyplot as plt
import numpy as np

from forward import StandParams
from lidarinv.examples import ShotRecipe, synthetic_shot
from lidarinv.inference import InversionSettings, SamplerSettings, invert_shot


def stand(density, mean_height, height_sd, shapes):
    """A single-cohort stand with truncated-normal heights (the inversion's family)."""
    return StandParams(
        density=density,
        height_mean=mean_height,
        height_sd=height_sd,
        height_family="truncnorm",
        height_truncation=2.0,
        shape_mix=shapes,
    )


stands = [
    stand(300, 12, 2, {"cone": 1.0}),
    stand(600, 18, 3, {"cone": 0.5, "ellipsoid": 0.5}),
    stand(900, 24, 4, {"ellipsoid": 1.0}),
]
rng = np.random.default_rng(11)
shots = [synthetic_shot(ShotRecipe(p), rng, shot_id=i) for i, p in enumerate(stands)]

# %%
# Invert each
# -----------
# Capped at 1500 steps here; a study leaves the cap at 20 000 so that the chains
# converge.
# A shot the analysis cannot use (no signal, a ground outside the window) is refused
# with its reason, as ``lidarinv invert`` and ``lidarinv batch`` report it.
settings = InversionSettings(sampler=SamplerSettings(max_steps=1500))
inverted = []
for shot in shots:
    try:
        inverted.append((shot, invert_shot(shot, settings, rng=rng)))
    except ValueError as error:
        print(f"refused: {error}")

# %%
# Truth against the posterior
# ---------------------------
# For each quantity: the truth, the posterior median and its 90 % interval. Over many
# shots, 90 % of the truths should fall inside their intervals.
quantities = ["cover", "footprint_top_height", "mean_height", "ground_elevation"]
inside = []
for shot, result in inverted:
    summary = result.summary()
    for name in quantities:
        truth, q = shot.truth[name], summary[name]
        inside.append(q["p05"] <= truth <= q["p95"])
        print(
            f"shot {shot.shot_id} {name:<21} truth {truth:7.3f}  median {q['median']:7.3f}"
            f"  90 % [{q['p05']:.3f}, {q['p95']:.3f}]"
        )
print(f"{sum(inside)} of {len(inside)} truths inside their 90 % intervals")

# %%
fig, axes = plt.subplots(1, len(quantities), figsize=(11, 3))
for ax, name in zip(axes, quantities):
    for shot, result in inverted:
        q = result.summary()[name]
        ax.errorbar(
            shot.truth[name],
            q["median"],
            yerr=[[q["median"] - q["p05"]], [q["p95"] - q["median"]]],
            fmt="o",
            color="tab:blue",
        )
    lo, hi = ax.get_xlim()
    ax.plot([lo, hi], [lo, hi], color="0.6", lw=0.8)
    ax.set_title(name.replace("_", " "), fontsize=9)
    ax.set_xlabel("truth")
axes[0].set_ylabel("posterior median, 90 % interval")
fig.tight_layout()
