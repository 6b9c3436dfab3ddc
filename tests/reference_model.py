"""A slow, obviously correct waveform model for testing the fast engine.

Regular grid of columns, each tree tested against each column, the optical depth evaluated
from its definition at fine edges, the return profile differentiated numerically and
convolved with the pulse by direct summation.
"""

import numpy as np

from forward.crowns import crown_interval


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
):
    sigma = instrument.footprint_sigma_m
    r_max = sigma * np.sqrt(-2 * np.log(tolerance))
    axis = np.arange(-r_max, r_max + spacing / 2, spacing)
    gx, gy = np.meshgrid(axis, axis)
    r2 = gx**2 + gy**2
    keep = r2 <= r_max**2
    gx, gy = gx[keep], gy[keep]
    w = np.exp(-0.5 * r2[keep] / sigma**2)
    w /= w.sum()

    top = max(float(stand.height.max(initial=0.0)), 0.0) + 1.0
    edges = np.arange(0.0, top + fine, fine)
    tau = np.zeros((gx.size, edges.size))
    alpha = instrument.extinction_per_favd * stand.favd
    for i in range(stand.n_trees):
        d = np.hypot(gx - (stand.x[i] - center[0]), gy - (stand.y[i] - center[1]))
        inside = d < stand.crown_radius[i]
        if not inside.any():
            continue
        rho = d[inside] / stand.crown_radius[i]
        lo, hi = crown_interval(
            np.full(rho.size, stand.shape[i]), rho, stand.crown_base[i], stand.crown_length[i]
        )
        path = np.clip(hi[:, None] - np.maximum(edges[None, :], lo[:, None]), 0, None)
        tau[inside] += alpha[i] * path
    gap = w @ np.exp(-tau)  # footprint-mean P at the fine edges
    centres = 0.5 * (edges[1:] + edges[:-1])
    canopy_profile = rho_v * np.diff(gap) / fine  # ρv dP/dz (1/m)
    dz = instrument.bin_height
    pulse = instrument.pulse
    canopy = dz * (pulse.pdf(heights[:, None] - centres[None, :]) @ canopy_profile) * fine
    ground = dz * rho_g * gap[0] * pulse.pdf(heights)
    return canopy + ground, gap[0]
