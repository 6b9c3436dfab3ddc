"""The explicit 3-D waveform engine.

:class:`WaveformSimulator` precomputes what depends only on the instrument and the
accuracy settings (the truncation radius, the fine layers, the pulse kernel); a
:class:`PreparedStand` holds per-stand work (stem search, crown extinction). Each
footprint then costs the crowns that reach it, the footprint sums of the gap profiles of
its columns, exact at the fine-layer edges (:mod:`.column_kernel`, compiled in
:mod:`.column_kernel_numba`, chosen by the one ``backend=`` switch of
:mod:`forward.backends`), and one short convolution with the pulse.

The columns lie on a grid over the truncated footprint (:mod:`.column_grid`) whose
spacing follows from the accuracy settings' tolerance (:mod:`.accuracy`). The
ground gap P̄(0) has closer columns of its own, which need only each column's whole
optical depth (:func:`.column_kernel.ground_gap`); the canopy returns are scaled
to 1 − P̄(0), so that canopy and ground energy still add up. The
per-crown disc quadrature of earlier versions (:mod:`.crown_quadrature`) is kept as the
scheme ``"crowns"``.
"""

from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree

from ..backends import resolve
from ..footprint import truncation_radius
from ..pulse import layer_kernel
from ..scene import Ground, UniformUnderstory
from ..stand import Stand
from .accuracy import AccuracySettings, as_accuracy
from .column_grid import ColumnGrid, CrownSet, bin_columns
from .column_kernel import footprint_profiles, ground_gap
from .crown_quadrature import CrownFootprint, DiscQuadrature
from .gap import ColumnProfiles, LayerGrid, gap_from_returns, with_understory
from .render import render_waveform
from .waveform import Waveform

__all__ = [
    "DEFAULT_CANOPY_REFLECTANCE",
    "AccuracySettings",
    "PreparedStand",
    "WaveformSimulator",
]

#: Default canopy backscatter reflectance ρv; with the default ρg = 0.3 the ratio is the
#: GEDI L2B value ρv/ρg = 1.5.
DEFAULT_CANOPY_REFLECTANCE = 0.45

#: Column spacings are rounded to this many steps per factor of two, so that footprints
#: under similar crowns share one grid.
SPACING_STEPS_PER_OCTAVE = 8


@dataclass(frozen=True)
class PreparedStand:
    """Per-stand work shared by every footprint over that stand."""

    stand: Stand
    extinction: np.ndarray
    max_radius: float
    # the stem search tree, built once a second footprint asks (see stems_within)
    _search: dict = field(default_factory=dict, repr=False, compare=False)

    @classmethod
    def build(cls, stand: Stand, extinction_per_favd: float) -> "PreparedStand":
        visible = (stand.crown_radius > 0) & (stand.crown_length > 0)
        if not visible.all():
            stand = stand.subset(visible)
        radius = float(stand.crown_radius.max()) if stand.n_trees else 0.0
        return cls(stand=stand, extinction=extinction_per_favd * stand.favd, max_radius=radius)

    def stems_within(self, cx, cy, reach) -> np.ndarray:
        """Indices (ascending) of the stems within ``reach`` (m) of (cx, cy).

        The first query scans every stem, which costs less than building a search tree;
        the tree is built at the second, where the stand serves several footprints.
        """
        stand = self.stand
        if "tree" not in self._search:
            if not self._search.get("scanned"):
                self._search["scanned"] = True
                return np.flatnonzero(np.hypot(stand.x - cx, stand.y - cy) <= reach)
            self._search["tree"] = cKDTree(np.column_stack([stand.x, stand.y]))
        near = self._search["tree"].query_ball_point((cx, cy), reach)
        return np.sort(np.asarray(near, np.intp))

    def crowns_near(self, cx, cy, radius, ground: Ground) -> CrownSet:
        """The crowns whose discs reach within ``radius`` (m) of (cx, cy), with their
        bases raised by the ground's height at their stems."""
        stand = self.stand
        near = self.stems_within(cx, cy, radius + self.max_radius)
        dx, dy = stand.x[near] - cx, stand.y[near] - cy
        reach = np.hypot(dx, dy) < radius + stand.crown_radius[near]
        near, dx, dy = near[reach], dx[reach], dy[reach]
        return CrownSet(
            x=dx,
            y=dy,
            radius=stand.crown_radius[near],
            shape=stand.shape[near].astype(np.int64),
            base=stand.crown_base[near] + ground.elevation(dx, dy),
            length=stand.crown_length[near],
            extinction=self.extinction[near],
            favd=stand.favd[near],
        )


