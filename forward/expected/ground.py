"""The ground's return and the total of the expected waveform, after the canopy's.

The ground is a pulse at each row's ground elevation, scaled by ρg·E[P(0)] and the bin
height (:func:`forward.pulse.point_returns`); the canopy samples (before ρv) are scaled by
ρv. Evaluated only over the bins within the pulse's support around the lowest and
highest ground of the batch. :func:`ground_return` takes ``backend=``
(:mod:`forward.backends`): compiled, a Gaussian pulse is evaluated by exact ratios, three
exponentials a row.
"""

import numpy as np

from ..backends import jit, resolve
from ..pulse import GaussianPulse, point_returns, support_bins


def ground_return(
    canopy, gap0, ground_elevation, rho_v, rho_g, valid, heights, dz, pulse, support,
    *, backend="auto",
):  # fmt: skip
    """Samples, canopy and ground parts of the expected waveform.

    Parameters
    ----------
    canopy : array (n, bins)
        Canopy samples before ρv; scaled by ρv in place.
    gap0 : array (n,)
        E[P(0)].
    ground_elevation : array (n,) (m)
    rho_v, rho_g : array (n,)
        Canopy and ground reflectances.
    valid : array of bool (n,)
        Rows that are not valid come back as zeros.
    heights : array (bins,) (m)
        Bin heights, evenly spaced by ``dz``.
    dz : float (m)
        Bin height.
    pulse : GaussianPulse or MeasuredPulse
    support : (float, float) (m)
        The pulse's support (``pulse.support(tolerance)``).
    backend : str
        ``"auto"``, ``"numba"`` or ``"numpy"``; compiled for a Gaussian pulse only.

    Returns
    -------
    samples, canopy, ground : arrays (n, bins)
        ``samples = canopy + ground``.

    Notes
    -----
    ground_j = ρg·E[P(0)]·Δz·p(z_j − z_g) and canopy_j = ρv·C_j (physics conventions,
    "Radiative transfer"; :func:`forward.pulse.point_returns`).
    """
    compiled = resolve(backend) == "numba" and isinstance(pulse, GaussianPulse)
    first, last = support_bins(heights, ground_elevation, support)
    if compiled and last > first:
        sigma = pulse.sigma_m
        return _gaussian_ground(
            canopy, _f64(gap0), _f64(ground_elevation), _f64(rho_v), _f64(rho_g),
            np.ascontiguousarray(valid, dtype=np.bool_), float(heights[first]),
            float(dz / (sigma * np.sqrt(2.0 * np.pi))), float(sigma), float(dz / sigma),
            first, last,
        )  # fmt: skip
    ground = point_returns(pulse, heights, ground_elevation, rho_g * gap0 * dz, support)
    canopy *= rho_v[:, None]
    if not valid.all():
        canopy[~valid] = 0.0
        ground[~valid] = 0.0
    return canopy + ground, canopy, ground


def _f64(x):
    """``x`` as a C-contiguous float64 array (no copy if it already is one)."""
    return np.ascontiguousarray(x, dtype=np.float64)


@jit
def _gaussian_ground(
    canopy, gap0, zg, rho_v, rho_g, valid, h_first, scale, sigma, step, first, last
):
    """The kernel of :func:`ground_return` for a Gaussian pulse of sd ``sigma`` (m):
    ``scale`` = Δz/(σ√(2π)), ``step`` = Δz/σ, bins ``first`` to ``last`` − 1."""
    n, bins = canopy.shape
    ground = np.zeros((n, bins))
    total = np.empty((n, bins))
    factor = np.exp(-step * step)
    for r in range(n):
        if not valid[r]:
            canopy[r] = 0.0
            total[r] = 0.0
            continue
        # e^{−d²/2} at d_j = d_k + (j − k)δ from the bin k nearest the ground, by its exact
        # ratios e^{±d_jδ − δ²/2} (each the previous times e^{−δ²}): three exps a row
        offset = (zg[r] - h_first) / (sigma * step)
        k = min(max(first + int(np.floor(offset + 0.5)), first), last - 1)
        d = (k - first - offset) * step
        peak = rho_g[r] * gap0[r] * scale * np.exp(-0.5 * d * d)
        value, ratio = peak, np.exp(-d * step - 0.5 * step * step)
        for j in range(k, last):
            ground[r, j] = value
            value *= ratio
            ratio *= factor
        value, ratio = peak, np.exp(d * step - 0.5 * step * step)
        for j in range(k - 1, first - 1, -1):
            value *= ratio
            ratio *= factor
            ground[r, j] = value
        for j in range(bins):
            canopy[r, j] *= rho_v[r]
            total[r, j] = canopy[r, j] + ground[r, j]
    return total, canopy, ground
