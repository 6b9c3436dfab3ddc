"""Footprint sums over a grid of columns: the numpy reference, and the backend switch.

:func:`footprint_profiles` walks the grid in square tiles of columns. For each tile it
finds the crowns whose discs reach it, the crossing of every column with every crown above
it (exact heights where the column enters and leaves the crown), and hands the crossings
to :func:`forward.explicit.gap.column_profiles`, which gives each column's gap probability exactly
at the layer edges. Sums over the tiles are footprint means, since a column's weight is
its share of the footprint. Memory is bounded by a tile's columns times the crowns that
reach it, whatever the number or size of the crowns.

:func:`ground_gap` gives the footprint-mean gap at the ground alone, on columns of its
own: each crown adds its optical depth to the columns under it.

:mod:`forward.explicit.column_kernel_numba` computes the same sums in compiled code,
under the same names; both functions here take ``backend=`` (:mod:`forward.backends`) and
give the same numbers to rounding either way.
"""

import numpy as np

from ..backends import resolve
from ..crowns import crown_interval
from . import column_kernel_numba
from .column_grid import ColumnGrid, CrownSet, FootprintSums, crown_node_ranges
from .gap import LayerGrid, column_profiles

#: Fewest columns per side of a tile.
MIN_TILE = 16


def footprint_profiles(
    grid: ColumnGrid,
    crowns: CrownSet,
    layers: LayerGrid,
    slope=(0.0, 0.0),
    ground_nodes=None,
    bin_nodes=16,
    *,
    backend="auto",
) -> FootprintSums:
    """Footprint sums of the columns of ``grid`` under ``crowns``.

    Parameters
    ----------
    grid : ColumnGrid
    crowns : CrownSet
        Crowns near the footprint; their heights must lie inside ``layers``.
    layers : LayerGrid
        Fine layers (m) holding every crown.
    slope : (float, float)
        Ground gradient (gx, gy): the ground under column (x, y) lies at gx·x + gy·y (m);
        foliage below it does not exist.
    ground_nodes : (int, int) or None
        Sloped ground: index of the first ground node and the number of nodes; the nodes
        lie at multiples of the layer thickness. None on flat ground.
    bin_nodes : int
        Columns per side of a bin of the compiled kernel; a tile here is at least
        :data:`MIN_TILE` columns wide (the sums do not depend on the tiling).
    backend : str
        ``"auto"``, ``"numba"`` (:mod:`forward.explicit.column_kernel_numba`) or
        ``"numpy"`` (:func:`forward.backends.resolve`); both give the same sums to
        rounding.

    Returns
    -------
    FootprintSums

    References
    ----------
    Sun, G. & Ranson, K. J. (2000). Modeling lidar returns from forest canopies. *IEEE
    Trans. Geosci. Remote Sens.* 38(6), 2617–2626 (Sec. II-B: the footprint's columns,
    weighted by the Gaussian beam).
    """
    if resolve(backend) == "numba":
        return column_kernel_numba.footprint_profiles(
            grid, crowns, layers, slope, ground_nodes, bin_nodes
        )
    bin_nodes = max(int(bin_nodes), MIN_TILE)
    h = layers.thickness
    n = grid.nodes.size
    first, last = crown_node_ranges(grid, crowns)
    sums = [np.zeros(layers.n_layers) for _ in range(3)]
    ground = None if ground_nodes is None else np.zeros(ground_nodes[1])
    for start_x in range(0, n, bin_nodes):
        for start_y in range(0, n, bin_nodes):
            stop_x, stop_y = min(n, start_x + bin_nodes), min(n, start_y + bin_nodes)
            gx, gy = np.meshgrid(
                grid.nodes[start_x:stop_x], grid.nodes[start_y:stop_y], indexing="ij"
            )
            omega = np.outer(grid.weights[start_x:stop_x], grid.weights[start_y:stop_y])
            inside = gx * gx + gy * gy <= grid.radius * grid.radius
            px, py, omega = gx[inside], gy[inside], omega[inside]
            if px.size == 0:
                continue
            near = np.flatnonzero(
                (first[:, 0] < stop_x)
                & (last[:, 0] >= start_x)
                & (first[:, 1] < stop_y)
                & (last[:, 1] >= start_y)
            )
            z_ground = slope[0] * px + slope[1] * py
            depth = np.zeros(px.size)
            if near.size:
                tile = _tile_profiles(px, py, omega, z_ground, crowns, near, layers, ground)
                if tile is not None:
                    profile, crowned = tile
                    for total, part in zip(
                        sums,
                        (profile.layer_return, profile.crown_volume, profile.foliage_area),
                    ):
                        total += part
                    if ground is not None:
                        depth[crowned] = profile.column_depth
            if ground is not None:
                _deposit(ground, z_ground / h - ground_nodes[0], omega * np.exp(-depth))
    return FootprintSums(*sums, ground)


