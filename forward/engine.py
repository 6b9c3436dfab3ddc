"""The explicit 3-D waveform engine.

:class:`WaveformSimulator` precomputes what depends only on the instrument and the
accuracy settings (the crown-disc quadrature, the truncation radius, the pulse kernel); a
:class:`PreparedStand` holds per-stand work (stem search tree, crown extinction). Each
footprint then costs a crown/column intersection, the exact gap profile over the layers
that hold crowns, and one short convolution.
"""

from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree
from scipy.special import ndtr

from .crowns import crown_interval
from .footprint import CrownCrossings, DiscQuadrature, crown_crossings, truncation_radius
from .gap import LayerGrid, add_uniform_layer, column_profiles
from .pulse import layer_kernel
from .scene import Ground, UniformUnderstory
from .stand import Stand
from .waveform import Waveform

#: Default canopy backscatter reflectance ρv; with the default ρg = 0.3 the ratio is the
#: GEDI L2B value ρv/ρg = 1.5.
DEFAULT_CANOPY_REFLECTANCE = 0.45


@dataclass(frozen=True)
class AccuracySettings:
    """Numerical settings of the explicit engine.

    Parameters
    ----------
    radial_nodes, angular_nodes : int
        Quadrature columns per crown disc: Gauss–Legendre rings in ρ² × angles.
    truncation_tolerance : float
        Footprint weight neglected beyond the truncation radius.
    vertical_oversampling : int or None
        Fine layers per digitiser bin; ``None`` picks the smallest count that makes the
        layer no thicker than a quarter of the pulse's σz.
    pulse_tolerance : float
        Pulse area neglected in each tail.
    """

    radial_nodes: int = 4
    angular_nodes: int = 8
    truncation_tolerance: float = 1e-3
    vertical_oversampling: int | None = None
    pulse_tolerance: float = 1e-9

    def __post_init__(self):
        for name in ("radial_nodes", "angular_nodes"):
            value = getattr(self, name)
            if not isinstance(value, (int, np.integer)) or value < 1:
                raise ValueError(f"{name} must be an integer ≥ 1, got {value!r}")
        m = self.vertical_oversampling
        if m is not None and (not isinstance(m, (int, np.integer)) or m < 1):
            raise ValueError(f"vertical_oversampling must be None or an integer ≥ 1, got {m!r}")
        if not 0.0 < self.truncation_tolerance < 1.0:
            raise ValueError(
                f"truncation_tolerance must lie in (0, 1), got {self.truncation_tolerance}"
            )
        if not 0.0 < self.pulse_tolerance < 0.5:
            raise ValueError(
                f"pulse_tolerance (pulse area left out per tail) must lie in (0, 0.5), "
                f"got {self.pulse_tolerance}"
            )


@dataclass(frozen=True)
class PreparedStand:
    """Per-stand work shared by every footprint over that stand."""

    stand: Stand
    extinction: np.ndarray
    max_radius: float
    tree: cKDTree = field(repr=False)

    @classmethod
    def build(cls, stand: Stand, extinction_per_favd: float) -> "PreparedStand":
        visible = (stand.crown_radius > 0) & (stand.crown_length > 0)
        if not visible.all():
            stand = stand.subset(visible)
        radius = float(stand.crown_radius.max()) if stand.n_trees else 0.0
        return cls(
            stand=stand,
            extinction=extinction_per_favd * stand.favd,
            max_radius=radius,
            tree=cKDTree(
                np.column_stack([stand.x, stand.y]) if stand.n_trees else np.zeros((0, 2))
            ),
        )


