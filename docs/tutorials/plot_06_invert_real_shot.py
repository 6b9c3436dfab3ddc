"""
Invert one real shot
====================

A real GEDI shot from the shipped cerrado files (:func:`lidarinv.io.example_file`),
inverted with its own transmitted waveform as the pulse, its own noise (correlated from
bin to bin: the likelihood whitens it) and its own ground, then set beside the L2A and
L2B products of the same shot.
"""

# %%
# One shot and what the analysis finds
# ------------------------------------
import numpy as np

from lidarinv.inference import InversionSettings, SamplerSettings, invert_shot
from lidarinv.io import example_file, iter_observations, read_gedi_l2a, read_gedi_l2b
from lidarinv.observe import analyse

shot = list(iter_observations(example_file("gedi-l1b"), beams=["BEAM0010"]))[4]
analysis = analyse(shot)
print(
    f"shot {shot.shot_id}: {analysis.status}, ground {analysis.ground:.2f} m, "
    f"RH98 {analysis.rh[98]:.2f} m, {analysis.n_modes} mode(s), noise R(1) "
    f"{analysis.noise.autocorrelation[1]:.2f}"
)

# %%
# Invert it
# ---------
# The default discrepancy model simulates explicit stands around a first fit, which
# takes about a minute on a shot like this; the ``observed`` model, a discrepancy in
# proportion to the shot's own signal, is faster and keeps this page quick to build (it
# is the narrower of the two: see :doc:`/explanation/limitations`).
settings = InversionSettings(discrepancy_model="observed", sampler=SamplerSettings(max_steps=6000))
result = invert_shot(shot, settings, rng=np.random.default_rng(1))

from lidarinv.cli.invert import headline

print(headline(result))
for name in ("ground_elevation", "pulse_broadening", "rh98", "gap_cover"):
    low, median, high = np.percentile(result.column(name), [5, 50, 95])
    print(f"{name:18s} {median:8.3f}  [{low:.3f}, {high:.3f}] {result.units.get(name, '')}")
print("converged" if result.converged else f"not converged: {result.flags}")

# %%
# Against the products
# --------------------
# The posterior ground and RH98 beside L2A's, the tree canopy's gap cover beside L2B's
# ``cover`` (both gap-based). The posterior's RH98 is that of the model waveform; L2A
# computes its own on the smoothed waveform, which puts RH98 a few decimetres higher on
# shots like this one.
l2a = read_gedi_l2a(example_file("gedi-l2a"))[shot.shot_id]
l2b = read_gedi_l2b(example_file("gedi-l2b"))[shot.shot_id]
print(
    f"L2A ground {l2a['elev_lowestmode']:.2f} m, RH98 {l2a['rh'][98]:.2f} m; "
    f"L2B cover {l2b['cover']:.3f}"
)

# %%
# The posterior predictive check: the observed samples against the band of replicated
# observations (noise and discrepancy included), with the residuals beside.
from lidarinv.inference.results.plots import predictive_plot

figure = predictive_plot(result)
