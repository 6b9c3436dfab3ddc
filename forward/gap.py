"""Bidirectional gap probability of footprint columns, exact at layer edges.

For a column, the foliage area above height z through one crown is the path length
``ℓ(z) = clip(z_high − z, 0, z_high − z_low)`` times its density, which is the difference
of two ramps, ``ramp(z_high − z) − ramp(z_low − z)``. A ramp sampled on a uniform grid is
reproduced exactly at the grid nodes by a linear (cloud-in-cell) deposit of its kink
followed by two cumulative sums from the top. So the optical depth of every column at
every layer edge is exact, and the work is one deposit per crown crossing plus dense
cumulative sums over the columns that meet a crown and the layers that hold crowns.
Columns that meet no crown are gaps (P = 1) and cost nothing.

Layer returns use ``P(top)·(1 − exp(−Δτ))`` (``expm1``), which keeps full relative
precision for optically thin layers where the difference of two nearly equal P values
would cancel.
"""

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class LayerGrid:
    """Uniform fine layers: edges ``bottom + i·h`` for i = 0..n_layers (m)."""

    bottom: float
    thickness: float
    n_layers: int

    @property
    def edges(self) -> np.ndarray:
        return self.bottom + self.thickness * np.arange(self.n_layers + 1)


@dataclass(frozen=True)
class ColumnProfiles:
    """Footprint-mean quantities on a :class:`LayerGrid`.

    Attributes
    ----------
    gap_edges : array (n_layers + 1)
        Footprint-mean gap probability P̄ at the layer edges.
    layer_return : array (n_layers)
        P̄(top) − P̄(bottom) of each layer: the canopy return per unit ρv.
    crown_volume : array (n_layers)
        Footprint-weighted crown volume in each layer per unit ground area (m³/m²).
    foliage_area : array (n_layers)
        Footprint-weighted one-sided foliage area in each layer per ground area (m²/m²).
    column_depth : array (n_crowned, n_layers + 1)
        Optical depth of each crowned column at the edges (kept for sloped ground).
    crowned_columns : int array
        Column indices of the rows of ``column_depth``.
    """

    gap_edges: np.ndarray
    layer_return: np.ndarray
    crown_volume: np.ndarray
    foliage_area: np.ndarray
    column_depth: np.ndarray
    crowned_columns: np.ndarray


def _deposit_kinks(row, z_low, z_high, weight, grid, n_rows):
    """Linear deposit of +w at z_high and −w at z_low on edge nodes counted from the top.

    Returns an (n_edges, n_rows) array whose row k belongs to edge ``n_layers − k``.
    """
    n_edges = grid.n_layers + 1
    top = grid.bottom + grid.n_layers * grid.thickness
    f = (top - np.concatenate([z_high, z_low])) / grid.thickness
    node = np.clip(np.floor(f).astype(np.intp), 0, n_edges - 1)
    frac = np.clip(f - node, 0.0, 1.0)
    lower = np.minimum(node + 1, n_edges - 1)
    signed = np.concatenate([weight, -weight])
    rows = np.concatenate([row, row])
    flat = np.concatenate([node * n_rows + rows, lower * n_rows + rows])
    values = np.concatenate([signed * (1.0 - frac), signed * frac])
    deposit = np.bincount(flat, values, minlength=n_rows * n_edges).astype(float, copy=False)
    return deposit.reshape(n_edges, n_rows)


def _layer_integral(deposit, h):
    """Per-layer integral of the deposited ramps, top layer first, clipped at ≥ 0.

    The ramp sum at edge k (from the top) is h·Σ_{j<k} S_j with S the running sum of the
    deposit, so layer k (between edges k and k + 1) holds h·S_k.
    """
    running = np.cumsum(deposit[:-1], axis=0)
    running *= h
    return np.maximum(running, 0.0, out=running)


