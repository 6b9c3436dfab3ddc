"""The expected-waveform model E[W | θ] of Poisson stands (derivation: :mod:`forward.expected`).

:class:`ExpectedWaveformModel` precomputes once per instrument, window and template (the
layer kernel, the radial quadrature, the tables' matrices) and evaluates batches of
parameter vectors: their cohorts (:mod:`.cohorts`), the trees' optical depth on a grid of
whole fine layers (:mod:`.depth`), the canopy samples (:mod:`.grid`) and the ground
(:mod:`.ground`), each compiled or with numpy by one ``backend`` setting.
"""

import numpy as np

from ..backends import resolve
from ..crowns import CROWN_SHAPES, SHAPE_NAMES
from ..height_families import HEIGHT_DISTRIBUTIONS
from ..pulse import layer_kernel
from ..stand_params import StandParams
from .cohorts import Cohort, cohort_rows, cohorts, narrowest_sd
from .depth import groups, tree_depth
from .grid import anchor_period, clip_keeping_energy, grid_canopy, grid_weight
from .ground import ground_return
from .interpolation import catmull_rom, grid_operator
from .settings import (
    GRID_MARGIN_CELLS,
    GRID_UNDERSHOOT,
    ExpectedWaveforms,
    ModelSettings,
    engine_oversampling,
)
from .tables import radial_rule, tail_matrix
from .vectors import (
    CONDITIONING_FIELDS,
    DEFAULT_FREE,
    MIX_FIELDS,
    VECTOR_FIELDS,
    physical_rows,
)
from .vectors import FIELD_INDEX as _I


