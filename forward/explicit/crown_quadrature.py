"""The per-crown quadrature of earlier versions of the explicit engine.

The per-crown quadrature (scheme ``"crowns"`` of
:class:`forward.explicit.accuracy.AccuracySettings`) is exact for isolated crowns but
converges slowly where crowns overlap; the engine's default is the grid of columns of
:mod:`forward.explicit.column_grid`. It is kept as a reference that tests and studies
select with ``AccuracySettings(radial_nodes=..., angular_nodes=...)``.

The waveform is the w-weighted mean of column returns, w(r) = exp(−r²/2σf²)/(2πσf²)
(:mod:`forward.footprint`), truncated at the radius whose outer weight equals a stated tolerance,
``r_max = σf·sqrt(−2 ln tol)`` (conventions, "Footprint"), and renormalised to unit mass.

Only columns inside crowns carry canopy signal; elsewhere P = 1. So the footprint mean is

    P̄(z) = 1 − ∫ w·(1 − P(x, z)) dA = 1 − Σ_i ∫_{disc_i} w·(1 − P)/n dA,

where disc_i is the horizontal disc of crown i and n(x) the number of discs covering x (a
partition of unity over overlapping crowns). Each disc gets its own polar quadrature:
Gauss–Legendre in ρ² (area-uniform) and the periodic trapezoid rule in angle. An isolated
crown is then integrated to quadrature accuracy, since the disc edge is a quadrature
boundary, and gaps between crowns cost nothing. A crown wider than half the truncation
radius (a slab, or a narrow beam) instead gets beam-centred points: Gauss–Legendre nodes in
the Gaussian's radial CDF times angles, kept where they fall inside its disc.
"""

from dataclasses import dataclass, field

import numpy as np
from numpy.polynomial.legendre import leggauss
from scipy.spatial import cKDTree
from scipy.special import ndtr

from ..crowns import crown_interval
from ..footprint import truncated_footprint_weight, truncation_radius
from .gap import column_profiles, with_understory


@dataclass(frozen=True)
class DiscQuadrature:
    """Polar quadrature on the unit disc: ``radial_nodes`` rings × ``angular_nodes`` angles.

    Attributes
    ----------
    unit_offsets : array (n, 2)
        Node positions on the unit disc; rings are staggered by half an angular step.
    unit_rho : array (n,)
        Node radii.
    unit_weights : array (n,)
        Area weights, summing to π.
    """

    radial_nodes: int = 4
    angular_nodes: int = 8
    unit_offsets: np.ndarray = field(init=False, repr=False)
    unit_rho: np.ndarray = field(init=False, repr=False)
    unit_weights: np.ndarray = field(init=False, repr=False)

    def __post_init__(self):
        if self.radial_nodes < 1 or self.angular_nodes < 1:
            raise ValueError("disc quadrature needs at least one radial and one angular node")
        s, a = leggauss(self.radial_nodes)
        s, a = 0.5 * (s + 1.0), 0.5 * a  # Gauss–Legendre on [0, 1] in s = ρ²
        rho = np.sqrt(s)
        ring = np.arange(self.radial_nodes)[:, None]
        theta = (
            2
            * np.pi
            * (np.arange(self.angular_nodes)[None, :] + 0.5 * (ring % 2))
            / (self.angular_nodes)
        )
        rho_grid = np.broadcast_to(rho[:, None], theta.shape)
        offsets = np.stack([rho_grid * np.cos(theta), rho_grid * np.sin(theta)], -1)
        weights = np.broadcast_to((np.pi * a)[:, None] / self.angular_nodes, theta.shape)
        object.__setattr__(self, "unit_offsets", offsets.reshape(-1, 2))
        object.__setattr__(self, "unit_rho", rho_grid.ravel().copy())
        object.__setattr__(self, "unit_weights", weights.ravel().copy())

    @property
    def size(self) -> int:
        return self.unit_rho.size


@dataclass(frozen=True)
class CrownCrossings:
    """Columns of one footprint and the crowns they cross.

    Attributes
    ----------
    points : array (n_points, 2)
        Column offsets (m) from the beam centre.
    weights : array (n_points,)
        Quadrature weights ω = w·dA/n (dimensionless; Σ over a crown's disc ≈ its
        footprint-weighted area).
    column, tree : int arrays (n_pairs,)
        Each crossing's column and tree (index into the trees handed in).
    rho : array (n_pairs,)
        Normalised distance of the column from that tree's stem.
    """

    points: np.ndarray
    weights: np.ndarray
    column: np.ndarray
    tree: np.ndarray
    rho: np.ndarray


