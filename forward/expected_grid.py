"""The grid path's assembly of the samples with numpy (the reference of
:func:`forward.expected_numba.assemble_grid`, which takes the same arguments).

The expected model evaluates the trees' optical depth on a grid of whole fine layers
anchored on a bin edge at or below each row's ground. From there the samples follow by
one constant matrix (:func:`forward.expected_tables.grid_operator`: Catmull–Rom
interpolation to the layer edges, layer energies, pulse), a correction for a uniform
understory below its top, and a shift of each row by whole bins.
"""

import numpy as np


def clip_keeping_energy(canopy, rows):
    """Zero the negative samples of ``rows`` (bool, n) and rescale the rest so that each
    row keeps its sum: non-negative samples and exact energy (a change of the order of
    the undershoot, far below the model error)."""
    if rows.any():
        part = canopy[rows]
        positive = np.clip(part, 0.0, None)
        total = positive.sum(axis=1)
        scale = np.where(total > 0, part.sum(axis=1) / np.where(total > 0, total, 1.0), 0.0)
        canopy[rows] = positive * np.clip(scale, 0.0, None)[:, None]
    return canopy


def _add_understory(lost, local, interp, layers_to_samples, under_scale, under_top, z0, layer):
    """Samples (n, width) and E[P(0)] with a uniform understory below its top.

    P = P_trees·P_u differs from P_trees only below the understory top: there the trees'
    E[P] is read at the fine-layer edges from the same grid interpolation, and each
    layer's energy becomes Δ(P_trees·P_u) instead of ΔP_trees. P_u is exact at the edges,
    so its kink at the layer top costs no accuracy.
    """
    top = np.where(under_scale > 0, under_top, 0.0)
    edges = min(int(np.max(np.ceil((top - z0) / layer))) + 2, interp.shape[1])
    z = np.maximum(z0[:, None] + layer * np.arange(edges), 0.0)
    trees = 1.0 + lost @ interp[:, :edges]
    intercepted = -np.expm1(-under_scale[:, None] * np.clip(under_top[:, None] - z, 0.0, None))
    # Δ(P_trees·P_u) − ΔP_trees = −Δ(P_trees·(1 − P_u)); z starts at 0 in every row
    change = -np.diff(trees * intercepted, axis=1)
    local = local + change @ layers_to_samples[: edges - 1]
    return local, (1.0 + lost[:, 0]) * (1.0 - intercepted[:, 0])


def assemble_grid(depth, operator, shift, under_scale, under_top, z0, layer, bins, undershoot):
    """Canopy samples (n, ``bins``), E[P(0)] (n,) and the rows to recompute (n,) from the
    trees' optical depth on each row's grid (n, nodes).

    Parameters
    ----------
    depth : array (n, nodes)
    operator : tuple
        :func:`forward.expected_tables.grid_operator` of the grid.
    shift : array (n,)
        Whole bins from the window's first bin edge to each row's grid.
    under_scale, under_top : arrays (n,)
        κ·LAI_u/h_u (1/m; 0 for rows without an understory) and h_u (m).
    z0 : array (n,) (m)
        Height above the ground of each row's first grid node (≤ 0).
    layer : float (m)
    bins : int
    undershoot : float
        Rows whose samples fall below zero by more than this fraction of their canopy
        energy are flagged; the others are clipped at zero keeping their energy.
    """
    matrix, first, interp, layers_to_samples = operator
    n = depth.shape[0]
    lost = np.expm1(-depth)  # E[P] − 1: zero above the trees, so a bare row gives zero
    local = lost @ matrix
    gap0 = 1.0 + lost[:, 0]
    if np.any(under_scale > 0):
        local, gap0 = _add_understory(
            lost, local, interp, layers_to_samples, under_scale, under_top, z0, layer
        )
    # row r's sample k lands in bin shift_r + first + k; bins outside the window go to two
    # spare columns (flat indices: much faster than a 2-D scatter)
    width = bins + 2
    cols = (np.asarray(shift).astype(np.intp) + first)[:, None] + np.arange(matrix.shape[1])
    np.clip(cols, -1, width - 2, out=cols)
    cols += (1 + width * np.arange(n))[:, None]
    out = np.zeros((n, width))
    out.ravel()[cols.ravel()] = local.ravel()
    canopy = out[:, 1:-1]
    lowest = canopy.min(axis=1)
    redo = lowest < -undershoot * np.maximum(1.0 - gap0, np.finfo(float).tiny)
    return clip_keeping_energy(canopy, (lowest < 0) & ~redo), gap0, redo
