"""
Invert one real shot
====================

.. note::

   This tutorial is a stub: it is shown but not run when the documentation builds. It
   waits for the real example files the package will ship
   (``lidarinv.io.example_file("gedi-l1b")``, ``"lvis-l1b"``) and for observation files
   that carry their instrument. The code below shows the intended steps.

Steps: read one GEDI shot, invert it with the shot's own transmit pulse and noise, read
its footprint canopy height and cover, and set them beside the L2A RH98 and L2B cover.
"""

# %%
# One shot
# --------
from lidarinv.inference import invert_shot
from lidarinv.io import example_file, iter_observations  # example_file: to come

shot = next(iter(iter_observations(example_file("gedi-l1b"), beams=["BEAM0101"])))

# %%
# Invert it
# ---------
result = invert_shot(shot)
print(result.summary_table())

# %%
# Against the products
# --------------------
# ``footprint_top_height`` beside the L2A RH98 of the same shot number, ``cover``
# beside the L2B cover (a gap-based cover, which counts the gaps within crowns: see
# :doc:`/explanation/limitations`).
