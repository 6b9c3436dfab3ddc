"""A slow, obviously correct waveform model for testing the fast engine.

A regular grid of columns over the truncated footprint; every tree is tested against every
column, and where crowns overlap their optical depths add. Each column's optical depth is
evaluated from its definition, τ(z) = Σ k·G·Ω·u·(path length of the crown above z), at
fine edges; on sloped ground a crown is cut at its column's ground and the ground under a
column lies at its own height; a uniform understory adds its own depth to every column.
The footprint-mean return profile is the difference of the mean gap P = exp(−τ) between
edges, each fine layer's return is placed at its centre and convolved with the pulse by
direct summation, and each column's ground returns ρg·P at its ground height.

Columns are taken in blocks, so memory stays bounded whatever the grid.
"""

import numpy as np

from forward.crowns import crown_interval
from forward.scene import Ground


def reference_waveform(
    stand,
    instrument,
    heights,
    center=(0.0, 0.0),
    rho_v=0.45,
    rho_g=0.3,
    spacing=0.05,
    tolerance=1e-3,
    fine=0.01,
    ground=None,
    understory=None,
    block=1000,
):
    """Samples at ``heights`` (m) and the footprint-mean gap at the ground.

    Parameters
    ----------
    stand : Stand
    instrument : Instrument
    heights : array (m)
        Bin centres.
    center : (float, float) (m)
    rho_v, rho_g : float
        Canopy and ground reflectance (``ground`` overrides ``rho_g``).
    spacing : float (m)
        Column spacing.
    tolerance : float
        Footprint weight left out beyond the truncation radius.
    fine : float (m)
        Spacing of the height edges.
    ground : Ground, optional
    understory : UniformUnderstory, optional
    block : int
        Columns per block.
    """
    ground = Ground(rho_g) if ground is None else ground
    sigma = instrument.footprint_sigma_m
    r_max = sigma * np.sqrt(-2 * np.log(tolerance))
    axis = np.arange(-r_max, r_max + spacing / 2, spacing)
    gx, gy = (g.ravel() for g in np.meshgrid(axis, axis))
    keep = gx**2 + gy**2 <= r_max**2
    gx, gy = gx[keep], gy[keep]
    w = np.exp(-0.5 * (gx**2 + gy**2) / sigma**2)
    w /= w.sum()
    z_ground = ground.elevation(gx, gy)

    top = max(float(stand.height.max(initial=0.0)), understory.height if understory else 0.0)
    top += float(np.abs(z_ground).max()) + 1.0
    edges = np.arange(float(np.floor(z_ground.min())), top + fine, fine)
    alpha = instrument.extinction_per_favd * stand.favd
    stem_ground = ground.elevation(stand.x - center[0], stand.y - center[1])
    dz = instrument.bin_height
    pulse = instrument.pulse
    mean_gap = np.zeros(edges.size)
    ground_samples = np.zeros(heights.size)
    ground_gap = 0.0
    for start in range(0, gx.size, block):
        part = slice(start, start + block)
        tau = np.zeros((gx[part].size, edges.size))
        for i in range(stand.n_trees):
            d = np.hypot(gx[part] - (stand.x[i] - center[0]), gy[part] - (stand.y[i] - center[1]))
            inside = d < stand.crown_radius[i]
            if not inside.any():
                continue
            rho = d[inside] / stand.crown_radius[i]
            base = np.full(rho.size, stand.crown_base[i] + stem_ground[i])
            lo, hi = crown_interval(
                np.full(rho.size, stand.shape[i]),
                rho,
                base,
                np.full(rho.size, stand.crown_length[i]),
            )
            local = z_ground[part][inside]  # foliage below the column's ground does not exist
            lo, hi = np.maximum(lo, local), np.maximum(hi, local)
            path = np.clip(hi[:, None] - np.maximum(edges[None, :], lo[:, None]), 0, None)
            tau[inside] += alpha[i] * path
        if understory is not None:
            depth = understory.favd * instrument.extinction_per_favd
            tau += depth * np.clip(understory.height - edges, 0.0, understory.height)
        gap = np.exp(-tau)
        mean_gap += w[part] @ gap
        # all foliage lies above each column's ground, so P there is P at the lowest edge
        mass = w[part] * gap[:, 0]
        ground_gap += mass.sum()
        ground_samples += pulse.pdf(heights[:, None] - z_ground[part][None, :]) @ mass
    centres = 0.5 * (edges[1:] + edges[:-1])
    canopy = rho_v * dz * (pulse.pdf(heights[:, None] - centres[None, :]) @ np.diff(mean_gap))
    return canopy + ground.reflectance * dz * ground_samples, float(ground_gap)
