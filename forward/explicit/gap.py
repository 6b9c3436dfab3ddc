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
    column_depth : array (n_crowned) or None
        Optical depth of each crowned column from its top to the ground (kept for sloped
        ground, where the ground under each column lies at its own height).
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


def layer_integral(deposit, h):
    """Per-layer integral of the deposited ramps, top layer first, clipped at ≥ 0.

    The ramp sum at edge k (from the top) is h·Σ_{j<k} S_j with S the running sum of the
    deposit, so layer k (between edges k and k + 1) holds h·S_k.
    """
    running = np.cumsum(deposit[:-1], axis=0)
    running *= h
    return np.maximum(running, 0.0, out=running)


def gap_from_returns(layer_return):
    """Footprint-mean gap P̄ (n_layers + 1) at the layer edges from the layer returns
    (bottom layer first): 1 minus the returns above each edge, clipped to [0, 1]."""
    above = np.zeros(layer_return.size + 1)
    above[:-1] = np.cumsum(layer_return[::-1])[::-1]
    return np.clip(1.0 - above, 0.0, 1.0)


#: Work-array budget (elements) of one block of columns in :func:`column_profiles`.
BLOCK_ELEMENTS = 1_000_000


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
        Keep each crowned column's whole optical depth (needed on sloped ground).

    Notes
    -----
    P̄ at an edge is 1 minus the layer returns above it, so canopy plus ground energy,
    ρv(1 − P̄(0)) + ρg·P̄(0), holds by construction.

    Crowned columns are sorted by the top of their highest crown and processed in
    blocks, each only over the layers between its lowest crown base and its highest
    crown top: above them P = 1, below them nothing more is intercepted. So the work is
    the number of crowned columns times the height span of their own crowns (not of the
    whole canopy), and memory stays bounded by :data:`BLOCK_ELEMENTS` per block.

    References
    ----------
    Sun, G. & Ranson, K. J. (2000). Modeling lidar returns from forest canopies. *IEEE
    Trans. Geosci. Remote Sens.* 38(6), 2617–2626 (Sec. II: the bidirectional gap
    probability of each column through the crowns above it, under the lidar's hot spot).
    Kuusk, A. (1991). The hot spot effect in plant canopy reflectance. In R. Myneni & J.
    Ross (eds), *Photon–Vegetation Interactions*, Springer, 139–159.
    """
    h = grid.thickness
    crowned, row = np.unique(column, return_inverse=True)
    n_crowned = crowned.size
    omega = weights[crowned]
    col_top = np.full(n_crowned, -np.inf)
    col_low = np.full(n_crowned, np.inf)
    np.maximum.at(col_top, row, z_high)
    np.minimum.at(col_low, row, z_low)
    # layer range [k0, k1) of each column's crowns, counted from the grid bottom
    k1 = np.clip(np.ceil((col_top - grid.bottom) / h), 0, grid.n_layers).astype(np.intp)
    k0 = np.clip(np.floor((col_low - grid.bottom) / h), 0, grid.n_layers).astype(np.intp)
    k0 = np.minimum(k0, k1)
    order = np.argsort(k1, kind="stable")
    rank = np.empty(n_crowned, np.intp)
    rank[order] = np.arange(n_crowned)
    pair_rank = rank[row]
    pairs = np.argsort(pair_rank, kind="stable")  # crossings grouped by sorted column
    sorted_row = pair_rank[pairs]
    layer_return = np.zeros(grid.n_layers)
    start = 0
    while start < n_crowned:
        # the longest run of sorted columns whose (columns × layer span) fits the budget
        window = order[start : start + BLOCK_ELEMENTS]
        low_run = np.minimum.accumulate(k0[window])
        cost = np.arange(1, window.size + 1) * (k1[window] - low_run + 1)
        stop = start + max(1, int(np.searchsorted(cost, BLOCK_ELEMENTS, side="right")))
        block = order[start:stop]
        first, last = np.searchsorted(sorted_row, [start, stop])
        sel = pairs[first:last]
        lo, hi = int(k0[block].min()), int(k1[block].max())
        sub = LayerGrid(grid.bottom + lo * h, h, hi - lo)
        loss = _block_losses(
            pair_rank[sel] - start, z_low[sel], z_high[sel], extinction[sel], sub, block.size
        )
        transmitted = np.cumprod(1.0 - loss, axis=0)  # P at each layer's lower edge
        sub_return = np.empty(sub.n_layers)
        if sub.n_layers:
            sub_return[0] = loss[0] @ omega[block]
            sub_return[1:] = (transmitted[:-1] * loss[1:]) @ omega[block]
        layer_return[lo:hi] += sub_return[::-1]
        start = stop
    intercepted = float(layer_return.sum())
    if intercepted > 1.0:
        # overlapping crowns covering the whole footprint: the partition-of-unity
        # quadrature can weigh the columns slightly above 1; cap the intercepted fraction
        # at 1 so that P̄(0) = 0 exactly and canopy + ground energy stay consistent
        layer_return /= intercepted
    gap_edges = gap_from_returns(layer_return)

    # a column's whole depth is the sum of its crossings' k·G·Ω·u × path length
    depth = (
        np.bincount(row, extinction * (z_high - z_low), minlength=n_crowned) if keep_depth else None
    )
    # crown volume and foliage are linear in the crossings: one column for all crossings
    single = np.zeros_like(row)
    pair_weight = weights[column]
    volume, foliage = (
        layer_integral(_deposit_kinks(single, z_low, z_high, w, grid, 1), h)[:, 0][::-1]
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


def _block_losses(row, z_low, z_high, extinction, grid, n_rows):
    """Layer losses 1 − exp(−Δτ) of each column, top layer first."""
    dtau = layer_integral(
        _deposit_kinks(row, z_low, z_high, extinction, grid, n_rows), grid.thickness
    )
    return -np.expm1(-dtau)  # exact for optically thin layers


def with_understory(profiles, grid, understory, extinction_per_favd):
    """The profiles with a uniform understory layer folded in (unchanged for None)."""
    if understory is None:
        return profiles
    return add_uniform_layer(
        profiles,
        grid,
        extinction_per_favd * understory.favd,
        understory.favd,
        understory.height,
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
    return ColumnProfiles(
        gap_edges=gap_from_returns(layer_return),
        layer_return=layer_return,
        crown_volume=profiles.crown_volume,
        foliage_area=foliage,
        column_depth=None if profiles.column_depth is None else profiles.column_depth + depth[0],
        crowned_columns=profiles.crowned_columns,
    )