class WaveformSimulator:
    """Simulates waveforms of explicit stands for one instrument.

    Parameters
    ----------
    instrument : Instrument
    accuracy : AccuracySettings, float or str, optional
        Accuracy settings, or a tolerance on the relative L1 error of the waveforms
        (e.g. ``1e-3``); the defaults aim at :data:`forward.explicit.accuracy.DEFAULT_TOLERANCE`.
    """

    def __init__(self, instrument, accuracy: AccuracySettings | float | str | None = None):
        accuracy = as_accuracy(accuracy)
        self.instrument = instrument
        self.accuracy = accuracy
        self.scheme = accuracy.scheme
        self.footprint_radius = truncation_radius(  # the reach of the furthest columns
            instrument.footprint_sigma_m,
            min(accuracy.footprint_tolerance, accuracy.ground_tolerance),
        )
        dz = instrument.bin_height
        low, high = instrument.pulse.support(0.1587)  # ±1σ of a Gaussian pulse
        self.oversampling = accuracy.oversampling_for(dz, max(0.5 * (high - low), 1e-12))
        self.layer_height = dz / self.oversampling
        self.kernel_offset, self.kernel = layer_kernel(
            instrument.pulse, dz, self.oversampling, accuracy.pulse_tolerance
        )
        self.pulse_support = instrument.pulse.support(accuracy.pulse_tolerance)
        self.quadrature = DiscQuadrature(*accuracy.crown_nodes) if self.scheme == "crowns" else None
        self.backend = resolve(accuracy.backend)  # "numba" or "numpy"
        self._grids: dict[tuple[float, float], ColumnGrid] = {}

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

    def column_grid(self, crown_radius, crowns=np.inf, shapes=(), ground=False) -> ColumnGrid:
        """The footprint's columns under about ``crowns`` crowns of typical radius
        ``crown_radius`` (m) and shape codes ``shapes``
        (:meth:`AccuracySettings.column_spacing_for`); with ``ground``, the columns of
        the ground gap (:meth:`AccuracySettings.ground_spacing_for`)."""
        sigma = self.instrument.footprint_sigma_m
        if ground:
            spacing = self.accuracy.ground_spacing_for(sigma, crown_radius, crowns)
        else:
            spacing = self.accuracy.column_spacing_for(sigma, crown_radius, crowns, shapes)
        if self.accuracy.column_spacing is None:  # round to a ladder, so grids are shared
            steps = SPACING_STEPS_PER_OCTAVE
            spacing = 2.0 ** (np.floor(steps * np.log2(spacing)) / steps)
        accuracy = self.accuracy
        tolerance = accuracy.ground_tolerance if ground else accuracy.footprint_tolerance
        if (spacing, tolerance) not in self._grids:
            self._grids[spacing, tolerance] = ColumnGrid.build(sigma, spacing, tolerance)
        return self._grids[spacing, tolerance]

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

        Returns
        -------
        Waveform

        References
        ----------
        Sun, G. & Ranson, K. J. (2000). Modeling lidar returns from forest canopies. *IEEE
        Trans. Geosci. Remote Sens.* 38(6), 2617–2626 (the waveform of a stem map: gap
        probability through the crowns, layer returns and the ground, convolved with the
        pulse).

        Examples
        --------
        One GEDI footprint at the centre of a 60 m plot of the generic conifer stand; the
        samples hold the whole return, ρv·(1 − P̄(0)) + ρg·P̄(0):

        >>> import numpy as np
        >>> from forward.examples import example_stand
        >>> from forward.explicit import WaveformSimulator
        >>> from forward.instrument import instrument_preset
        >>> from forward.realise import realise
        >>> stand = realise(example_stand(), 60.0, np.random.default_rng(1))
        >>> simulator = WaveformSimulator(instrument_preset("gedi"))
        >>> waveform = simulator.simulate(stand, center=(30.0, 30.0))
        >>> bool(np.isclose(waveform.samples.sum(), waveform.total_energy, rtol=1e-3))
        True
        >>> bool(0.0 < waveform.ground_gap < 1.0)
        True
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
        footprint = FOOTPRINT_SCHEMES[self.scheme](self, prepared, cx, cy, ground, understory)
        if heights is None:
            ground_reach = self.footprint_radius * np.tan(np.radians(ground.slope_deg))
            top = max(footprint.top, understory.height if understory else 0.0, ground_reach)
            heights = self.default_heights(top, min(footprint.bottom, -ground_reach))
        else:
            heights = self._check_heights(heights)
        profiles, grid, nodes, weights, settings = footprint.profiles(heights)
        return render_waveform(
            self,
            heights,
            profiles,
            grid,
            (nodes, weights),
            ground,
            canopy_reflectance,
            understory,
            (cx, cy),
            settings,
        )

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

    def layer_grid(self, heights, span_low, span_high):
        """Fine layers on the bins' grid spanning [span_low, span_high] (m), and the
        global index of the first (layer i spans heights[0] − Δz/2 + [i, i + 1]·h)."""
        dz, h = self.instrument.bin_height, self.layer_height
        origin = heights[0] - dz / 2
        first = int(np.floor((span_low - origin) / h))
        last = int(np.ceil((span_high - origin) / h))
        return LayerGrid(origin + first * h, h, last - first), first


