"""
Simulate the waveform of a stand
================================

The explicit forward model (:mod:`forward`) turns a stem map into the waveform a lidar
records: single scattering through turbid crowns, a Gaussian footprint, a pulse and a
digitiser (see :doc:`/explanation/physics/index`). Here: the trees of the paper's jack
pine stand, seen by a GEDI-like instrument.
"""

# %%
# A stem map
# ----------
# The package ships a small one: trees of Sun & Ranson's (2000) jack pine stand in a
# 40 m square (x, y, height, crown length and radius in m, crown shape, FAVD in m² m⁻³).
from importlib.resources import files

import matplotlib.pyplot as plt
import numpy as np

import forward as fw

stand = fw.Stand.from_csv(files("lidarinv.data") / "stems.csv")
print(f"{stand.n_trees} trees, heights {stand.height.min():.1f}–{stand.height.max():.1f} m")

# %%
# An instrument and three footprints
# ----------------------------------
# ``instrument_preset`` gives the pulse, the digitiser bin and the footprint of a
# mission; any field can be overridden. GEDI: a 15 ns pulse, 1 ns bins and σf = 5.5 m
# (a 1/e² diameter of 22 m).
gedi = fw.instrument_preset("gedi")
print(gedi.describe())

simulator = fw.WaveformSimulator(gedi)
centres = [(45.0, 45.0), (50.0, 50.0), (55.0, 55.0)]
waveforms = simulator.simulate_many(
    stand, centres, ground=fw.Ground(reflectance=0.3), canopy_reflectance=0.45
)

# %%
# What a waveform holds
# ---------------------
# ``samples`` is the apparent reflectance per bin, the sum of a ``canopy`` and a
# ``ground`` part; ``gap`` is the footprint's mean gap probability P̄ and
# ``crown_volume`` its crown volume per bin. The energies obey the conventions'
# closure exactly: canopy + ground = ρv (1 − P̄(0)) + ρg P̄(0).
for wf in waveforms:
    closure = 0.45 * (1 - wf.ground_gap) + 0.3 * wf.ground_gap
    print(
        f"centre {wf.center}: canopy {wf.canopy_energy:.4f} + ground {wf.ground_energy:.4f}"
        f" = {wf.canopy_energy + wf.ground_energy:.6f}; closure {closure:.6f}"
    )

# %%
# The waveform beside the crown-volume profile
# --------------------------------------------
# As in the paper's Fig. 1, the canopy peak sits above the crown-volume peak: the
# upper crown shades the lower one.
fig, axes = plt.subplots(1, 3, figsize=(9, 4.5), sharey=True)
for ax, wf in zip(axes, waveforms):
    ax.plot(wf.samples / wf.samples.max(), wf.heights, "k:", label="waveform")
    ax.plot(
        wf.crown_volume / wf.crown_volume.max(),
        wf.heights,
        color="forestgreen",
        label="crown volume",
    )
    ax.set_xlabel("normalised to its maximum")
    ax.set_title(f"({wf.center[0]:.0f}, {wf.center[1]:.0f}) m", fontsize=9)
axes[0].set_ylabel("height above ground (m)")
axes[0].legend(fontsize=8)
fig.tight_layout()

# %%
# The same from the command line
# ------------------------------
# ``lidarinv simulate STEMS.csv --instrument gedi --center 50 50 -o out.h5 --plot out.png``
# writes the same waveforms to HDF5 (layout in :mod:`lidarinv.io.simulation`). These
# are noise-free; :func:`lidarinv.observe.observe` turns them into observations in
# digitiser units, which the inversion takes:
from lidarinv.observe import observe

rng = np.random.default_rng(1)
shot = observe(
    waveforms[1].samples,
    heights=waveforms[1].heights,
    gain=2500.0,
    baseline=50.0,
    noise_sigma=2.0,
    rng=rng,
    shot_id=1,
    instrument="gedi",  # recorded with the shot: the inversion reads it
)
print(f"observed: {shot.n_bins} bins, {shot.samples.min():.1f}–{shot.samples.max():.1f} DN")
