"""The Gaussian footprint: its weight, its truncation, and the crown cover under it.

Both engines and the inversion weigh the ground under a beam by one Gaussian,
w(r) = exp(−r²/2σf²)/(2πσf²), of unit integral over the plane (physics conventions,
"Footprint"). Its shape is written once, :func:`footprint_falloff`; the normalised weight
(:func:`gaussian_footprint_weight`), the weight truncated and renormalised at a stated
tolerance (:func:`truncated_footprint_weight`), the columns of the explicit engine and
the crown cover of a footprint (:func:`footprint_crown_cover`) all call it.
"""

import numpy as np


def footprint_falloff(scaled_squared_distance):
    """Relative weight of the Gaussian footprint, exp(−r²/2σf²).

    Parameters
    ----------
    scaled_squared_distance : float or array
        r²/σf²: the squared distance from the beam centre in units of σf².

    Returns
    -------
    float or array
        exp(−r²/2σf²), 1 at the beam centre.
    """
    return np.exp(-0.5 * scaled_squared_distance)


def gaussian_footprint_weight(squared_distance, sigma):
    """Weight of a Gaussian footprint of sd ``sigma`` (m) at squared distance r² (m²).

    Parameters
    ----------
    squared_distance : float or array (m²)
        r² from the beam centre.
    sigma : float (m)
        σf.

    Returns
    -------
    float or array (1/m²)
        w(r) = exp(−r²/2σf²)/(2πσf²), of unit integral over the plane (physics
        conventions, "Footprint").

    References
    ----------
    Sun, G. & Ranson, K. J. (2000). Modeling lidar returns from forest canopies. *IEEE
    Trans. Geosci. Remote Sens.* 38(6), 2617–2626 (Sec. II-B: the Gaussian intensity across
    the footprint).
    Blair, J. B. & Hofton, M. A. (1999). Modeling laser altimeter return waveforms over
    complex vegetation using high-resolution elevation data. *Geophys. Res. Lett.* 26(16),
    2509–2512.
    """
    s2 = sigma * sigma
    return footprint_falloff(squared_distance / s2) / (2.0 * np.pi * s2)


def truncation_radius(sigma, tolerance):
    """Radius outside which the Gaussian footprint holds ``tolerance`` of its weight.

    Parameters
    ----------
    sigma : float (m)
        σf.
    tolerance : float
        Weight left out, in (0, 1).

    Returns
    -------
    float (m)
        r_max = σf·sqrt(−2 ln tolerance) (physics conventions, "Footprint").

    Raises
    ------
    ValueError
        For a tolerance outside (0, 1).
    """
    if not 0.0 < tolerance < 1.0:
        raise ValueError(f"truncation tolerance must lie in (0, 1), got {tolerance}")
    return sigma * np.sqrt(-2.0 * np.log(tolerance))


def truncated_footprint_weight(dx, dy, sigma, tolerance):
    """The Gaussian footprint weight truncated at :func:`truncation_radius` and
    renormalised to unit mass.

    Parameters
    ----------
    dx, dy : float or array (m)
        Offsets from the beam centre.
    sigma : float (m)
        σf.
    tolerance : float
        Weight left out beyond the truncation radius.

    Returns
    -------
    float or array (1/m²)
        w(r)/(1 − tolerance) inside the truncation radius, 0 outside.
    """
    r2 = dx * dx + dy * dy
    inside = r2 <= truncation_radius(sigma, tolerance) ** 2
    peak = 1.0 / (2.0 * np.pi * sigma * sigma * (1.0 - tolerance))
    return np.where(inside, peak * footprint_falloff(r2 / (sigma * sigma)), 0.0)


def footprint_crown_cover(stand, centre, sigma, radius_sigmas=3.0, step=0.2) -> float:
    """Crown cover of one footprint: the fraction of the ground under at least one crown,
    weighted by the Gaussian footprint.

    Parameters
    ----------
    stand : forward.stand.Stand
    centre : (float, float) (m)
        The beam centre.
    sigma : float (m)
        Footprint σf.
    radius_sigmas : float
        The sum runs over a disc of this many σf.
    step : float (m)
        Grid step of the sum.

    Returns
    -------
    float
        Σ w·[covered] / Σ w with w = exp(−r²/2σf²) over the grid nodes in the disc; 0 with
        no crown over it, 1 with every node covered.
    """
    reach = radius_sigmas * sigma
    offsets = np.arange(-reach, reach + step / 2, step)
    dx, dy = np.meshgrid(offsets, offsets, indexing="ij")
    inside = dx**2 + dy**2 <= reach**2
    weight = np.where(inside, footprint_falloff((dx**2 + dy**2) / sigma**2), 0.0)
    covered = np.zeros(dx.shape, bool)
    x, y = stand.x - centre[0], stand.y - centre[1]
    near = np.hypot(x, y) <= reach + stand.crown_radius
    for cx, cy, r in zip(x[near], y[near], stand.crown_radius[near]):
        i0, i1 = np.searchsorted(offsets, [cx - r, cx + r], side="left")
        j0, j1 = np.searchsorted(offsets, [cy - r, cy + r], side="left")
        i1, j1 = i1 + 1, j1 + 1  # the box's last node may lie on the crown's edge
        box = (dx[i0:i1, j0:j1] - cx) ** 2 + (dy[i0:i1, j0:j1] - cy) ** 2 <= r * r
        covered[i0:i1, j0:j1] |= box
    return float(np.sum(weight[covered]) / np.sum(weight))
