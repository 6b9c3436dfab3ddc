"""From footprint-mean gap profiles to a sampled waveform (conventions, "Pulse and
digitiser").

The canopy return of each fine layer, ρv·(P̄(top) − P̄(bottom)), is spread evenly over the
layer and convolved with the pulse (:func:`forward.pulse.layer_kernel`); the ground
returns ρg times its share of P̄ at each ground height, convolved with the pulse at that
height (:func:`forward.pulse.point_returns`, the ground of the expected model too; its
numpy reference, whichever backend the engine's columns use). Samples are point values
at the bin centres times Δz.
"""

import numpy as np

from ..pulse import point_returns
from .waveform import Waveform


def render_waveform(
    sim, heights, profiles, layers, ground_deposit, ground, rho_v, understory, center, settings
) -> Waveform:
    """The waveform of one footprint.

    Parameters
    ----------
    sim : WaveformSimulator
        Supplies the instrument, the fine layers and the pulse kernel.
    heights : array (m)
        Bin centres.
    profiles : ColumnProfiles
        Footprint-mean gap and layer sums on ``layers``.
    layers : (LayerGrid, int)
        The fine layers and the global index of the first one.
    ground_deposit : (array, array)
        Ground heights (m) and their shares of P̄ at the ground.
    ground : Ground
    rho_v : float
        Canopy reflectance ρv.
    understory : UniformUnderstory or None
    center : (float, float) (m)
    settings : dict
        Scheme settings recorded with the waveform.

    References
    ----------
    Sun, G. & Ranson, K. J. (2000). Modeling lidar returns from forest canopies. *IEEE
    Trans. Geosci. Remote Sens.* 38(6), 2617–2626 (Sec. II-B: layer returns and the ground's
    return, convolved with the pulse).
    """
    grid, first = layers
    n, m = heights.size, sim.oversampling
    gap_edges = profiles.gap_edges
    canopy = rho_v * _convolve_layers(sim, profiles.layer_return, first, n)
    ground_part = ground.reflectance * ground_samples(sim, *ground_deposit, heights)
    ground_gap = float(gap_edges[0])  # P̄ at the ground: all foliage lies above it
    accuracy = sim.accuracy
    return Waveform(
        heights=heights,
        samples=canopy + ground_part,
        canopy=canopy,
        ground=ground_part,
        gap=np.interp(heights, grid.edges, gap_edges, left=gap_edges[0], right=1.0),
        crown_volume=_layers_to_bins(profiles.crown_volume, first, m, n),
        foliage_area=_layers_to_bins(profiles.foliage_area, first, m, n),
        canopy_energy=rho_v * (1.0 - ground_gap),
        ground_energy=ground.reflectance * ground_gap,
        ground_gap=ground_gap,
        center=center,
        settings={
            **sim.instrument.describe(),
            **settings,
            "truncation_tolerance": accuracy.footprint_tolerance,
            "vertical_oversampling": m,
            "canopy_reflectance": rho_v,
            "ground_reflectance": ground.reflectance,
            "ground_slope_deg": ground.slope_deg,
            "understory_height_m": understory.height if understory else 0.0,
            "understory_lai": understory.lai if understory else 0.0,
        },
    )


def _convolve_layers(sim, layer_energy, first, n_bins):
    """Samples at bins 0..n_bins−1 from energies of global layers first, first + 1, …"""
    m, q0 = sim.oversampling, sim.kernel_offset
    full = np.convolve(layer_energy, sim.kernel)  # full[k] ↔ q = q0 + k − t
    out = np.zeros(n_bins)
    # bin j reads full[j·m − first − q0]
    j_first = max(0, -(-(first + q0) // m))
    j_last = min(n_bins - 1, (full.size - 1 + first + q0) // m)
    if j_last >= j_first:
        start = j_first * m - first - q0
        out[j_first : j_last + 1] = full[start::m][: j_last - j_first + 1]
    return out


def ground_samples(sim, nodes, weights, heights):
    """Ground samples per unit ρg: each node's weight times the pulse at its height.

    Parameters
    ----------
    sim : WaveformSimulator
        Supplies the instrument and the pulse's support.
    nodes : array (m)
        Ground heights.
    weights : array
        Each ground height's share of P̄ at the ground.
    heights : array (m)
        Bin centres.

    Returns
    -------
    array (bins,)
        Σ_k weights[k]·Δz·p(heights − nodes[k]) (:func:`forward.pulse.point_returns`),
        each node within its own pulse support.
    """
    instrument = sim.instrument
    out = np.zeros(heights.size)
    for z, w in zip(nodes, weights):
        if w != 0.0:  # one node at a time: each within its own support
            out += point_returns(
                instrument.pulse, heights, [z], [w], sim.pulse_support,
                bin_height=instrument.bin_height, backend="numpy",
            )[0]  # fmt: skip
    return out


def _layers_to_bins(layer_values, first, m, n_bins):
    """Sum fine-layer values into the digitiser bins they fall in (window bins only)."""
    bins = (first + np.arange(layer_values.size)) // m
    keep = (bins >= 0) & (bins < n_bins)
    return np.bincount(bins[keep], layer_values[keep], minlength=n_bins)[:n_bins]
