"""The ground's return and the total of the expected waveform, after the canopy's.

The ground is a pulse at each row's ground elevation, scaled by ρg·E[P(0)] and the bin
height (:func:`forward.pulse.point_returns`); the canopy samples (before ρv) are scaled by
ρv. Evaluated only over the bins within the pulse's support around the lowest and
highest ground of the batch. :func:`ground_return` takes ``backend=``
(:mod:`forward.backends`), passed on to :func:`forward.pulse.point_returns`: compiled, a
Gaussian pulse is evaluated by exact ratios, three exponentials a row.
"""

from ..pulse import point_returns


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

    References
    ----------
    Sun, G. & Ranson, K. J. (2000). Modeling lidar returns from forest canopies. *IEEE
    Trans. Geosci. Remote Sens.* 38(6), 2617–2626 (Sec. II: the ground's pulse-shaped
    return, scaled by the gap at the ground).
    """
    ground = point_returns(
        pulse, heights, ground_elevation, rho_g * gap0, support, bin_height=dz, backend=backend
    )
    canopy *= rho_v[:, None]
    if not valid.all():
        canopy[~valid] = 0.0
        ground[~valid] = 0.0
    return canopy + ground, canopy, ground
