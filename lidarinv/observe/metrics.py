"""Direct waveform metrics: RH percentiles (GEDI L2A) and gap, cover and PAVD (GEDI L2B).

These are the baseline that the inversion must beat. Each sample's energy is spread
uniformly over its bin, so cumulative energies are piecewise linear in height.
"""

from dataclasses import dataclass

import numpy as np

#: RH0 … RH100.
ALL_PERCENTILES = np.arange(101)


def _window(samples, axis, noise_mean, start, end):
    """Energies above the noise mean and the bin edges of the signal window."""
    samples = np.asarray(samples, float)
    axis = np.asarray(axis, float)
    if samples.shape != axis.shape or samples.size < 2:
        raise ValueError("metrics need samples and an axis of equal length ≥ 2")
    step = float(axis[1] - axis[0])
    top = axis[-1] if start is None else float(start)
    bottom = axis[0] if end is None else float(end)
    if top < bottom:
        raise ValueError(f"signal start {top} lies below signal end {bottom}")
    keep = (axis >= bottom - 1e-9 * step) & (axis <= top + 1e-9 * step)
    energy = np.clip(samples[keep] - noise_mean, 0.0, None)
    if energy.sum() <= 0:
        raise ValueError("no return energy above the noise mean in the signal window")
    centres = axis[keep]
    edges = np.concatenate([centres - 0.5 * step, [centres[-1] + 0.5 * step]])
    cumulative = np.concatenate([[0.0], np.cumsum(energy)])
    return edges, cumulative, step


def rh_metrics(
    samples,
    axis,
    ground: float,
    *,
    noise_mean: float = 0.0,
    start: float | None = None,
    end: float | None = None,
    percentiles=ALL_PERCENTILES,
) -> np.ndarray:
    """Relative heights in the GEDI L2A convention.

    RH_p is the height above the ground peak below which p % of the return energy
    between the signal end and the signal start lies. Each bin's energy is spread over
    the bin; RH is clipped to [end, start], so RH100 is the signal start minus ground.

    Parameters
    ----------
    samples, axis : arrays
        Waveform (digitiser units) and ascending axis (m).
    ground : float (m)
        Ground-peak position in axis units.
    noise_mean : float
        Subtracted from the samples (negative remainders count as 0).
    start, end : float (m), optional
        Signal start (top) and end (bottom) in axis units; default the whole window.
    percentiles : array
        Percentages in [0, 100].

    Returns
    -------
    array (m)
        RH for each percentile (RH0 may be negative: energy below the ground peak).

    References
    ----------
    Hofton, M. & Blair, J. B. (2019). *Algorithm Theoretical Basis Document (ATBD) for GEDI
    Transmit and Receive Waveform Processing for L1 and L2 Products*, version 1.0. NASA
    Goddard Space Flight Center, Greenbelt, MD (relative heights RH0–RH100 above the
    ground).
    Blair, J. B., Rabine, D. L. & Hofton, M. A. (1999). The Laser Vegetation Imaging Sensor:
    a medium-altitude, digitisation-only, airborne laser altimeter for mapping vegetation
    and topography. *ISPRS J. Photogramm. Remote Sens.* 54(2–3), 115–122.
    """
    percentiles = np.asarray(percentiles, float)
    if np.any((percentiles < 0) | (percentiles > 100)):
        raise ValueError("RH percentiles must lie in [0, 100]")
    edges, cumulative, step = _window(samples, axis, noise_mean, start, end)
    fraction = cumulative / cumulative[-1]
    heights = np.interp(percentiles / 100.0, fraction, edges)
    # for p = 0 take the lowest height where energy starts (skip empty leading bins)
    if np.any(percentiles == 0):
        heights[percentiles == 0] = edges[np.flatnonzero(fraction > 0)[0] - 1]
    # RH0 and RH100 are the signal end and start themselves (bin centres), not bin edges
    heights = np.clip(heights, edges[0] + 0.5 * step, edges[-1] - 0.5 * step)
    return heights - ground


@dataclass(frozen=True)
class GapProfile:
    """Direct gap-probability retrieval (GEDI L2B / MacArthur–Horn).

    Attributes
    ----------
    cover : float
        Canopy cover 1 − P(0).
    pai : float (m² m⁻²)
        Plant area index −ln P(0) / (k·G·Ω).
    height : array (m)
        Layer edges above the ground peak, from 0 up to the signal start.
    gap : array
        Gap probability P at ``height``.
    pavd : array (m² m⁻³)
        Plant area volume density of each layer between consecutive ``height`` values.
    canopy_energy, ground_energy : float
        Rv and Rg (digitiser units × bins).

    References
    ----------
    Tang, H. & Armston, J. (2019). *Algorithm Theoretical Basis Document (ATBD) for GEDI L2B
    Footprint Canopy Cover and Vertical Profile Metrics*, version 1.0. NASA Goddard Space
    Flight Center, Greenbelt, MD (cover, PAI and PAVD from the directional gap probability).
    MacArthur, R. H. & Horn, H. S. (1969). Foliage profile by vertical measurements.
    *Ecology* 50(5), 802–804.
    """

    cover: float
    pai: float
    height: np.ndarray
    gap: np.ndarray
    pavd: np.ndarray
    canopy_energy: float
    ground_energy: float
    extinction: float = 0.5

    def layer_pavd(self, layer_m: float = 5.0, n_layers: int | None = None) -> np.ndarray:
        """Mean PAVD (m² m⁻³) of layers ``layer_m`` thick from the ground up (GEDI L2B
        ``pavd_z``): the plant area between the layer's edges over its thickness."""
        if not layer_m > 0:
            raise ValueError(f"layer thickness must be positive, got {layer_m}")
        top = self.height[-1]
        count = max(int(np.ceil(top / layer_m)), 1) if n_layers is None else int(n_layers)
        edges = np.arange(count + 1) * layer_m
        area_above = -np.log(self.gap) / self.extinction
        # plant area above each edge; above the signal start there is none
        above = np.interp(edges, self.height, area_above, right=0.0)
        return -np.diff(above) / layer_m