def beam_points(sigma, tolerance, radial_nodes, angular_nodes):
    """Beam-centred columns (m) and their footprint masses, summing to one."""
    u, a = leggauss(radial_nodes)
    u, a = 0.5 * (u + 1.0), 0.5 * a  # Gauss–Legendre in the truncated radial CDF
    r = sigma * np.sqrt(-2.0 * np.log1p(-u * (1.0 - tolerance)))
    ring = np.arange(radial_nodes)[:, None]
    theta = 2 * np.pi * (np.arange(angular_nodes)[None, :] + 0.5 * (ring % 2)) / angular_nodes
    points = np.stack([r[:, None] * np.cos(theta), r[:, None] * np.sin(theta)], -1)
    mass = np.broadcast_to(a[:, None] / angular_nodes, theta.shape)
    return points.reshape(-1, 2), mass.ravel().copy()


#: Crowns wider than this fraction of the truncation radius use beam-centred points.
WIDE_CROWN_FRACTION = 0.5


def crown_crossings(quadrature, dx, dy, crown_radius, sigma, tolerance) -> CrownCrossings:
    """Quadrature columns for crowns at stem offsets (dx, dy) (m) with radii (m)."""
    n_trees, n_q = len(dx), quadrature.size
    stems = np.column_stack([dx, dy])
    points = (stems[:, None, :] + crown_radius[:, None, None] * quadrature.unit_offsets).reshape(
        -1, 2
    )
    area = (crown_radius[:, None] ** 2 * quadrature.unit_weights).ravel()
    weights = area * truncated_footprint_weight(points[:, 0], points[:, 1], sigma, tolerance)
    owner = np.repeat(np.arange(n_trees), n_q)
    wide = np.flatnonzero(crown_radius > WIDE_CROWN_FRACTION * truncation_radius(sigma, tolerance))
    if wide.size:
        weights[np.isin(owner, wide)] = 0.0
        beam, mass = beam_points(
            sigma, tolerance, 4 * quadrature.radial_nodes, 4 * quadrature.angular_nodes
        )
        for tree in wide:
            inside = np.hypot(*(beam - stems[tree]).T) < crown_radius[tree]
            points = np.concatenate([points, beam[inside]])
            weights = np.concatenate([weights, mass[inside]])
            owner = np.concatenate([owner, np.full(inside.sum(), tree)])
    keep = weights > 0
    points, weights, owner = points[keep], weights[keep], owner[keep]
    if points.shape[0] == 0 or n_trees == 0:
        empty = np.zeros(0, np.intp)
        return CrownCrossings(np.zeros((0, 2)), np.zeros(0), empty, empty, np.zeros(0))
    # every crown covering each column: the owner, plus overlapping neighbours
    hits = cKDTree(points).query_ball_point(stems, crown_radius, return_sorted=False)
    counts = np.fromiter(map(len, hits), np.intp, n_trees)
    column = np.concatenate([np.asarray(h, np.intp) for h in hits if h])
    tree = np.repeat(np.arange(n_trees), counts)
    delta = points[column] - stems[tree]
    rho = np.hypot(delta[:, 0], delta[:, 1]) / crown_radius[tree]
    inside = (rho < 1.0) | (tree == owner[column])
    column, tree, rho = column[inside], tree[inside], np.minimum(rho[inside], 1.0)
    cover = np.bincount(column, minlength=points.shape[0])
    return CrownCrossings(points, weights / np.maximum(cover, 1), column, tree, rho)


class CrownFootprint:
    """One footprint under the per-crown quadrature: its crossings, then its profiles.

    The interface of the engine's column scheme: ``top`` and ``bottom`` (m) of the
    crossings, and :meth:`profiles` on the bins at ``heights``.
    """

    def __init__(self, sim, prepared, cx, cy, ground, understory):
        self.sim, self.ground, self.understory = sim, ground, understory
        self.crossings = _crossings(sim, prepared, cx, cy, ground)
        self.top = float(self.crossings[2].max(initial=0.0))
        self.bottom = float(self.crossings[1].min(initial=0.0))

    def profiles(self, heights):
        """Profiles on the fine layers of ``heights``: (profiles, (layers, first layer),
        ground heights (m), their shares of P̄ at the ground, scheme settings)."""
        sim, ground, understory = self.sim, self.ground, self.understory
        found, z_low, z_high, extinction, favd = self.crossings
        span_low = min(z_low.min(initial=np.inf), 0.0 if understory else np.inf)
        span_high = max(z_high.max(initial=-np.inf), understory.height if understory else -np.inf)
        if span_high <= span_low:  # nothing above the ground: a one-layer empty canopy
            span_low, span_high = 0.0, sim.layer_height
        layers, first = sim.layer_grid(heights, span_low, span_high)
        profiles = column_profiles(
            found.column,
            z_low,
            z_high,
            extinction,
            favd,
            layers,
            found.weights,
            keep_depth=not ground.is_flat,
        )
        profiles = with_understory(profiles, layers, understory, sim.instrument.extinction_per_favd)
        nodes, weights = _ground_deposit(sim, found, profiles, ground)
        settings = {
            "scheme": "crowns",
            "radial_nodes": sim.quadrature.radial_nodes,
            "angular_nodes": sim.quadrature.angular_nodes,
        }
        return profiles, (layers, first), nodes, weights, settings


