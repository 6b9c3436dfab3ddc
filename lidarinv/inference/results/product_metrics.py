"""Relative heights of posterior waveforms in the convention of the instrument's product.

The model's RH (:func:`.model.waveform.relative_heights`) spreads the energy of the
noise-free model waveform over the whole window. The products measure RH otherwise:
GEDI L2A on the smoothed, noise-subtracted waveform, LVIS L2 on the recorded counts with
the noise level included, both between the shot's signal end and start
(:mod:`lidarinv.observe.processing`). On a tall LVIS canopy the noise level spread over
the extent lifts RH98 by metres, so a posterior RH98 in the model's convention and the
product's RH98 measure different things. :func:`product_relative_heights` applies the
product's convention to each posterior sample's expected recorded waveform, so that the
comparison is like with like.
"""

import numpy as np

from lidarinv.observe.signal import smooth

from ..model.waveform import relative_heights


def product_relative_heights(mean, axis, ground, baseline, analysis, processing, levels):
    """RH of expected recorded waveforms as the instrument's product computes it.

    Parameters
    ----------
    mean : array (n, bins) (DN)
        Expected recorded waveforms b + a·W on ``axis``.
    axis : array (bins,) (m)
        Bin centres, ascending in equal steps.
    ground : array (n,) (m)
        Each row's ground elevation on the axis.
    baseline : array (n,) (DN)
        Each row's noise mean b.
    analysis : lidarinv.observe.ShotAnalysis
        The shot's analysis: its signal start and end (m) and smoothing σ (bins).
    processing : lidarinv.observe.ProcessingSettings
        The product's RH convention (``rh_energy``, ``rh_smoothed``).
    levels : sequence of float
        Energy fractions in [0, 1].

    Returns
    -------
    array (n, len(levels)) (m)
        Heights above ``ground`` below which each fraction of the energy between the
        signal end and start lies, the energy smoothed by the analysis' σ where the
        product smooths, less ``baseline`` where it takes the energy above the noise;
        NaN where the extent holds no bin of ``axis`` or no energy.

    References
    ----------
    Hofton, M. & Blair, J. B. (2019). *Algorithm Theoretical Basis Document (ATBD) for GEDI
    Transmit and Receive Waveform Processing for L1 and L2 Products*, version 1.0. NASA
    Goddard Space Flight Center, Greenbelt, MD (GEDI L2A's RH on the smoothed, noise-
    subtracted waveform).
    Blair, J. B., Rabine, D. L. & Hofton, M. A. (1999). The Laser Vegetation Imaging Sensor:
    a medium-altitude, digitisation-only, airborne laser altimeter for mapping vegetation
    and topography. *ISPRS J. Photogramm. Remote Sens.* 54(2–3), 115–122 (LVIS L2's RH).
    """
    mean = np.atleast_2d(np.asarray(mean, float))
    axis = np.asarray(axis, float)
    if mean.shape[1] != axis.size:
        raise ValueError(f"waveforms of {mean.shape[1]} bins on an axis of {axis.size}")
    baseline = np.broadcast_to(np.asarray(baseline, float), (mean.shape[0],))
    energy = smooth(mean, analysis.smoothing_bins) if processing.rh_smoothed else mean
    if processing.rh_energy == "above-noise":
        energy = energy - baseline[:, None]
    step = axis[1] - axis[0]
    inside = (axis >= analysis.signal_end - 1e-9 * step) & (
        axis <= analysis.signal_start + 1e-9 * step
    )
    if not inside.any():
        return np.full((mean.shape[0], len(levels)), np.nan)
    ground = np.broadcast_to(np.asarray(ground, float), (mean.shape[0],))
    return relative_heights(energy[:, inside], axis[inside], ground, levels)
