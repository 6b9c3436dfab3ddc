"""A tall, dense synthetic stand over one LVIS footprint under LVIS-like correlated noise:
the closed canopy the ground tests search under (shared by the observation tests)."""

from functools import lru_cache

import numpy as np

import forward as fw
from lidarinv.observe import observe

#: A digitiser noise filter whose autocorrelation is LVIS's measured one
#: (R(1), R(2), R(3) ≈ 0.60, 0.31, 0.11 on the Mondah waveforms' signal-free bins).
LVIS_NOISE_FILTER = [1.0, 0.858, 3.257, 1.661]
GROUND_Z = 100.0  # m


@lru_cache(maxsize=1)
def closed_canopy():
    """A tall (30–45 m), dense two-storey stand over one LVIS footprint: ground gap ≤ 0.03."""
    inst = fw.instrument_preset("lvis")
    rng = np.random.default_rng(3)
    grid = np.arange(-16, 16.1, 3.2)
    x, y = (a.ravel() + rng.uniform(-0.8, 0.8, a.size) for a in np.meshgrid(grid, grid))
    n, m = x.size, 60
    stand = fw.Stand.from_arrays(
        x=np.r_[x, rng.uniform(-16, 16, m)],
        y=np.r_[y, rng.uniform(-16, 16, m)],
        height=np.r_[rng.uniform(30, 45, n), rng.uniform(11, 20, m)],
        crown_length=np.r_[rng.uniform(10, 18, n), rng.uniform(4, 10, m)],
        crown_radius=np.r_[rng.uniform(2.5, 3.5, n), rng.uniform(1.0, 2.0, m)],
        favd=0.4,
        shape="ellipsoid",
    )
    heights = np.arange(-20, 60, inst.bin_height)
    waveform = fw.WaveformSimulator(inst).simulate(stand, heights=heights)
    return inst, waveform


def closed_canopy_shot(seed, gain=30000.0):
    """An observation of the closed canopy's waveform (noise seeded by ``seed``)."""
    inst, waveform = closed_canopy()
    return observe(waveform, gain=gain, baseline=64.0, noise_sigma=1.9, quantise=True,
                   rng=np.random.default_rng(seed), noise_filter=LVIS_NOISE_FILTER,
                   instrument=inst, ground_elevation=GROUND_Z)  # fmt: skip
