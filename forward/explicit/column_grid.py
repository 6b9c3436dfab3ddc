"""The columns of a footprint and the crowns that reach them.

The footprint mean of any column quantity is a quadrature over vertical columns,

    Q̄ = ∫ w(x, y)·Q(x, y) dA ≈ Σ_ij ω_i·ω_j·Q(x_i, y_j),

with w the Gaussian footprint (:mod:`forward.footprint`) truncated where its outer
weight equals a tolerance (conventions, "Footprint"). The columns form a tensor grid: the
nodes along each axis are the midpoints of equal-probability cells of a Gaussian of
standard deviation ``stretch·σf``, so the columns are densest under the beam centre and
sparser where the footprint weight is low, and each node's weight is the footprint's
Gaussian factor (:func:`forward.footprint.footprint_falloff`) times its cell width. A
column sees every crown above it, so overlapping crowns need no special treatment: where
crowns overlap, their optical depths add in the column.

The kernels bin the crowns near a footprint by blocks of columns
(:func:`crown_node_ranges` gives each crown's nodes), so each column tests only the crowns
whose discs reach its block.
"""

from dataclasses import dataclass, field

import numpy as np
from scipy.special import ndtr, ndtri

from ..footprint import footprint_falloff, truncation_radius

#: Ratio of the column density's Gaussian width to the footprint's σf. Columns as dense
#: as the footprint weight would leave its rim coarse, evenly spaced ones would spend most
#: columns on a rim of little weight; a density twice as wide as the footprint sits
#: between (chosen by measurement, ``studies/forward_runtime_vs_error.py``).
COLUMN_STRETCH = 2.0

#: Most nodes along one axis (the grid has at most this squared columns).
MAX_AXIS_NODES = 2049


@dataclass(frozen=True)
class ColumnGrid:
    """Tensor grid of footprint columns, truncated to a disc.

    Attributes
    ----------
    nodes : array (n,) (m)
        Column offsets from the beam centre along x, and the same along y; ascending and
        symmetric about 0.
    weights : array (n,)
        Axis weights: column (i, j) inside the disc carries ``weights[i]·weights[j]``,
        its share of the footprint; these shares sum to one over the disc.
    radius : float (m)
        Truncation radius: columns with x² + y² > radius² are left out.
    spacing : float (m)
        Node spacing at the beam centre.
    n_columns : int
        Number of columns inside the disc.
    """

    nodes: np.ndarray = field(repr=False)
    weights: np.ndarray = field(repr=False)
    radius: float
    spacing: float
    n_columns: int = field(init=False)

    def __post_init__(self):
        object.__setattr__(self, "n_columns", int(_columns_within(self.nodes, self.radius).sum()))

    @classmethod
    def build(cls, sigma, spacing, tolerance, stretch=COLUMN_STRETCH) -> "ColumnGrid":
        """Columns ``spacing`` m apart at the centre of a footprint of σf = ``sigma`` (m),
        truncated where the outer weight is ``tolerance``; ``stretch=None`` spaces the
        nodes evenly."""
        if not (np.isfinite(spacing) and spacing > 0):
            raise ValueError(f"column spacing must be positive, got {spacing} m")
        radius = float(truncation_radius(sigma, tolerance))
        nodes, widths = _axis_nodes(radius, spacing, None if stretch is None else stretch * sigma)
        weights = footprint_falloff((nodes / sigma) ** 2) * widths
        return cls(nodes, weights / np.sqrt(_disc_total(nodes, weights, radius)), radius, spacing)