def gap_profile(
    samples,
    axis,
    ground: float,
    *,
    noise_mean: float = 0.0,
    start: float | None = None,
    end: float | None = None,
    rho_ratio: float = 1.5,
    extinction: float = 0.5,
    ground_cdf=None,
) -> GapProfile:
    """Cover and a PAVD profile by the direct gap-probability method.

    The ground return Rg is the energy below the ground peak over the fraction of a
    ground return that lies below its peak (a half for a symmetric pulse: the peak
    mirrored); the canopy return is the rest, Rv. With ρv/ρg = ``rho_ratio``, the gap probability
    below height z is P(z) = 1 − Rv(>z) / (Rv + (ρv/ρg)·Rg), so P(0) is exact for the
    model of the physics conventions when the ground peak is symmetric and clear of the
    canopy. Foliage area above z is −ln P(z) / (k·G·Ω), ``extinction`` = k·G·Ω.

    Parameters
    ----------
    samples, axis, ground, noise_mean, start, end
        As in :func:`rh_metrics`.
    rho_ratio : float
        Assumed ρv/ρg (> 0); GEDI L2B uses 1.5.
    extinction : float
        k·G·Ω (> 0); 0.5 for a spherical leaf angle distribution with a full hot spot.
    ground_cdf : callable, optional
        Fraction of the ground return below a height offset from its peak (for the pulse
        as recorded; :func:`lidarinv.observe.instrument.ground_return_cdf`): the ground
        energy is then the energy below the peak over ``ground_cdf(0)``. Default: a
        symmetric return, mirrored about its peak.

    References
    ----------
    Tang, H. & Armston, J. (2019). *Algorithm Theoretical Basis Document (ATBD) for GEDI L2B
    Footprint Canopy Cover and Vertical Profile Metrics*, version 1.0. NASA Goddard Space
    Flight Center, Greenbelt, MD (the gap probability from the canopy and ground returns
    with ρv/ρg = 1.5, and PAVD).
    Armston, J., Disney, M., Lewis, P., Scarth, P., Phinn, S., Lucas, R., Bunting, P. &
    Goodwin, N. (2013). Direct retrieval of canopy gap probability using airborne waveform
    lidar. *Remote Sens. Environ.* 134, 24–38.
    Ni-Meister, W., Jupp, D. L. B. & Dubayah, R. (2001). Modeling lidar waveforms in
    heterogeneous and discrete canopies. *IEEE Trans. Geosci. Remote Sens.* 39(9),
    1943–1958.
    MacArthur, R. H. & Horn, H. S. (1969). Foliage profile by vertical measurements.
    *Ecology* 50(5), 802–804.
    """
    if not (rho_ratio > 0 and extinction > 0):
        raise ValueError("rho_ratio and extinction must be positive")
    edges, cumulative, step = _window(samples, axis, noise_mean, start, end)
    if not edges[0] <= ground <= edges[-1]:
        raise ValueError(f"ground {ground:.3f} lies outside the signal window")

    def below(z):  # energy below z, from the window bottom
        return np.interp(z, edges, cumulative, left=0.0, right=cumulative[-1])

    total = cumulative[-1]
    n_layers = max(int(np.ceil((edges[-1] - ground) / step)), 1)
    height = np.arange(n_layers + 1) * step
    z = ground + height
    if ground_cdf is None:  # a symmetric ground return: mirror the energy below its peak
        ground_energy = min(2.0 * below(ground), total)
        ground_above = below(2 * ground - z)
    else:
        ground_energy = min(below(ground) / float(ground_cdf(0.0)), total)
        ground_above = ground_energy * (1.0 - ground_cdf(height))
    canopy_energy = total - ground_energy
    canopy_above = np.clip(total - below(z) - ground_above, 0.0, None)
    canopy_above = np.minimum.accumulate(canopy_above)  # non-increasing upwards
    canopy_above[0] = canopy_energy
    scale = canopy_energy + rho_ratio * ground_energy
    gap = np.clip(1.0 - canopy_above / scale, 1e-12, 1.0)
    area_above = -np.log(gap) / extinction
    pavd = -np.diff(area_above) / step
    return GapProfile(
        cover=float(1.0 - gap[0]),
        pai=float(area_above[0]),
        height=height,
        gap=gap,
        pavd=pavd,
        canopy_energy=float(canopy_energy),
        ground_energy=float(ground_energy),
        extinction=float(extinction),
    )