class WaveformSimulator:
    """Simulates waveforms of explicit stands for one instrument.

    Parameters
    ----------
    instrument : Instrument
    accuracy : AccuracySettings
    """

    def __init__(self, instrument, accuracy: AccuracySettings | None = None):
        accuracy = AccuracySettings() if accuracy is None else accuracy
        self.instrument = instrument
        self.accuracy = accuracy
        self.quadrature = DiscQuadrature(accuracy.radial_nodes, accuracy.angular_nodes)
        self.footprint_radius = truncation_radius(
            instrument.footprint_sigma_m, accuracy.truncation_tolerance
        )
        dz = instrument.bin_height
        m = accuracy.vertical_oversampling
        if m is None:  # layers no thicker than σz/4; the ±1σ support spans 2σz
            low, high = instrument.pulse.support(0.1587)
            m = max(1, int(np.ceil(8.0 * dz / max(high - low, 1e-12))))
        if m < 1:
            raise ValueError(f"vertical_oversampling must be ≥ 1, got {m}")
        self.oversampling = int(m)
        self.layer_height = dz / self.oversampling
        self.kernel_offset, self.kernel = layer_kernel(
            instrument.pulse, dz, self.oversampling, accuracy.pulse_tolerance
        )
        self.pulse_support = instrument.pulse.support(accuracy.pulse_tolerance)

    # public API ----------------------------------------------------------------------
    def prepare(self, stand: Stand) -> PreparedStand:
        """Per-stand precomputation, reusable across footprints."""
        return PreparedStand.build(stand, self.instrument.extinction_per_favd)

    def default_heights(self, top, bottom=0.0):
        """Bin centres on multiples of Δz covering returns from ``bottom`` to ``top`` (m)."""
        dz = self.instrument.bin_height
        low, high = self.pulse_support
        first = np.floor((min(bottom, 0.0) + low) / dz) - 1
        last = np.ceil((max(top, 0.0) + high) / dz) + 1
        return np.arange(first, last + 1) * dz

    def simulate(
        self,
        stand,
        center=(0.0, 0.0),
        heights=None,
        ground: Ground | None = None,
        canopy_reflectance: float = DEFAULT_CANOPY_REFLECTANCE,
        understory: UniformUnderstory | None = None,
    ) -> Waveform:
        """Waveform of one footprint centred at ``center`` (m, stand coordinates).

        Parameters
        ----------
        stand : Stand or PreparedStand
        center : (float, float) (m)
        heights : array (m), optional
            Bin-centre heights above the ground at the beam centre, ascending with the
            instrument's bin height; by default the whole return.
        ground : Ground, optional
            Flat ground of reflectance 0.3 by default.
        canopy_reflectance : float
            ρv.
        understory : UniformUnderstory, optional
        """
        prepared = stand if isinstance(stand, PreparedStand) else self.prepare(stand)
        ground = Ground() if ground is None else ground
        if understory is not None and not ground.is_flat:
            raise ValueError(
                "a uniform understory layer needs flat ground; on a slope, model the "
                "understory as a population of small crowns"
            )
        if not np.isfinite(canopy_reflectance) or canopy_reflectance < 0:
            raise ValueError(f"canopy reflectance must be finite and ≥ 0, got {canopy_reflectance}")
        if np.shape(center) != (2,):
            raise ValueError(f"footprint centre must be two numbers (x, y) in m, got {center}")
        cx, cy = (float(c) for c in center)
        if not (np.isfinite(cx) and np.isfinite(cy)):
            raise ValueError(f"footprint centre must be finite, got {center}")
        crossings = self._crossings(prepared, cx, cy, ground)
        top = max(crossings[2].max(initial=0.0), understory.height if understory else 0.0)
        if heights is None:
            ground_reach = self.footprint_radius * np.tan(np.radians(ground.slope_deg))
            low = min(crossings[1].min(initial=0.0), -ground_reach)
            heights = self.default_heights(max(top, ground_reach), low)
        else:
            heights = self._check_heights(heights)
        return self._render(crossings, heights, ground, canopy_reflectance, understory, (cx, cy))

    def simulate_many(self, stand, centers, **kwargs) -> list[Waveform]:
        """Waveforms of several footprints over one stand (per-stand work done once)."""
        centers = np.atleast_2d(np.asarray(centers, float))
        if centers.ndim != 2 or centers.shape[1] != 2:
            raise ValueError(f"centers must have shape (n, 2), got {centers.shape}")
        prepared = stand if isinstance(stand, PreparedStand) else self.prepare(stand)
        return [self.simulate(prepared, center, **kwargs) for center in centers]

    # internals -----------------------------------------------------------------------
    def _check_heights(self, heights):
        heights = np.asarray(heights, float)
        if heights.ndim != 1 or heights.size == 0:
            raise ValueError("heights must be a non-empty 1-D array of bin centres (m)")
        if not np.all(np.isfinite(heights)):
            raise ValueError("heights contain NaN or infinite values")
        if heights.size > 1:
            steps = np.diff(heights)
            dz = self.instrument.bin_height
            if np.max(np.abs(steps - dz)) > 1e-6 * dz:
                raise ValueError(
                    f"heights must ascend in steps of the bin height {dz:.6g} m; "
                    f"got steps from {steps.min():.6g} to {steps.max():.6g} m"
                )
        return heights

    def _crossings(self, prepared, cx, cy, ground):
        """Quadrature columns of all crowns that reach the truncated footprint."""
        stand = prepared.stand
        reach = self.footprint_radius + prepared.max_radius
        near = np.asarray(prepared.tree.query_ball_point((cx, cy), reach), np.intp)
        if near.size == 0:  # bare ground: nothing to intersect
            empty, none = np.zeros(0), np.zeros(0, np.intp)
            found = CrownCrossings(np.zeros((0, 2)), empty, none, none, empty)
            return found, empty, empty, empty, empty
        dx, dy = stand.x[near] - cx, stand.y[near] - cy
        found = crown_crossings(
            self.quadrature,
            dx,
            dy,
            stand.crown_radius[near],
            self.instrument.footprint_sigma_m,
            self.accuracy.truncation_tolerance,
        )
        index = near[found.tree]
        base = stand.crown_base[index] + ground.elevation(dx[found.tree], dy[found.tree])
        z_low, z_high = crown_interval(
            stand.shape[index], found.rho, base, stand.crown_length[index]
        )
        if not ground.is_flat:  # foliage below the local ground surface does not exist
            local = ground.elevation(found.points[found.column, 0], found.points[found.column, 1])
            z_low, z_high = np.maximum(z_low, local), np.maximum(z_high, local)
        return found, z_low, z_high, prepared.extinction[index], stand.favd[index]

    def _render(self, crossings, heights, ground, rho_v, understory, center):
        found, z_low, z_high, extinction, favd = crossings
        dz, h, m = self.instrument.bin_height, self.layer_height, self.oversampling
        origin = heights[0] - dz / 2  # global layer i spans origin + [i, i + 1]·h
        span_low = min(z_low.min(initial=np.inf), 0.0 if understory else np.inf)
        span_high = max(z_high.max(initial=-np.inf), understory.height if understory else -np.inf)
        n = heights.size
        canopy = np.zeros(n)
        crown_volume = np.zeros(n)
        foliage = np.zeros(n)
        if span_high > span_low:
            first = int(np.floor((span_low - origin) / h))
            last = int(np.ceil((span_high - origin) / h))
            grid = LayerGrid(origin + first * h, h, last - first)
            profiles = column_profiles(
                found.column,
                z_low,
                z_high,
                extinction,
                favd,
                grid,
                found.weights,
                keep_depth=not ground.is_flat,
            )
            if understory is not None:
                profiles = add_uniform_layer(
                    profiles,
                    grid,
                    self.instrument.extinction_per_favd * understory.favd,
                    understory.favd,
                    understory.height,
                )
            canopy = rho_v * self._convolve_layers(profiles.layer_return, first, n)
            crown_volume = _layers_to_bins(profiles.crown_volume, first, m, n)
            foliage = _layers_to_bins(profiles.foliage_area, first, m, n)
            edges, gap_edges = grid.edges, profiles.gap_edges
        else:
            profiles, grid = None, None
            edges, gap_edges = np.array([0.0, 1.0]), np.ones(2)
        ground_nodes, ground_weights = self._ground_deposit(found, profiles, ground)
        ground_gap = float(gap_edges[0])  # P̄ at the ground: all foliage lies above it
        ground_part = ground.reflectance * self._ground_samples(
            ground_nodes, ground_weights, heights
        )
        gap = np.interp(heights, edges, gap_edges, left=gap_edges[0], right=1.0)
        return Waveform(
            heights=heights,
            samples=canopy + ground_part,
            canopy=canopy,
            ground=ground_part,
            gap=gap,
            crown_volume=crown_volume,
            foliage_area=foliage,
            canopy_energy=rho_v * float(1.0 - gap_edges[0]) if span_high > span_low else 0.0,
            ground_energy=ground.reflectance * ground_gap,
            ground_gap=ground_gap,
            center=center,
            settings={
                **self.instrument.describe(),
                "radial_nodes": self.quadrature.radial_nodes,
                "angular_nodes": self.quadrature.angular_nodes,
                "truncation_tolerance": self.accuracy.truncation_tolerance,
                "vertical_oversampling": m,
                "canopy_reflectance": rho_v,
                "ground_reflectance": ground.reflectance,
                "ground_slope_deg": ground.slope_deg,
                "understory_height_m": understory.height if understory else 0.0,
                "understory_lai": understory.lai if understory else 0.0,
            },
        )

    def _convolve_layers(self, layer_energy, first, n_bins):
        """Samples at bins 0..n_bins−1 from energies of global layers first, first + 1, …"""
        m, q0 = self.oversampling, self.kernel_offset
        full = np.convolve(layer_energy, self.kernel)  # full[k] ↔ q = q0 + k − t
        out = np.zeros(n_bins)
        # bin j reads full[j·m − first − q0]
        j_first = max(0, -(-(first + q0) // m))
        j_last = min(n_bins - 1, (full.size - 1 + first + q0) // m)
        if j_last >= j_first:
            start = j_first * m - first - q0
            out[j_first : j_last + 1] = full[start::m][: j_last - j_first + 1]
        return out

    def _ground_deposit(self, found, profiles, ground):
        """Ground heights (m) and their weights ∫w·P dA at the ground."""
        # all foliage lies above the ground, so P̄ at the ground is P̄ at the lowest edge
        at_ground = 1.0 if profiles is None else float(profiles.gap_edges[0])
        if ground.is_flat:
            return np.zeros(1), np.array([at_ground])
        # bare slope: ground heights are Gaussian with σ = tan(slope)·σf
        h = self.layer_height
        spread = np.tan(np.radians(ground.slope_deg)) * self.instrument.footprint_sigma_m
        reach = self.footprint_radius * np.tan(np.radians(ground.slope_deg))
        k = np.arange(np.floor(-reach / h) - 1, np.ceil(reach / h) + 2)
        mass = np.diff(ndtr((np.append(k - 0.5, k[-1] + 0.5) * h) / spread))
        nodes, values = k * h, mass / mass.sum()
        if profiles is not None and found.column.size:
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

    def _ground_samples(self, nodes, weights, heights):
        dz = self.instrument.bin_height
        low, high = self.pulse_support
        out = np.zeros(heights.size)
        for z, w in zip(nodes, weights):
            lo = np.searchsorted(heights, z + low)
            hi = np.searchsorted(heights, z + high, side="right")
            if hi > lo:
                out[lo:hi] += w * dz * self.instrument.pulse.pdf(heights[lo:hi] - z)
        return out


def _layers_to_bins(layer_values, first, m, n_bins):
    """Sum fine-layer values into the digitiser bins they fall in (window bins only)."""
    bins = (first + np.arange(layer_values.size)) // m
    keep = (bins >= 0) & (bins < n_bins)
    return np.bincount(bins[keep], layer_values[keep], minlength=n_bins)[:n_bins]