def _tile_profiles(px, py, omega, z_ground, crowns, near, layers, ground):
    """Column profiles of one tile, or None where no column meets a crown."""
    dx = px[:, None] - crowns.x[near]
    dy = py[:, None] - crowns.y[near]
    radius = crowns.radius[near]
    column, which = np.nonzero(dx * dx + dy * dy < radius * radius)
    if column.size == 0:
        return None
    tree = near[which]
    rho = np.hypot(dx[column, which], dy[column, which]) / crowns.radius[tree]
    z_low, z_high = crown_interval(crowns.shape[tree], rho, crowns.base[tree], crowns.length[tree])
    if ground is not None:  # foliage below the local ground surface does not exist
        z_low = np.maximum(z_low, z_ground[column])
        z_high = np.maximum(z_high, z_ground[column])
    keep = z_high > z_low
    column, tree, z_low, z_high = column[keep], tree[keep], z_low[keep], z_high[keep]
    if column.size == 0:
        return None
    profile = column_profiles(
        column,
        z_low,
        z_high,
        crowns.extinction[tree],
        crowns.favd[tree],
        layers,
        omega,
        keep_depth=ground is not None,
    )
    return profile, profile.crowned_columns


def _deposit(target, position, value):
    """Add ``value`` at fractional node ``position``, shared linearly by its two nodes."""
    node = np.floor(position).astype(np.intp)
    frac = position - node
    np.add.at(target, node, value * (1.0 - frac))
    np.add.at(target, np.minimum(node + 1, target.size - 1), value * frac)


def ground_gap(
    grid: ColumnGrid, crowns: CrownSet, slope=(0.0, 0.0), ground_nodes=None, h=1.0, *,
    backend="auto",
):  # fmt: skip
    """Footprint-mean gap at the ground, P̄(0) = Σ ω·exp(−τ), over the columns of ``grid``.

    Only the whole optical depth τ of each column is needed, τ = Σ k·G·Ω·u·(path length
    of each crown over it), so the ground can have columns of its own, closer than those
    of the profiles (:meth:`forward.explicit.accuracy.AccuracySettings.ground_spacing_for`). Each
    crown adds its depth to the columns of its bounding square.

    Parameters
    ----------
    grid : ColumnGrid
    crowns : CrownSet
    slope : (float, float)
        Ground gradient (gx, gy), as for :func:`footprint_profiles`.
    ground_nodes : (int, int) or None
        Sloped ground: first ground node and number of nodes, at multiples of ``h``.
    h : float (m)
        Spacing of the ground nodes.
    backend : str
        ``"auto"``, ``"numba"`` or ``"numpy"``, as for :func:`footprint_profiles`.

    Returns
    -------
    gap : float
        P̄ at the ground.
    ground_mass : array or None
        Sloped ground: Σ ω·P(ground) of the columns whose ground lies at each node
        (linear deposit between nodes); None on flat ground.

    References
    ----------
    Sun, G. & Ranson, K. J. (2000). Modeling lidar returns from forest canopies. *IEEE
    Trans. Geosci. Remote Sens.* 38(6), 2617–2626 (Sec. II-B: the ground's return through
    the gap at the ground).
    """
    if resolve(backend) == "numba":
        return column_kernel_numba.ground_gap(grid, crowns, slope, ground_nodes, h)
    nodes = grid.nodes
    first, last = crown_node_ranges(grid, crowns)
    depth = np.zeros((nodes.size, nodes.size))
    for c in range(crowns.size):
        (i0, j0), (i1, j1) = first[c], last[c] + 1
        if i1 <= i0 or j1 <= j0:
            continue
        px, py = np.meshgrid(nodes[i0:i1], nodes[j0:j1], indexing="ij")
        rho = np.hypot(px - crowns.x[c], py - crowns.y[c]) / crowns.radius[c]
        inside = rho < 1.0
        shape = np.full(rho.shape, crowns.shape[c])
        z_low, z_high = crown_interval(
            shape, np.minimum(rho, 1.0), crowns.base[c], crowns.length[c]
        )
        if ground_nodes is not None:  # foliage below the local ground surface does not exist
            z_ground = slope[0] * px + slope[1] * py
            z_low, z_high = np.maximum(z_low, z_ground), np.maximum(z_high, z_ground)
        path = np.where(inside, np.maximum(z_high - z_low, 0.0), 0.0)
        depth[i0:i1, j0:j1] += crowns.extinction[c] * path
    px, py = np.meshgrid(nodes, nodes, indexing="ij")
    inside = px * px + py * py <= grid.radius * grid.radius
    gap = np.outer(grid.weights, grid.weights)[inside] * np.exp(-depth[inside])
    if ground_nodes is None:
        return float(gap.sum()), None
    mass = np.zeros(ground_nodes[1])
    z_ground = slope[0] * px[inside] + slope[1] * py[inside]
    _deposit(mass, z_ground / h - ground_nodes[0], gap)
    return float(gap.sum()), mass
