"""
Read real GEDI and LVIS files and compute metrics
=================================================

lidarinv ships a few shots of real NASA products: GEDI L1B, L2A and L2B over cerrado
savanna in Brazil, and LVIS L1B and L2 over tropical forest in Gabon
(:func:`lidarinv.io.example_file`). This tutorial reads the GEDI waveforms, analyses each
shot exactly as ``lidarinv metrics``, ``invert`` and ``batch`` do (noise, signal extent,
ground, quality flags, RH metrics, cover), and sets the results beside the products of
the same shots.
"""

# %%
# Read the shots
# --------------
# The reader knows the file is GEDI L1B: each shot carries its instrument, its
# transmitted waveform (the pulse), its geolocation and the product's noise fields.
# Shot numbers stay integers.
import matplotlib.pyplot as plt
import numpy as np

from lidarinv.io import example_file, iter_observations, read_gedi_l2a, read_gedi_l2b
from lidarinv.observe import analyse

shots = list(iter_observations(example_file("gedi-l1b")))
first = shots[0]
print(f"{len(shots)} shots; shot {first.shot_id} ({first.instrument}, {first.metadata['beam']}):")
print(
    f"  {first.n_bins} bins of {first.bin_size:.3f} m, {first.axis[0]:.1f}–{first.axis[-1]:.1f} m"
)
print(f"  transmitted pulse: {first.pulse.size} samples")

# %%
# One shot, analysed
# ------------------
# :func:`lidarinv.observe.analyse` measures the noise on the shot's signal-free bins
# (mean, σ, autocorrelation: GEDI's digitiser noise is strongly correlated from bin to
# bin), smooths the waveform by the σ of the shot's own pulse, finds the signal between a
# front and a back floor and takes the lowest significant mode as the ground.
result = analyse(first)
noise = result.noise
print(f"status {result.status}, quality {result.quality}, flags {result.flags}")
print(
    f"noise: mean {noise.mean:.2f} DN, σ {noise.sigma:.2f} DN, "
    f"R(1) = {noise.autocorrelation[1]:.2f}, smoothed σ {noise.smoothed_sigma:.2f} DN"
)
print(
    f"  (the file's own noise fields: mean {noise.product_mean:.2f}, σ {noise.product_sigma:.2f})"
)
print(
    f"ground {result.ground:.2f} ± {result.ground_uncertainty:.2f} m at "
    f"({result.latitude:.5f}, {result.longitude:.5f})"
)
print(
    f"RH50 {result.rh[50]:.2f} m, RH98 {result.rh[98]:.2f} m, cover {result.cover:.3f}, "
    f"sensitivity {result.sensitivity:.3f}"
)

# %%
# The figure marks what the analysis found: the smoothed waveform, the front and back
# floors, the signal start and end, and the ground beside the L2A ground.
from lidarinv.observe.figures import plot_analysis

l2a = read_gedi_l2a(example_file("gedi-l2a"))
fig, ax = plt.subplots(figsize=(4.5, 6))
plot_analysis(ax, first, result, product_ground=l2a[first.shot_id]["elev_lowestmode"])
ax.legend(fontsize=7)
fig.tight_layout()

# %%
# Every shot against the products
# -------------------------------
# The same analysis on every shot, set beside GEDI L2A (ground, RH98) and L2B (cover).
# ``lidarinv metrics FILE --csv out.csv`` writes the same records for a GIS.
l2b = read_gedi_l2b(example_file("gedi-l2b"))
rows = []
for shot in shots:
    r = analyse(shot)
    if r.ok:
        a, b = l2a[shot.shot_id], l2b[shot.shot_id]
        rows.append((r.ground - a["elev_lowestmode"], r.rh[98], a["rh"][98], r.cover, b["cover"]))
rows = np.array(rows)
print(f"{len(rows)} shots with metrics")
print(
    f"ground − L2A ground: median {np.median(rows[:, 0]):+.3f} m, "
    f"median |d| {np.median(np.abs(rows[:, 0])):.3f} m"
)
print(f"RH98 − L2A RH98: median {np.median(rows[:, 1] - rows[:, 2]):+.3f} m")
print(f"cover − L2B cover: median {np.median(rows[:, 3] - rows[:, 4]):+.3f}")

fig, axes = plt.subplots(1, 2, figsize=(8, 3.6))
axes[0].plot(rows[:, 2], rows[:, 1], "o", ms=4)
axes[0].plot([2, 10], [2, 10], "k-", lw=0.6)
axes[0].set_xlabel("L2A RH98 (m)")
axes[0].set_ylabel("lidarinv RH98 (m)")
axes[1].plot(rows[:, 4], rows[:, 3], "o", ms=4)
axes[1].plot([0, 0.4], [0, 0.4], "k-", lw=0.6)
axes[1].set_xlabel("L2B cover")
axes[1].set_ylabel("lidarinv cover (ρv/ρg = 1.5)")
fig.tight_layout()

# %%
# LVIS
# ----
# The LVIS reader works the same way; LVIS L2's RH convention accumulates the recorded
# counts (noise level included), and the analysis follows it for LVIS shots.
from lidarinv.io import read_lvis_l2

l2 = read_lvis_l2(example_file("lvis-l2"))
for shot in list(iter_observations(example_file("lvis-l1b")))[:5]:
    r = analyse(shot)
    product = l2.get(shot.shot_id)
    if r.ok and product is not None:
        print(
            f"{shot.shot_id}: ground {r.ground:.2f} m (L2 {product['zg']:.2f}), "
            f"RH98 {r.rh[98]:.2f} m (L2 {product['rh'][98]:.2f}), {r.n_modes} modes"
        )