class ExpectedWaveformModel:
    """Expected waveform E[W | θ] of Poisson stands, batched over parameter vectors.

    Parameters
    ----------
    instrument : Instrument
        Pulse (Gaussian or measured), bins and κ = k·G·Ω; the footprint size does not
        enter the expectation.
    heights : array (m)
        Bin centres on the absolute height axis, ascending in steps of the bin height.
    template : StandParams
        Values of everything that is not free: height family, shape mixes, FAVD ratios,
        truncation, and the fixed numbers.
    free : tuple of str
        Names from :data:`VECTOR_FIELDS` forming the parameter vector, in order.
    settings : ModelSettings

    References
    ----------
    Sun, G. & Ranson, K. J. (2000). Modeling lidar returns from forest canopies. *IEEE
    Trans. Geosci. Remote Sens.* 38(6), 2617–2626 (the waveform as layer returns through
    the gap probability, and the ground's return through the gap at the ground).

    Examples
    --------
    The expected GEDI waveform of the generic conifer stand: its samples hold the canopy
    return ρv·(1 − E[P(0)]) and the ground return ρg·E[P(0)]:

    >>> import numpy as np
    >>> from forward.examples import example_stand
    >>> from forward.expected import ExpectedWaveformModel
    >>> from forward.instrument import instrument_preset
    >>> gedi = instrument_preset("gedi")
    >>> stand = example_stand()
    >>> heights = np.arange(-10.0, 35.0, gedi.bin_height)
    >>> model = ExpectedWaveformModel(gedi, heights, stand)
    >>> out = model.evaluate(model.vector(stand)[None, :])
    >>> out.samples.shape == (1, heights.size)
    True
    >>> gap = out.gap_ground[0]
    >>> energy = stand.canopy_reflectance * (1 - gap) + stand.ground_reflectance * gap
    >>> bool(np.isclose(out.samples.sum(), energy, rtol=1e-3))
    True
    """

    def __init__(
        self,
        instrument,
        heights,
        template: StandParams,
        free=DEFAULT_FREE,
        settings: ModelSettings | None = None,
    ):
        self.settings = ModelSettings() if settings is None else settings
        unknown = [name for name in free if name not in _I]
        if unknown:
            raise ValueError(f"unknown free parameter(s) {unknown}; choose from {VECTOR_FIELDS}")
        self.instrument = instrument
        self.template = template
        self.parameter_names = tuple(free)
        self._free_index = np.array([_I[name] for name in free], np.intp)
        self._base = self.full_vector(template)
        heights = np.asarray(heights, float)
        dz = instrument.bin_height
        if heights.ndim != 1 or heights.size < 2 or np.max(np.abs(np.diff(heights) - dz)) > 1e-6:
            raise ValueError("heights must ascend in steps of the instrument's bin height")
        self.heights = heights
        s = self.settings
        m = engine_oversampling(instrument) if s.oversampling is None else int(s.oversampling)
        self.oversampling = m
        self.layer_height = dz / m
        q_min, taps = layer_kernel(instrument.pulse, dz, m, 1e-9)
        self._q_min, self._taps = q_min, taps
        # layers that reach a window bin: q = j·m − i within [q_min, q_min + len − 1]
        q_max = q_min + taps.size - 1
        self._layer0 = -q_max
        n_layers = (heights.size - 1) * m - q_min - self._layer0 + 1
        i = self._layer0 + np.arange(n_layers)
        q = np.arange(heights.size)[None, :] * m - i[:, None]
        inside = (q >= q_min) & (q <= q_max)
        self._kernel = np.where(inside, taps[np.clip(q - q_min, 0, taps.size - 1)], 0.0)
        origin = heights[0] - dz / 2
        self._origin = origin
        self._edges = origin + (self._layer0 + np.arange(n_layers + 1)) * self.layer_height
        # radial quadrature: the nodes of every shape in the model, side by side
        mixes = np.array([template.shape_mix, template.cohort2_shape_mix])
        free_mix = [f"mix_{name}" in self.parameter_names for name in SHAPE_NAMES]
        self._shapes = [k for k in range(len(SHAPE_NAMES)) if mixes[:, k].any() or free_mix[k]]
        self._mixes = mixes
        self._mix_index = np.array([_I[MIX_FIELDS[k]] for k in self._shapes], np.intp)
        parts = []
        for position, k in enumerate(self._shapes):
            rho, weights = radial_rule(SHAPE_NAMES[k], s.radial_nodes)
            lo, hi = CROWN_SHAPES[SHAPE_NAMES[k]].extent(rho)
            parts.append((np.full(rho.size, position), weights, lo, hi))
        node_shape, self._node_weight, self._s_lo, self._s_hi = (
            np.concatenate([np.asarray(p[i], float) for p in parts]) for i in range(4)
        )
        self._node_shape = node_shape.astype(np.intp)
        ratio = np.asarray(template.favd_ratio, float)[self._shapes]
        self._node_favd = ratio[self._node_shape]
        # tail integrals as a matrix product on short grids, cumulative sums on long ones
        self._tails = tail_matrix(s.height_nodes) if s.height_nodes <= 128 else None
        self._unit_grid = np.arange(s.height_nodes, dtype=float)
        self._family = HEIGHT_DISTRIBUTIONS[template.height_family]
        self._kappa = instrument.extinction_per_favd
        self._ground_support = instrument.pulse.support(1e-12)
        # the compiled kernels need grids of at least four nodes
        compiled = resolve(s.backend) == "numba" and s.height_nodes >= 4
        self.backend = "numba" if compiled else "numpy"
        self._depth_tables = (self._tails, groups(self._s_lo), groups(self._s_hi))
        # the depth grid of the fast path: whole fine layers, about depth_nodes nodes up
        # to the template's tallest tree
        self._per_cell, self._operators = None, {}
        if s.depth_nodes is not None:
            span = float(self._top(self._cohorts(self._base[None, :]))[0])
            self._per_cell = max(1, round(span / max(s.depth_nodes - 1, 1) / self.layer_height))

    # vectors ---------------------------------------------------------------------------
    @property
    def ndim(self) -> int:
        return len(self.parameter_names)

    def full_vector(self, params: StandParams, ground_elevation=0.0) -> np.ndarray:
        """All of :data:`VECTOR_FIELDS` for one parameter object.

        Parameters
        ----------
        params : StandParams
        ground_elevation : float (m)
            On the model's height axis.

        Returns
        -------
        array (len(VECTOR_FIELDS),)
            The stand's values, cohort 1's shape fractions and the conditioning fields at
            their neutral values (:data:`.vectors.CONDITIONING_FIELDS`).
        """
        values = params.as_dict()
        values["ground_elevation"] = ground_elevation
        values.update(CONDITIONING_FIELDS)
        values.update(zip(MIX_FIELDS, params.shape_mix))
        return np.array([float(values[name]) for name in VECTOR_FIELDS])

    def vector(self, params: StandParams, ground_elevation=0.0) -> np.ndarray:
        """The free-parameter vector of a parameter object.

        Parameters
        ----------
        params : StandParams
            Its fixed settings (height family, shape mixes unless free, FAVD ratios,
            truncation) must be the template's.
        ground_elevation : float (m)

        Returns
        -------
        array (ndim,)
            The :attr:`parameter_names` of :meth:`full_vector`.

        Raises
        ------
        ValueError
            Where a fixed setting differs from the template's.
        """
        for name in (
            "height_family",
            "shape_mix",
            "cohort2_shape_mix",
            "favd_ratio",
            "height_truncation",
        ):
            if name == "shape_mix" and set(MIX_FIELDS) & set(self.parameter_names):
                continue  # the mix is (partly) free
            if getattr(params, name) != getattr(self.template, name):
                raise ValueError(f"{name} differs from the model's template; build a new model")
        return self.full_vector(params, ground_elevation)[self._free_index]

    def _full(self, theta):
        if isinstance(theta, StandParams):
            theta = [theta]
        if isinstance(theta, (list, tuple)) and theta and isinstance(theta[0], StandParams):
            theta = np.array([self.vector(p) for p in theta])
        theta = np.atleast_2d(np.asarray(theta, float))
        if theta.ndim != 2 or theta.shape[1] != self.ndim:
            raise ValueError(f"theta must have shape (n, {self.ndim}), got {theta.shape}")
        full = np.repeat(self._base[None, :], theta.shape[0], axis=0)
        full[:, self._free_index] = theta
        return full

    def full_vectors(self, theta) -> np.ndarray:
        """Rows of parameter vectors completed with the template.

        Parameters
        ----------
        theta : array (n, ndim), StandParams or list of StandParams

        Returns
        -------
        array (n, len(VECTOR_FIELDS))
            E.g. for :func:`forward.expected.vectors.params_from_vector`.
        """
        return self._full(theta)

    def valid(self, theta) -> np.ndarray:
        """Which rows are physical parameter vectors.

        Parameters
        ----------
        theta : array (n, ndim), StandParams or list of StandParams

        Returns
        -------
        array of bool (n,)
            :func:`.vectors.physical_rows` of the completed vectors.
        """
        return self._valid(self._full(theta))

    def _valid(self, v):
        return physical_rows(v, self._family, self.template.height_truncation, backend=self.backend)

    # evaluation --------------------------------------------------------------------------
    def __call__(self, theta) -> np.ndarray:
        """Expected waveforms, shape (n, n_bins); invalid rows are zeros (see ``valid``)."""
        return self.evaluate(theta).samples

    def evaluate(self, theta) -> ExpectedWaveforms:
        """Expected waveforms with their canopy and ground parts and a validity mask.

        Parameters
        ----------
        theta : array (n, ndim), StandParams or list of StandParams

        Returns
        -------
        ExpectedWaveforms
            Samples (apparent reflectance per bin), canopy and ground parts (n, n_bins),
            E[P(0)] and the validity mask; invalid rows are zeros.

        Notes
        -----
        E[W_j] = ρv·Σ_i K_{ji}·(E[P](z_i) − E[P](z_{i+1})) + ρg·E[P(0)]·Δz·p(z_j − g): the
        layer returns through the layer kernel K, and the ground's pulse
        (:mod:`forward.expected`, "Waveform").
        """
        full = self._full(theta)
        valid = self._valid(full)
        full[~valid] = self._base
        n = full.shape[0]
        s = self.settings
        per_row = len(self._shapes) * s.radial_nodes * max(s.height_nodes, self._edges.size)
        chunk = max(1, s.max_elements // max(per_row, 1))
        canopy = np.empty((n, self.heights.size))
        gap0 = np.empty(n)
        for start in range(0, n, chunk):
            rows = slice(start, start + chunk)
            canopy[rows], gap0[rows] = self._canopy(full[rows])
        samples, canopy, ground = ground_return(
            canopy, gap0, full[:, _I["ground_elevation"]], full[:, _I["canopy_reflectance"]],
            full[:, _I["ground_reflectance"]], valid, self.heights, self.instrument.bin_height,
            self.instrument.pulse, self._ground_support, backend=self.backend,
        )  # fmt: skip
        return ExpectedWaveforms(samples, canopy, ground, gap0, valid)

    def gap(self, theta, z) -> np.ndarray:
        """The expected gap probability E[P(z)] above heights ``z``.

        Parameters
        ----------
        theta : array (n, ndim), StandParams or list of StandParams
        z : float or array (m)
            Heights above the ground (clipped at 0).

        Returns
        -------
        array (n, len(z))
            exp(−λ·E[∫(1 − e^{−κuℓ}) dA]) of the trees, times the uniform understory's
            transmission.

        References
        ----------
        Sun, G. & Ranson, K. J. (2000). Modeling lidar returns from forest canopies. *IEEE
        Trans. Geosci. Remote Sens.* 38(6), 2617–2626 (Sec. II, Eqs. (1)–(3): the
        bidirectional gap probability).
        Chiu, S. N., Stoyan, D., Kendall, W. S. & Mecke, J. (2013). *Stochastic Geometry and
        its Applications*, 3rd ed., Wiley, Sec. 3.1 (the Boolean model of the crowns).
        """
        full = self._full(theta)
        z = np.broadcast_to(np.asarray(z, float), (full.shape[0], np.size(z)))
        return self._gap(full, z)

    def _canopy(self, v):
        """Canopy waveforms before ρv (n, n_bins) and E[P(0)] (n,)."""
        cohorts = self._cohorts(v)
        if self._per_cell is None:
            return self._canopy_edges(v, cohorts, self._top(cohorts))
        # rows of nearly equal heights, which the grid cannot resolve, blend into the
        # per-edge path of exact depths (grid_weight); so do rows whose cubic undershoots
        # zero by more than GRID_UNDERSHOOT (~1e-8 of the canopy energy in typical
        # stands), a canopy much thinner than a grid cell
        weight = grid_weight(narrowest_sd(v), self._per_cell * self.layer_height)
        gridded = weight > 0.0
        canopy, gap0 = np.zeros((v.shape[0], self.heights.size)), np.ones(v.shape[0])
        if gridded.any():
            part = cohorts if gridded.all() else self._rows(cohorts, gridded)
            canopy[gridded], gap0[gridded], redo = self._canopy_grid(
                v[gridded], part, self._top(part)
            )
            weight[np.flatnonzero(gridded)[redo]] = 0.0
        edges = weight < 1.0
        if edges.any():
            again, w = v[edges], weight[edges]
            part = cohorts if edges.all() else self._rows(cohorts, edges)
            exact, exact_gap0 = self._canopy_edges(again, part, self._top(part), True)
            canopy[edges] = w[:, None] * canopy[edges] + (1.0 - w[:, None]) * exact
            gap0[edges] = w * gap0[edges] + (1.0 - w) * exact_gap0
            canopy = clip_keeping_energy(canopy, edges)
        return canopy, gap0

    def _canopy_edges(self, v, cohorts, top, exact=False):
        """E[P] at every fine-layer edge, then the layer kernel as a matrix product; with
        ``exact``, the depth itself at every edge (not interpolated from ``depth_nodes``)."""
        g = v[:, _I["ground_elevation"]]
        # only edges that can hold canopy for some row need the tables
        lo_edge = np.searchsorted(self._edges, g.min(), side="right") - 1
        hi_edge = np.searchsorted(self._edges, (g + top).max(), side="right") + 1
        lo_edge, hi_edge = max(lo_edge, 0), min(hi_edge, self._edges.size - 1)
        canopy = np.zeros((v.shape[0], self.heights.size))
        z = self._edges[None, lo_edge : hi_edge + 1] - g[:, None]
        z = np.concatenate([np.zeros((v.shape[0], 1)), z], axis=1)
        p = self._gap(v, z, cohorts, exact)
        if hi_edge > lo_edge:
            energy = np.diff(p[:, 1:], axis=1)
            canopy = energy @ self._kernel[lo_edge:hi_edge]
        return canopy, p[:, 0]

    def _canopy_grid(self, v, cohorts, top):
        """E[P] on a grid of whole fine layers anchored at or below each row's ground on
        an edge that is both a bin edge and a grid-cell edge (:func:`.grid.anchor_period`), so
        that interpolation, layer energies and the pulse are one constant matrix; each
        row is then shifted by whole bins.

        Returns the samples (n, bins), E[P(0)] (n,) and the rows whose samples undershoot
        zero by more than :data:`GRID_UNDERSHOOT` of their canopy energy (n,); the others
        are clipped at zero, keeping their energy."""
        dz = self.instrument.bin_height
        g = v[:, _I["ground_elevation"]]
        step = self._per_cell * self.layer_height
        period_layers = anchor_period(self._per_cell, self.oversampling)
        period = period_layers * self.layer_height
        shift = np.floor((g - self._origin) / period) * (period_layers // self.oversampling)
        z0 = self._origin + shift * dz - g  # in (−period, 0]
        # up to the tallest tree, but no further than three cells beyond the last layer
        # that reaches the window (a taller canopy only needs E[P] below that)
        reach = np.max(np.ceil((self._edges[-1] - g - z0) / step)) + 3
        understory = v[:, _I["understory_lai"]] > 0
        hu = np.where(understory, v[:, _I["understory_height"]], 0.0)
        # two cells beyond the tallest canopy, where E[P] = 1: the interpolation's end
        # condition then reaches no row's canopy, and a row's samples are the same
        # whatever other rows share its batch (one target density for the sampler)
        span = np.max(np.ceil((np.maximum(top, hu) - z0) / step)) + GRID_MARGIN_CELLS
        nodes = max(2, int(min(span, reach)) + 1)
        lai, top_u = v[:, _I["understory_lai"]], v[:, _I["understory_height"]]
        scale_u = np.divide(
            self._kappa * lai, top_u, out=np.zeros_like(lai), where=understory & (top_u != 0)
        )
        return grid_canopy(
            self._cohort_densities(v, cohorts), self._point_masses(v, cohorts),
            self._crown_columns(v), z0, step, nodes, self._grid_operator(nodes), shift,
            scale_u, top_u, self.layer_height, self.heights.size, GRID_UNDERSHOOT,
            backend=self.backend, tables=self._depth_tables,
        )  # fmt: skip

    def _grid_operator(self, nodes):
        """:func:`.interpolation.grid_operator` for ``nodes``, cached."""
        if nodes not in self._operators:
            if len(self._operators) >= 16:
                self._operators.clear()
            self._operators[nodes] = grid_operator(
                nodes, self._per_cell, self.oversampling, self._q_min, self._taps
            )
        return self._operators[nodes]

    def _cohorts(self, v) -> list[Cohort]:
        """The cohorts of full vectors ``v`` (:func:`.cohorts.cohorts`)."""
        two = self.template.cohort2_fraction > 0 or "cohort2_fraction" in self.parameter_names
        return cohorts(
            v,
            self._family,
            self.template.height_truncation,
            self.settings.tail,
            self._mix_index,
            self._mixes[1, self._shapes][None, :],
            two,
        )

    @staticmethod
    def _rows(cohorts, rows):
        """The cohorts of the rows ``rows`` (bool (n,)) only (:func:`.cohorts.cohort_rows`)."""
        return [cohort_rows(c, rows, rows.size) for c in cohorts]

    @staticmethod
    def _top(cohorts):
        """Tallest tree of any active cohort (m), per row."""
        return np.max([np.where(c.present, c.hi, 0.0) for c in cohorts], axis=0)

    def _gap(self, v, z, cohorts=None, exact=False):
        """E[P] at heights z (n, e) above the ground, for full vectors v (n, …)."""
        z = np.maximum(z, 0.0)
        cohorts = self._cohorts(v) if cohorts is None else cohorts
        gap = self._tree_gap(v, z, cohorts, exact)
        if np.any(v[:, _I["understory_lai"]] > 0):  # it multiplies every column's gap
            gap = gap * np.exp(-self._understory_depth(v, z))
        return gap

    def _tree_gap(self, v, z, cohorts, exact=False):
        """E[P] of the trees alone at heights z ≥ 0 (n, e)."""
        nodes = self.settings.depth_nodes
        if nodes is None or exact:
            gap = np.exp(-self._tree_depth(v, z, cohorts))
        else:  # the depth on a uniform grid from 0 to the tallest tree, then cubic
            top = self._top(cohorts)
            grid = top[:, None] * np.linspace(0.0, 1.0, nodes)
            depth = self._tree_depth(v, grid, cohorts)
            # interpolate the optical depth (not E[P]): E[P] stays in (0, 1] in dense stands
            depth = catmull_rom(depth, z, top / (nodes - 1), beyond=0.0)
            # the cubic may overshoot by ~1e-5: keep the depth non-increasing with height
            order = np.argsort(z, axis=1, kind="stable")
            ranked = np.minimum.accumulate(np.take_along_axis(depth, order, axis=1), axis=1)
            np.put_along_axis(depth, order, ranked, axis=1)
            gap = np.exp(-np.maximum(depth, 0.0))
        return gap

    def _cohort_densities(self, v, cohorts):
        """Per cohort with trees: its height density on each row's grid lo + step·i
        (n, height_nodes), lo (n,), step (n,), stems (n,) and the radial nodes' weights
        (n, J) (shape fractions times quadrature weights)."""
        nh = self.settings.height_nodes
        out = []
        for cohort in cohorts:
            w = cohort.fractions[:, self._node_shape] * self._node_weight  # (n, J) or (1, J)
            if cohort.pdf is None or not w.any():  # point masses: see _point_masses
                continue
            lo = cohort.lo
            step = (cohort.hi - lo) / (nh - 1)
            pdf = cohort.pdf(lo[:, None] + step[:, None] * self._unit_grid)
            if w.shape[0] != v.shape[0]:  # one mix for every row (cohort 2)
                w = np.repeat(w, v.shape[0], axis=0)
            out.append((pdf, lo, step, cohort.stems, w))
        return out

    def _point_masses(self, v, cohorts):
        """(stems (n,), height (n,), w (n, J)) of the cohorts of trees all of one height
        per row (the apex trees), or None."""
        points = [c for c in cohorts if c.pdf is None]
        if not points:
            return None
        (point,) = points
        w = point.fractions[:, self._node_shape] * self._node_weight
        return point.stems, point.hi, np.broadcast_to(w, (v.shape[0], w.shape[1]))

    def _crown_columns(self, v):
        """What the compiled depth kernels take besides the densities: r0, r1, the crown
        length ratio, the nodes' chord ends s_lo and s_hi, κ·FAVD and the FAVD ratios."""
        return (
            v[:, _I["crown_radius_intercept"]], v[:, _I["crown_radius_slope"]],
            v[:, _I["crown_length_ratio"]], self._s_lo, self._s_hi,
            self._kappa * v[:, _I["favd"]], self._node_favd,
        )  # fmt: skip

    def _understory_depth(self, v, z):
        """Optical depth of the uniform understory layer above heights z ≥ 0 (n, e)."""
        lai, hu = v[:, _I["understory_lai"], None], v[:, _I["understory_height"], None]
        return self._kappa * lai * np.clip(hu - z, 0.0, None) / hu

    def _tree_depth(self, v, z, cohorts):
        """λ·E[∫(1 − e^{−κuℓ}) dA] at heights z ≥ 0 (n, e), for full vectors v (n, …):
        :func:`.depth.tree_depth` of the rows' cohorts."""
        return tree_depth(
            self._cohort_densities(v, cohorts), self._point_masses(v, cohorts),
            self._crown_columns(v), z, backend=self.backend, tables=self._depth_tables,
        )  # fmt: skip