def column_profiles(column, z_low, z_high, extinction, density, grid, weights, keep_depth=False):
    """Footprint-mean gap and layer returns from weighted columns.

    Parameters
    ----------
    column : int array
        Column index of each (tree, column) crown crossing.
    z_low, z_high : arrays (m)
        Heights where each crossing enters and leaves the crown; inside the grid.
    extinction : array (1/m)
        k·G·Ω·u of the crossed crown.
    density : array (m²/m³)
        FAVD u of the crossed crown (for the foliage profile).
    grid : LayerGrid
    weights : array
        Footprint weight of every column (index by ``column``); columns that cross no
        crown have P = 1 and need no weight.
    keep_depth : bool
        Keep each crowned column's optical depth at the edges (needed on sloped ground).

    Notes
    -----
    P̄ at an edge is 1 minus the layer returns above it, so canopy plus ground energy,
    ρv(1 − P̄(0)) + ρg·P̄(0), holds by construction.
    """
    h = grid.thickness
    crowned, row = np.unique(column, return_inverse=True)
    omega = weights[crowned]
    # optical thickness of each crowned column's layers, top layer first: (layers, columns)
    dtau = _layer_integral(_deposit_kinks(row, z_low, z_high, extinction, grid, crowned.size), h)
    depth = None
    if keep_depth:
        depth = np.zeros((crowned.size, grid.n_layers + 1))
        depth[:, :-1] = np.cumsum(dtau, axis=0)[::-1].T
    layer_loss = np.expm1(-dtau, out=dtau)
    np.negative(layer_loss, out=layer_loss)  # 1 − exp(−Δτ), exact for thin layers
    transmitted = np.cumprod(1.0 - layer_loss, axis=0)  # P at each layer's lower edge
    layer_return = np.empty(grid.n_layers)
    if grid.n_layers:
        layer_return[0] = layer_loss[0] @ omega
        layer_return[1:] = (transmitted[:-1] * layer_loss[1:]) @ omega
    layer_return = layer_return[::-1]  # bottom layer first
    gap_edges = np.empty(grid.n_layers + 1)
    gap_edges[-1] = 0.0
    gap_edges[:-1] = np.cumsum(layer_return[::-1])[::-1]
    gap_edges = np.clip(1.0 - gap_edges, 0.0, 1.0)

    # crown volume and foliage are linear in the crossings: one column for all crossings
    single = np.zeros_like(row)
    pair_weight = weights[column]
    volume, foliage = (
        _layer_integral(_deposit_kinks(single, z_low, z_high, w, grid, 1), h)[:, 0][::-1]
        for w in (pair_weight, pair_weight * density)
    )
    return ColumnProfiles(
        gap_edges=gap_edges,
        layer_return=layer_return,
        crown_volume=volume,
        foliage_area=foliage,
        column_depth=depth,
        crowned_columns=crowned,
    )


def add_uniform_layer(profiles, grid, extinction_per_m, foliage_per_m, top):
    """Fold a horizontally uniform foliage layer from 0 to ``top`` (m) into the profiles.

    Its transmission U(z) multiplies every column's, so P̄ = U·P̄_trees, and each layer's
    return is U(top)·ΔP̄_trees + P̄_trees(bottom)·ΔU, both terms non-negative.
    """
    edges = grid.edges
    above = np.clip(top - edges, 0.0, None)
    above = np.minimum(above, top)
    depth = extinction_per_m * above
    dtau = depth[:-1] - depth[1:]
    uniform = np.exp(-depth)
    trees = profiles.gap_edges
    layer_return = uniform[1:] * profiles.layer_return + trees[:-1] * uniform[1:] * -np.expm1(-dtau)
    foliage = profiles.foliage_area + foliage_per_m * (above[:-1] - above[1:])
    gap_edges = np.empty_like(trees)
    gap_edges[-1] = 0.0
    gap_edges[:-1] = np.cumsum(layer_return[::-1])[::-1]
    return ColumnProfiles(
        gap_edges=np.clip(1.0 - gap_edges, 0.0, 1.0),
        layer_return=layer_return,
        crown_volume=profiles.crown_volume,
        foliage_area=foliage,
        column_depth=None if profiles.column_depth is None else profiles.column_depth + depth,
        crowned_columns=profiles.crowned_columns,
    )