def _crossings(sim, prepared, cx, cy, ground):
    """Quadrature columns of all crowns that reach the truncated footprint."""
    stand = prepared.stand
    reach = sim.footprint_radius + prepared.max_radius
    near = prepared.stems_within(cx, cy, reach)
    if near.size == 0:  # bare ground: nothing to intersect
        empty, none = np.zeros(0), np.zeros(0, np.intp)
        found = CrownCrossings(np.zeros((0, 2)), empty, none, none, empty)
        return found, empty, empty, empty, empty
    dx, dy = stand.x[near] - cx, stand.y[near] - cy
    found = crown_crossings(
        sim.quadrature,
        dx,
        dy,
        stand.crown_radius[near],
        sim.instrument.footprint_sigma_m,
        sim.accuracy.footprint_tolerance,
    )
    index = near[found.tree]
    base = stand.crown_base[index] + ground.elevation(dx[found.tree], dy[found.tree])
    z_low, z_high = crown_interval(stand.shape[index], found.rho, base, stand.crown_length[index])
    if not ground.is_flat:  # foliage below the local ground surface does not exist
        local = ground.elevation(found.points[found.column, 0], found.points[found.column, 1])
        z_low, z_high = np.maximum(z_low, local), np.maximum(z_high, local)
    return found, z_low, z_high, prepared.extinction[index], stand.favd[index]


def _ground_deposit(sim, found, profiles, ground):
    """Ground heights (m) and their weights ∫w·P dA at the ground."""
    # all foliage lies above the ground, so P̄ at the ground is P̄ at the lowest edge
    at_ground = float(profiles.gap_edges[0])
    if ground.is_flat:
        return np.zeros(1), np.array([at_ground])
    # bare slope: ground heights are Gaussian with σ = tan(slope)·σf
    h = sim.layer_height
    spread = np.tan(np.radians(ground.slope_deg)) * sim.instrument.footprint_sigma_m
    reach = sim.footprint_radius * np.tan(np.radians(ground.slope_deg))
    k = np.arange(np.floor(-reach / h) - 1, np.ceil(reach / h) + 2)
    mass = np.diff(ndtr((np.append(k - 0.5, k[-1] + 0.5) * h) / spread))
    nodes, values = k * h, mass / mass.sum()
    if found.column.size:
        # remove what the crowns intercept above each crowned column's own ground:
        # crowns are clipped there, so that is the column's whole optical depth (an
        # interpolation inside the ground's layer would miss the foliage above it)
        cols = profiles.crowned_columns
        z_ground = ground.elevation(found.points[cols, 0], found.points[cols, 1])
        lost = found.weights[cols] * -np.expm1(-profiles.column_depth)
        g = z_ground / h
        lower = np.floor(g)
        frac = g - lower
        nodes = np.concatenate([nodes, lower * h, (lower + 1) * h])
        values = np.concatenate([values, -lost * (1 - frac), -lost * frac])
    unique, inverse = np.unique(np.round(nodes / h).astype(np.int64), return_inverse=True)
    weights = np.maximum(np.bincount(inverse, values), 0.0)
    # the Gaussian spread of ground heights and the crowned columns are two different
    # discretisations, so a node can go slightly negative where crowns shade most of
    # its ground: clip, and rescale so that the weights sum to P̄ at the ground exactly
    # (the canopy energy is ρv(1 − P̄ at the lowest edge): the two stay consistent)
    positive = float(weights.sum())
    if positive > 0:
        weights *= at_ground / positive
    else:
        weights[np.argmin(np.abs(unique))] = at_ground
    return unique * h, weights
