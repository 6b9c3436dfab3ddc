"""The ground return's width: the shot's pulse broadened to fit the ground's lower flank.

A flat, smooth ground returns the transmitted pulse. Real ground returns are wider: the
receiver's response, the terrain's slope and roughness within the footprint spread them
(GEDI's ground returns over bare cerrado are about twice as wide as their transmitted
waveforms; LVIS's barely wider). Read as vegetation, that width becomes a fictitious
understorey and pulls the ground down. The lower flank of the ground return, below its
peak, holds no vegetation, so it measures the width: :func:`fit_ground_return` fits
``A·(p ⊛ N(0, s²))(z − z_g)`` to the samples from four widths below the ground peak to
a quarter width above it, over a grid of broadenings ``s`` and ground positions ``z_g``
(the amplitude ``A`` by least squares at each), ``p`` being the shot's pulse with its
peak at zero. The broadened pulse is then the shot's effective pulse, and ``z_g`` the
ground in the model's registration (the effective pulse's peak on the ground).
"""

from dataclasses import dataclass

import numpy as np

from forward.pulse import GaussianPulse

#: Broadenings (m) searched: σ of the Gaussian the pulse is convolved with.
BROADENING_GRID_M = np.arange(0.0, 3.0001, 0.05)
#: Ground positions searched, about the detected ground (m).
POSITION_SPAN_M, POSITION_STEP_M = 1.0, 0.025
#: Resolution (m) of the pulse densities.
DENSITY_STEP_M = 0.01


@dataclass(frozen=True)
class GroundReturnFit:
    """The ground return fitted with the broadened pulse.

    Attributes
    ----------
    position : float (m)
        Ground, where the broadened pulse's peak sits (axis units).
    broadening : float (m)
        σ of the Gaussian that broadens the pulse.
    broadening_range : (float, float) (m)
        Broadenings whose misfit is within one (correlated) noise unit of the best.
    amplitude : float (DN per unit density)
        A.
    n_bins : int
        Samples fitted.
    """

    position: float
    broadening: float
    broadening_range: tuple
    amplitude: float
    n_bins: int


def broadened_densities(pulse, widths, step=DENSITY_STEP_M):
    """Densities of the pulse convolved with Gaussians of σ ``widths`` (m), each with its
    peak at offset zero: (offsets, densities (len(widths), len(offsets)))."""
    low, high = pulse.support(1e-6)
    pad = 5.0 * float(np.max(widths))
    offsets = np.arange(low - pad, high + pad + step, step)
    base = pulse.pdf(offsets)
    out = np.empty((len(widths), offsets.size))
    for i, width in enumerate(widths):
        if width <= 0:
            out[i] = base
            continue
        half = int(np.ceil(5.0 * width / step))
        kernel = np.exp(-0.5 * (np.arange(-half, half + 1) * step / width) ** 2)
        out[i] = np.convolve(base, kernel / kernel.sum(), mode="same")
    return offsets, out, np.array([_peak(offsets, row) for row in out])


def _peak(offsets, density) -> float:
    """The density's peak, refined by the parabola through its three highest samples."""
    k = int(np.argmax(density))
    if 0 < k < density.size - 1:
        a, b, c = density[k - 1 : k + 2]
        curvature = a - 2.0 * b + c
        if curvature < 0:
            return float(offsets[k] + 0.5 * (a - c) / curvature * (offsets[1] - offsets[0]))
    return float(offsets[k])


def fit_ground_return(samples, axis, noise_mean, noise_sigma, pulse, ground, tau=1.0):
    """Fit the shot's broadened pulse to its ground return's lower flank.

    Parameters
    ----------
    samples, axis : arrays
        Waveform (DN) on its ascending axis (m).
    noise_mean, noise_sigma : float (DN)
        The shot's noise.
    pulse : GaussianPulse or MeasuredPulse
        The shot's pulse (peak at offset 0).
    ground : float (m)
        The detected ground (the lowest mode), the centre of the positions searched.
    tau : float
        Integrated autocorrelation time of the noise (the misfit's noise unit is
        τ·σn²).

    Returns
    -------
    GroundReturnFit
    """
    samples = np.asarray(samples, float)
    axis = np.asarray(axis, float)
    offsets, densities, peaks = broadened_densities(pulse, BROADENING_GRID_M)
    narrowest, widest = _half_width(offsets, densities[0]), _half_width(offsets, densities[-1])
    positions = ground + np.arange(-POSITION_SPAN_M, POSITION_SPAN_M + 1e-9, POSITION_STEP_M)
    # one window for every width: from where the widest return has died away below the
    # ground to a quarter of the pulse's half width above it
    use = (axis >= ground - POSITION_SPAN_M - 3.0 * widest) & (axis <= ground + 0.25 * narrowest)
    z, y = axis[use], samples[use] - noise_mean
    best = (np.inf, 0.0, 0, 0.0, z.size)
    misfits = np.full((BROADENING_GRID_M.size, positions.size), np.inf)
    for i in range(BROADENING_GRID_M.size):
        # the density at each bin for each position, the peak registered at the position
        d = np.interp(z[None, :] - positions[:, None] + peaks[i], offsets, densities[i])
        norm = np.sum(d * d, axis=1)
        amplitude = np.where(norm > 0, d @ y / np.where(norm > 0, norm, 1.0), 0.0)
        misfit = np.sum((y[None, :] - amplitude[:, None] * d) ** 2, axis=1)
        misfits[i] = misfit
        j = int(np.argmin(misfit))
        if misfit[j] < best[0]:
            best = (misfit[j], positions[j], i, amplitude[j], z.size)
    _, position, index, amplitude, n_bins = best
    # broadenings within Δχ² = 1 of the best (the noise unit τ·σn² for correlated noise)
    unit = tau * noise_sigma**2
    within = BROADENING_GRID_M[np.min(misfits, axis=1) <= best[0] + unit]
    return GroundReturnFit(
        position=float(position),
        broadening=float(BROADENING_GRID_M[index]),
        broadening_range=(float(within.min()), float(within.max())),
        amplitude=float(amplitude),
        n_bins=int(n_bins),
    )


def mode_offset(pulse, sigma_m: float) -> float:
    """Where the peak of the pulse convolved with N(0, σ²) lies relative to the pulse's own
    peak (m): below it for a pulse with a tail in time (GEDI, LVIS), nowhere else for a
    symmetric (Gaussian) pulse."""
    if isinstance(pulse, GaussianPulse):
        return 0.0
    _, _, peaks = broadened_densities(pulse, [float(sigma_m)])
    return float(peaks[0])


def registered_ground(detected: float, pulse, broadening_m: float, smoothing_m: float) -> float:
    """The ground in the model's registration (the pulse's peak on the ground, physics
    conventions) from the detected lowest mode of the smoothed waveform: a flat ground's
    return, the pulse broadened by ``broadening_m`` and smoothed by ``smoothing_m``, peaks
    :func:`mode_offset` away from the ground."""
    return float(detected - mode_offset(pulse, np.hypot(broadening_m, smoothing_m)))


def _half_width(offsets, density) -> float:
    """Half the width at half maximum of a density (m)."""
    above = offsets[density >= 0.5 * density.max()]
    return 0.5 * float(above[-1] - above[0]) if above.size > 1 else 0.0
