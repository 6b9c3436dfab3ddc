"""
Invert a shot and read its posterior
====================================

The inversion samples the posterior of a stand's structure given one waveform (see
:doc:`/explanation/inference`). We simulate a GEDI shot whose truth we know, invert it,
and read what the posterior says.
"""

# %%
# A simulated shot
# ----------------
# ``lidarinv invert --example gedi-mixed`` inverts this same recipe: a random explicit
# stand of cones and ellipsoids (600 stems/ha, mean height 16 m) seen by the explicit
# engine, plus GEDI-like noise. The observation keeps the truth.
import numpy as np

from lidarinv.examples import SYNTHETIC_SHOTS, synthetic_shot
from lidarinv.inference import InversionResult, InversionSettings, SamplerSettings, invert_shot

rng = np.random.default_rng(0)
shot = synthetic_shot(SYNTHETIC_SHOTS["gedi-mixed"], rng, shot_id="demo")
print(
    {
        k: round(v, 3)
        for k, v in shot.truth.items()
        if k in ("cover", "top_height", "footprint_top_height", "pai")
    }
)

# %%
# Invert it
# ---------
# The defaults run the sampler to convergence (50 autocorrelation times, at most 20 000
# steps). To keep this page quick to build, we cap the run at 2500 steps; the result
# then says whether it converged.
settings = InversionSettings(sampler=SamplerSettings(max_steps=2500))
result = invert_shot(shot, settings, rng=rng)

# %%
# What to compare with a product
# ------------------------------
# ``lidarinv invert`` prints these lines first: the footprint's canopy height (its
# tallest stem; set it beside RH98) and its crown cover (beside a product's cover), then
# the stand's ``top_height``, the upper limit of its height distribution, which one
# footprint rarely reaches (:doc:`/explanation/limitations`).
from lidarinv.cli.invert import headline

print(headline(result))

# %%
# The full table
# --------------
# Every parameter and derived quantity, with its median and the 5, 16, 84 and 95 %
# quantiles; then the chain's diagnostics and any warnings.
print(result.summary_table())

# %%
# Read the posterior
# ------------------
# ``column`` gives the samples of any quantity; ask the posterior anything.
cover = result.column("cover")
height = result.column("footprint_top_height")
print(f"P(cover > 0.5) = {np.mean(cover > 0.5):.2f}")
print(
    f"canopy height 90 % interval: {np.percentile(height, 5):.1f}–"
    f"{np.percentile(height, 95):.1f} m (truth {shot.truth['footprint_top_height']:.1f} m)"
)
print(f"correlation of cover and PAI: {np.corrcoef(cover, result.column('pai'))[0, 1]:.2f}")

# %%
# One shot's interval may miss its truth (one in ten should, at 90 %). The footprint's
# tallest stem tends to sit a little low: the topmost metres of a stem are thin crown
# tips that return little light (:doc:`/explanation/limitations`); the calibration of
# these intervals over hundreds of shots is on :doc:`/validation/generated/calibration`.

# %%
# Save and load
# -------------
# A posterior file holds one group per shot (layout: :doc:`/how-to/posterior-file`).
import tempfile
from pathlib import Path

path = Path(tempfile.mkdtemp()) / "posterior.h5"
result.save(path, name="shot_demo")
again = InversionResult.load(path, name="shot_demo")
print(again.summary()["cover"])

# %%
# Check the fit
# -------------
# The outer band is where replicated observations fall (the model mean plus the noise
# and the model discrepancy): about 90 % of the observed samples should lie in it. The
# inner band is the model mean alone. The right panel shows the residuals.
from lidarinv.inference.results.plots import corner_plot, predictive_plot

predictive_plot(result)

# %%
# The joint posterior
# -------------------
# Titles: median [5 %, 95 %]. Orange: the truth of this simulated shot.
corner_plot(result, names=["cover", "pai", "top_height", "height_sd", "ground_elevation"])
