"""
Invert a file of shots in a batch
=================================

:func:`lidarinv.batch.invert_many` (``lidarinv batch`` on the command line) inverts many
shots in parallel into one resumable HDF5 file and a CSV summary: a rerun skips the
shots already done, and a shot that fails is recorded with its reason.
"""

# %%
# A file of shots
# ---------------
# Four simulated GEDI shots written in the lidarinv waveform layout
# (:func:`lidarinv.io.write_observations`); a GEDI L1B or LVIS L1B file is read the same
# way by :func:`lidarinv.io.iter_observations`.
import csv
import tempfile
from pathlib import Path

import numpy as np

from lidarinv.batch import invert_many, read_result
from lidarinv.examples import SYNTHETIC_SHOTS, synthetic_shot
from lidarinv.inference import InversionResult, InversionSettings, SamplerSettings
from lidarinv.io import iter_observations, write_observations

folder = Path(tempfile.mkdtemp())
rng = np.random.default_rng(3)
shots = [synthetic_shot(SYNTHETIC_SHOTS["gedi-mixed"], rng, shot_id=i) for i in range(3)]
write_observations(folder / "shots.h5", shots)

# %%
# Invert them
# -----------
# One local worker process here (``workers=None`` uses every core; ``executor=`` takes
# any ``concurrent.futures`` executor or a Dask client, see :doc:`/how-to/dask`). The
# steps are capped at 600 to keep this page quick: real runs leave the cap at 20 000.
# Each shot's seed derives from ``rng`` and its id, so the results do not depend on the
# scheduling.
settings = InversionSettings(sampler=SamplerSettings(max_steps=600))


def run_batch():
    return invert_many(
        iter_observations(folder / "shots.h5"),
        settings,
        output=folder / "results.h5",
        workers=1,
        rng=1,
        progress=False,
    )


summary = run_batch()
print(summary)

# %%
# The summary CSV
# ---------------
# One row per shot: its status, attempts, time and the posterior's quantiles.
with open(summary.csv, newline="") as handle:
    rows = list(csv.DictReader(handle))
for row in rows:
    print(
        row["shot_id"],
        row["status"],
        f"{float(row['seconds']):.1f} s",
        f"cover {float(row['cover_median']):.2f}",
        f"footprint canopy height {float(row['footprint_top_height_median']):.1f} m",
    )

# %%
# A shot's full posterior
# -----------------------
# Each finished shot is a group of the results file, read back as an
# :class:`~lidarinv.inference.InversionResult`.
result = read_result(folder / "results.h5", 1, InversionResult)
print(result.summary_table().splitlines()[-2])

# %%
# Resuming
# --------
# Run the same call again: every shot is found in the file and skipped.
print(run_batch())
