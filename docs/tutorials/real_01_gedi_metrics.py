"""
Read a real GEDI or LVIS file and compute metrics
=================================================

.. note::

   This tutorial is a stub: it is shown but not run when the documentation builds. It
   waits for the real example files the package will ship
   (``lidarinv.io.example_file("gedi-l1b")`` and the others) and for the real-file
   preprocessing. The code below shows the intended steps.

Steps: open a GEDI L1B file, read its shots as observations (noise, signal extent and
ground peak from each shot's own data), compute RH metrics and cover, and set them beside
the L2A and L2B products of the same shots.
"""

# %%
# Read the shots
# --------------
from lidarinv.io import example_file, iter_observations  # example_file: to come
from lidarinv.observe import analyse, rh_metrics

path = example_file("gedi-l1b")
shots = [s for s in iter_observations(path, beams=["BEAM0101"])][:5]

# %%
# Metrics of each shot
# --------------------
for shot in shots:
    analysis = analyse(shot)
    print(shot.shot_id, analysis.status, rh_metrics(shot, analysis))

# %%
# Against the products
# --------------------
# Read RH98 from the L2A file (``example_file("gedi-l2a")``) and cover from the L2B file
# (``example_file("gedi-l2b")``) for the same shot numbers, and compare.