def _axis_nodes(radius, spacing, width):
    """Nodes (m) on [−radius, radius] and their cell widths (m): even steps if ``width``
    is None, else equal-probability cells of a Gaussian of standard deviation ``width``
    with the central cell ``spacing`` wide."""
    if width is None:
        half = min(int(np.floor(radius / spacing)), MAX_AXIS_NODES // 2)
        step = max(spacing, radius / max(half, 1))
        return step * np.arange(-half, half + 1), np.full(2 * half + 1, step)
    mass = 2.0 * ndtr(radius / width) - 1.0  # Gaussian mass on [−radius, radius]
    n = int(np.ceil(mass * width * np.sqrt(2.0 * np.pi) / spacing))
    n = min(n + (1 - n % 2), MAX_AXIS_NODES)  # odd: a node at the beam centre
    edges = width * ndtri(0.5 + mass * (np.arange(n + 1) / n - 0.5))
    edges[0], edges[-1] = -radius, radius
    middle = width * ndtri(0.5 + mass * ((np.arange(n) + 0.5) / n - 0.5))
    return middle, np.diff(edges)


def _columns_within(nodes, radius):
    """Number of nodes j with x_i² + y_j² ≤ radius² for each node i (nodes symmetric)."""
    reach = np.sqrt(np.maximum(radius * radius - nodes * nodes, 0.0))
    inside = np.searchsorted(nodes, reach, side="right") - np.searchsorted(nodes, -reach)
    return np.where(np.abs(nodes) <= radius, inside, 0)


def _disc_total(nodes, weights, radius):
    """Σ weights[i]·weights[j] over the columns inside the disc."""
    reach = np.sqrt(np.maximum(radius * radius - nodes * nodes, 0.0))
    cumulative = np.concatenate([[0.0], np.cumsum(weights)])
    row = (
        cumulative[np.searchsorted(nodes, reach, side="right")]
        - cumulative[np.searchsorted(nodes, -reach)]
    )
    return float(np.sum(weights * np.where(np.abs(nodes) <= radius, row, 0.0)))


@dataclass(frozen=True)
class CrownSet:
    """The crowns that reach one footprint, as flat arrays.

    Attributes
    ----------
    x, y : arrays (m)
        Stem offsets from the beam centre.
    radius, length : arrays (m)
        Crown radius and crown length.
    base : array (m)
        Crown base height above the ground datum at the beam centre (on sloped ground it
        includes the ground's height at the stem).
    shape : int64 array
        Crown-shape codes (:data:`forward.crowns.SHAPE_NAMES`).
    extinction : array (1/m)
        k·G·Ω·u of each crown.
    favd : array (m²/m³)
        Foliage area volume density u.
    """

    x: np.ndarray
    y: np.ndarray
    radius: np.ndarray
    shape: np.ndarray
    base: np.ndarray
    length: np.ndarray
    extinction: np.ndarray
    favd: np.ndarray

    @property
    def size(self) -> int:
        return int(self.x.size)

    @property
    def top(self) -> np.ndarray:
        """Crown top heights (m)."""
        return self.base + self.length

    def effective_count(self, sigma) -> float:
        """Effective number (Σω)²/Σω² of crowns sharing a footprint of σf = ``sigma`` (m),
        ω being a crown's area times the footprint's weight at its stem."""
        share = self.radius**2 * footprint_falloff((self.x**2 + self.y**2) / sigma**2)
        total = float(np.sum(share * share))
        return float(np.sum(share)) ** 2 / total if total > 0 else 0.0


def bin_columns(grid: ColumnGrid, crown_radius) -> int:
    """Columns per side of a bin of the crown lists: about one typical crown radius
    ``crown_radius`` (m), from 2 to 64 columns."""
    return int(np.clip(np.round(crown_radius / grid.spacing), 2, 64))


def crown_node_ranges(grid: ColumnGrid, crowns: CrownSet):
    """First and last grid node strictly inside each crown's bounding square.

    Returns
    -------
    first, last : int64 arrays (n_crowns, 2)
        Node indices along x (column 0) and y (column 1); ``last < first`` where no
        node falls inside.
    """
    nodes = grid.nodes
    first = [np.searchsorted(nodes, c - crowns.radius, side="right") for c in (crowns.x, crowns.y)]
    last = [
        np.searchsorted(nodes, c + crowns.radius, side="left") - 1 for c in (crowns.x, crowns.y)
    ]
    return np.column_stack(first).astype(np.int64), np.column_stack(last).astype(np.int64)


@dataclass(frozen=True)
class FootprintSums:
    """Footprint-weighted sums over the columns, on a :class:`~forward.explicit.gap.LayerGrid`.

    Attributes
    ----------
    layer_return : array (n_layers)
        Σ ω·(P(top) − P(bottom)) of each layer, bottom layer first: the canopy return per
        unit ρv.
    crown_volume : array (n_layers)
        Σ ω·(crown path length in the layer) (m³ of crown per m² of ground).
    foliage_area : array (n_layers)
        Σ ω·u·(crown path length in the layer) (m² of foliage per m² of ground).
    ground_mass : array or None
        Sloped ground only: Σ ω·P(ground) of the columns whose ground lies at each node
        ``(ground_first + k)·h`` (linear deposit between nodes); None on flat ground.
    """

    layer_return: np.ndarray
    crown_volume: np.ndarray
    foliage_area: np.ndarray
    ground_mass: np.ndarray | None
