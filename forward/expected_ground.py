"""The ground's return and the total of the expected waveform, after the canopy's.

The ground is a pulse at each row's ground elevation, scaled by ρg·E[P(0)] and the bin
height; the canopy samples (before ρv) are scaled by ρv. Evaluated only over the bins
within the pulse's support around the lowest and highest ground of the batch. The numpy
function here is the reference of the compiled Gaussian-pulse kernel
(:func:`forward.expected_numba.gaussian_ground_return`), which takes the same arguments.
"""

import numpy as np


def ground_bins(heights, ground_elevation, support):
    """First and last-plus-one bin whose height lies within ``support`` (m, below and
    above) of some row's ground elevation (m)."""
    low, high = support
    first = max(int(np.searchsorted(heights, ground_elevation.min() + low)), 0)
    last = int(np.searchsorted(heights, ground_elevation.max() + high, side="right"))
    return first, last


def ground_return(canopy, gap0, ground_elevation, rho_v, rho_g, valid, heights, dz, pulse, support):
    """Samples, canopy and ground (n, bins) of rows with canopy samples before ρv
    (``canopy``, scaled in place), E[P(0)] ``gap0`` (n,), ground elevation (m), ρv and ρg
    (n,); rows not ``valid`` are zeros. ``heights`` (bins,) are the bin heights (m), ``dz``
    the bin height (m); ``pulse`` a :mod:`forward.pulse` pulse with support ``support``
    (m)."""
    first, last = ground_bins(heights, ground_elevation, support)
    ground = np.zeros_like(canopy)
    if last > first:
        shape = pulse.pdf(heights[None, first:last] - ground_elevation[:, None])
        ground[:, first:last] = (rho_g * gap0)[:, None] * dz * shape
    canopy *= rho_v[:, None]
    if not valid.all():
        canopy[~valid] = 0.0
        ground[~valid] = 0.0
    return canopy + ground, canopy, ground