class ColumnFootprint:
    """One footprint under the grid-of-columns scheme: its crowns, then its profiles."""

    def __init__(self, sim, prepared, cx, cy, ground, understory):
        self.sim, self.ground, self.understory = sim, ground, understory
        self.crowns = prepared.crowns_near(cx, cy, sim.footprint_radius, ground)
        self.top = float(self.crowns.top.max(initial=0.0))
        self.bottom = float(self.crowns.base.min(initial=0.0))

    def profiles(self, heights):
        """Profiles on the fine layers of ``heights``: (profiles, (layers, first layer),
        ground heights (m), their shares of P̄ at the ground, scheme settings)."""
        sim, crowns, ground, understory = self.sim, self.crowns, self.ground, self.understory
        h = sim.layer_height
        typical = float(np.median(crowns.radius)) if crowns.size else sim.footprint_radius
        count = crowns.effective_count(sim.instrument.footprint_sigma_m)
        grid = sim.column_grid(typical, count, np.unique(crowns.shape))
        ground_grid = sim.column_grid(typical, count, ground=True)
        span_low = min(crowns.base.min(initial=np.inf), 0.0 if understory else np.inf)
        span_high = max(
            crowns.top.max(initial=-np.inf), understory.height if understory else -np.inf
        )
        if span_high <= span_low:  # nothing above the ground: a one-layer empty canopy
            span_low, span_high = 0.0, h
        layers, first = sim.layer_grid(heights, span_low, span_high)
        ground_nodes = None
        if not ground.is_flat:
            reach = max(grid.radius, ground_grid.radius) * np.tan(np.radians(ground.slope_deg))
            k0 = int(np.floor(-reach / h)) - 1
            ground_nodes = (k0, int(np.ceil(reach / h)) - k0 + 2)
        sums = footprint_profiles(
            grid,
            crowns,
            layers,
            ground.gradient,
            ground_nodes,
            bin_columns(grid, typical),
            backend=sim.backend,
        )
        layer_return, ground_mass = sums.layer_return, sums.ground_mass
        separate = ground_grid.spacing < grid.spacing or ground_grid.radius > grid.radius
        if separate and crowns.size:
            layer_return, ground_mass = _with_ground_columns(
                sim.backend, ground_grid, crowns, sums, ground.gradient, ground_nodes, h
            )
        profiles = ColumnProfiles(
            gap_edges=gap_from_returns(layer_return),
            layer_return=layer_return,
            crown_volume=sums.crown_volume,
            foliage_area=sums.foliage_area,
            column_depth=None,
            crowned_columns=np.zeros(0, np.intp),
        )
        profiles = with_understory(profiles, layers, understory, sim.instrument.extinction_per_favd)
        at_ground = float(profiles.gap_edges[0])  # all foliage lies above the ground
        if ground_nodes is None:
            nodes, weights = np.zeros(1), np.array([at_ground])
        else:
            mass = ground_mass
            nodes = (ground_nodes[0] + np.arange(mass.size)) * h
            weights = mass * (at_ground / mass.sum()) if mass.sum() > 0 else mass
        settings = {
            "scheme": "columns",
            "tolerance": sim.accuracy.tolerance,
            "column_spacing_m": grid.spacing,
            "columns": grid.n_columns,
            "ground_column_spacing_m": ground_grid.spacing if separate else grid.spacing,
            "ground_truncation_tolerance": sim.accuracy.ground_tolerance,
            "backend": sim.backend,
        }
        return profiles, (layers, first), nodes, weights, settings


def _with_ground_columns(backend, grid, crowns, sums, slope, ground_nodes, h):
    """The layer returns scaled so that they add up to 1 − P̄(0), with P̄(0) from the
    ground's own columns ``grid``, and the ground masses from those columns.

    Energy is conserved column by column, so the returns of the profiles' columns add
    up to 1 minus their own P̄(0): the scaling corrects the canopy energy by what the
    closer ground columns correct in the ground's, and leaves the profile's shape."""
    intercepted = float(sums.layer_return.sum())
    if intercepted <= 0.0:  # no crown over the profiles' columns: nothing to scale
        return sums.layer_return, sums.ground_mass
    gap, mass = ground_gap(grid, crowns, slope, ground_nodes, h, backend=backend)
    return sums.layer_return * ((1.0 - gap) / intercepted), mass


#: Footprint schemes by :attr:`AccuracySettings.scheme`: the grid of columns, and the
#: per-crown quadrature of earlier versions (:mod:`.crown_quadrature`).
FOOTPRINT_SCHEMES = {"columns": ColumnFootprint, "crowns": CrownFootprint}
