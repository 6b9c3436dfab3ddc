"""Catmull–Rom interpolation on uniform grids, and the grid path's constant operator.

The expected model evaluates the trees' optical depth on a coarse grid and interpolates
it by Catmull–Rom, either per row (:func:`catmull_rom`) or, on the grid path, as one
constant matrix that also takes the layer energies and the pulse (:func:`grid_operator`).
"""

import numpy as np


def _catmull_rom_weights(t):
    """Weights of y(k−1), y(k), y(k+1), y(k+2) at fraction t of cell k (Catmull–Rom)."""
    t2, t3 = t * t, t * t * t
    return (
        -0.5 * t + t2 - 0.5 * t3,
        1.0 - 2.5 * t2 + 1.5 * t3,
        0.5 * t + 2.0 * t2 - 1.5 * t3,
        -0.5 * t2 + 0.5 * t3,
    )


def catmull_rom(values, z, step, beyond=0.0):
    """Catmull–Rom interpolation of values on uniform grids.

    Parameters
    ----------
    values : array (n, m)
        On grids 0, step, … per row.
    z : array (n, e)
    step : array (n,)
    beyond : float
        The value beyond the last node (no crown above the tallest tree: zero depth).

    Returns
    -------
    array (n, e)
        Below the first node the values are extrapolated linearly.

    References
    ----------
    Catmull, E. & Rom, R. (1974). A class of local interpolating splines. In R. E. Barnhill
    & R. F. Riesenfeld (eds), *Computer Aided Geometric Design*, Academic Press, 317–326.
    """
    n, m = values.shape
    y = np.full((n, m + 3), float(beyond))
    y[:, 1 : m + 1] = values
    y[:, 0] = 2 * values[:, 0] - values[:, 1]
    p = np.clip(z / step[:, None], 0.0, m - 1.0)
    i = p.astype(np.intp)
    weights = _catmull_rom_weights(p - i)
    i += (np.arange(n) * (m + 3))[:, None]
    flat = y.ravel()
    return sum(w * flat[i + k] for k, w in enumerate(weights))


def catmull_rom_matrix(nodes, per_cell):
    """Catmull–Rom interpolation as a matrix, for ``per_cell`` points per grid cell.

    Parameters
    ----------
    nodes : int
    per_cell : int

    Returns
    -------
    array (nodes, points)
        M with ``y @ M`` the interpolated values at k/per_cell, k = 0 … (nodes − 1)·per_cell,
        of values y on the grid 0, 1, …; below the first node they are extrapolated linearly
        and the value beyond the last node is 0, as :func:`catmull_rom` with ``beyond=0``.
    """
    cells = nodes - 1
    # padded values: y(−1) = 2y(0) − y(1), y(0 … nodes − 1), y(nodes) = 0
    pad = np.zeros((nodes, nodes + 2))
    pad[:, 1 : nodes + 1] = np.eye(nodes)
    pad[0, 0], pad[1, 0] = 2.0, -1.0
    points = cells * per_cell + 1
    interp = np.zeros((nodes + 2, points))
    k = np.arange(points - 1) // per_cell
    t = (np.arange(points - 1) % per_cell) / per_cell
    for offset, w in enumerate(_catmull_rom_weights(t)):
        np.add.at(interp, (k + offset, np.arange(points - 1)), w)
    interp[nodes, points - 1] = 1.0  # the last node itself
    return pad @ interp


def layer_operator(layers, oversampling, q_min, taps):
    """The matrix from fine-layer energies to waveform samples.

    Parameters
    ----------
    layers : int
        Fine layers, the first starting on a bin edge.
    oversampling : int
        Layers per bin.
    q_min, taps
        The layer kernel of :func:`forward.pulse.layer_kernel`.

    Returns
    -------
    matrix : array (layers, bins)
        Column k is the sample ``first + k`` bins above the first layer's bin edge.
    first : int
    """
    m = oversampling
    first = -((-q_min) // m)  # ceil(q_min / m)
    last = (q_min + taps.size - 1 + layers - 1) // m
    q = np.arange(first, last + 1)[None, :] * m - np.arange(layers)[:, None] - q_min
    inside = (q >= 0) & (q < taps.size)
    return np.where(inside, taps[np.clip(q, 0, taps.size - 1)], 0.0), first


def grid_operator(nodes, per_cell, oversampling, q_min, taps):
    """The matrix from E[P] − 1 on a depth grid to waveform samples, and its first bin.

    Parameters
    ----------
    nodes : int
        Points of the depth grid, the first on a bin edge.
    per_cell : int
        Fine layers per grid cell.
    oversampling : int
        Fine layers per bin.
    q_min, taps
        The layer kernel of :func:`forward.pulse.layer_kernel`.

    Returns
    -------
    matrix : array (nodes, bins)
        Column k is the sample ``first + k`` bins above the grid's first bin edge.
    first : int
    interp : array (nodes, layers + 1)
        The interpolation matrix (values at the layer edges).
    layers_to_samples : array (layers, bins)
        The :func:`layer_operator` of the grid's layers.

    Notes
    -----
    :func:`catmull_rom_matrix` interpolation to every layer edge, layer energies
    P(top) − P(bottom), then :func:`layer_operator`.
    """
    interp = catmull_rom_matrix(nodes, per_cell)
    energy = interp[:, 1:] - interp[:, :-1]  # (nodes, layers)
    kernel, first = layer_operator(energy.shape[1], oversampling, q_min, taps)
    return energy @ kernel, first, interp, kernel
